#include "pipelines/panorama/ruler_alignment.hpp"

#include <Eigen/Dense>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <tbb/parallel_for.h>
#include <opencv2/imgproc.hpp>

#include "engine/ellipse_erosion.hpp"
#include "pipelines/panorama/chain_counts.hpp"

namespace fluoro {
namespace {

float bilinear(const cv::Mat& m, double x, double y) {
  const int x0 = int(std::floor(x)), y0 = int(std::floor(y));
  const float fx = float(x - x0), fy = float(y - y0);
  const float* r0 = m.ptr<float>(y0);
  const float* r1 = m.ptr<float>(y0 + 1);
  return (1 - fy) * ((1 - fx) * r0[x0] + fx * r0[x0 + 1]) + fy * ((1 - fx) * r1[x0] + fx * r1[x0 + 1]);
}

// Frame j mapped into frame i for an along-ruler shift s (a_i = a_j + s on the ruler).
struct PairMap {
  Eigen::Matrix2d R;
  Eigen::Vector2d offset;  // u_i = R u_j + offset
};

PairMap pair_map(const RulerThread& ti, const RulerThread& tj, double s) {
  PairMap m;
  m.R = Eigen::Rotation2Dd(ti.angle_rad - tj.angle_rad).toRotationMatrix();
  const Eigen::Vector2d c = ti.centre;
  m.offset = c - m.R * c + ti.direction() * s + ti.normal() * (ti.offset_px - tj.offset_px);
  return m;
}

struct Overlap {
  double ncc = -1, fraction = 0;
};

// NCC of the pixels of frame j that land in frame i's field of view, on a sparse grid.
Overlap overlap_ncc(const RulerAlignmentFrame& fi, const RulerAlignmentFrame& fj, const PairMap& m, int stride) {
  double n = 0, sa = 0, sb = 0, saa = 0, sbb = 0, sab = 0;
  long valid = 0;
  const int W = fi.image.cols, H = fi.image.rows;
  for (int v = 0; v < fj.image.rows; v += stride) {
    const uint8_t* mj = fj.mask.ptr<uint8_t>(v);
    const float* ij = fj.image.ptr<float>(v);
    for (int u = 0; u < fj.image.cols; u += stride) {
      if (!mj[u]) continue;
      ++valid;
      const double x = m.R(0, 0) * u + m.R(0, 1) * v + m.offset.x(), y = m.R(1, 0) * u + m.R(1, 1) * v + m.offset.y();
      if (x < 0 || y < 0 || x >= W - 1 || y >= H - 1) continue;
      if (!fi.mask.at<uint8_t>(int(y + 0.5), int(x + 0.5))) continue;
      const double a = bilinear(fi.image, x, y), b = ij[u];
      n += 1, sa += a, sb += b, saa += a * a, sbb += b * b, sab += a * b;
    }
  }
  Overlap o;
  if (valid == 0 || n < 50) return o;
  o.fraction = n / double(valid);
  const double va = saa - sa * sa / n, vb = sbb - sb * sb / n, cab = sab - sa * sb / n;
  o.ncc = (va > 0 && vb > 0) ? cab / std::sqrt(va * vb) : -1;
  return o;
}

bool strip_column_ok(const RulerStrip& st, int x, int b0, int b1) {
  if (x < 0 || x >= st.image.cols) return false;
  for (int b = b0; b <= b1; ++b)
    if (!st.valid.at<uint8_t>(b - st.b_first, x)) return false;
  return true;
}

// NCC of the two ruler strips (thread and graduations, the long ones included) for the shift s
// rounded to a pixel: free of parallax, it tells 5 mm from 10 mm and, where a 50 mm mark is
// shared, 10 mm from 50 mm.
double strip_band_ncc(const RulerFrame& ri, const RulerFrame& rj, double s, int b0, int b1) {
  const RulerStrip& si = ri.strip;
  const RulerStrip& sj = rj.strip;
  const int shift = int(std::lround(s));
  double n = 0, sa = 0, sb = 0, saa = 0, sbb = 0, sab = 0;
  for (int x = 0; x < sj.image.cols; ++x) {
    if (!strip_column_ok(sj, x, b0, b1) || !strip_column_ok(si, x + shift, b0, b1)) continue;
    for (int b = b0; b <= b1; ++b) {
      const double a = si.image.at<float>(b - si.b_first, x + shift), c = sj.image.at<float>(b - sj.b_first, x);
      n += 1, sa += a, sb += c, saa += a * a, sbb += c * c, sab += a * c;
    }
  }
  if (n < 20 * (b1 - b0 + 1)) return -1;
  const double va = saa - sa * sa / n, vb = sbb - sb * sb / n, cab = sab - sa * sb / n;
  return (va > 0 && vb > 0) ? cab / std::sqrt(va * vb) : -1;
}

// NCC of the two ruler strips for the shift s rounded to a pixel, band by band across the ruler:
// the bands beyond the short graduations hold only the 10 mm and 50 mm marks, so they tell 5 mm
// from 10 mm and, where a 50 mm mark is shared, 10 mm from 50 mm; free of parallax.
double strip_ncc(const RulerFrame& ri, const RulerFrame& rj, double s) {
  const int lo = std::max(ri.strip.b_first, rj.strip.b_first);
  const int hi = std::min(ri.strip.b_first + ri.strip.image.rows, rj.strip.b_first + rj.strip.image.rows) - 1;
  const int start = int(std::ceil(0.5 * std::max(ri.thread.width_px, rj.thread.width_px))) + 1;
  if (hi - start < 6) return strip_band_ncc(ri, rj, s, lo, hi);
  const int bands = 3;
  double sum = 0;
  int used = 0;
  for (int k = 0; k < bands; ++k) {
    const int b0 = start + (hi - start) * k / bands, b1 = start + (hi - start) * (k + 1) / bands;
    const double r = strip_band_ncc(ri, rj, s, b0, b1);
    if (r > -1) sum += r, ++used;
  }
  return used ? sum / used : -1;
}

// Sub-pixel along-ruler shift by cv::matchTemplate (normalised correlation) of the two ruler
// strips around the lattice's shift s; nullopt when the strips share too little.
std::optional<double> refine_shift(const RulerFrame& ri, const RulerFrame& rj, double s) {
  const RulerStrip& si = ri.strip;
  const RulerStrip& sj = rj.strip;
  // Rows with the same across-coordinate b in both strips.
  const int b0 = std::max(si.b_first, sj.b_first);
  // Thread and the short and 10 mm marks: rows that stay inside the field over a long stretch.
  const int b1 = std::min({si.b_first + si.image.rows, sj.b_first + sj.image.rows,
                           int(std::ceil(3.5 * std::max(ri.thread.width_px, rj.thread.width_px)))}) - 1;
  if (b1 - b0 < 4) return std::nullopt;
  const auto column_ok = strip_column_ok;
  const int search = 4;
  const int si_shift = int(std::floor(s));
  int x0 = -1, x1 = -1;  // template columns in strip j
  for (int x = 0; x < sj.image.cols; ++x) {
    const bool ok = column_ok(sj, x, b0, b1) && column_ok(si, x + si_shift - search, b0, b1) &&
                    column_ok(si, x + si_shift + search + 1, b0, b1);
    if (ok) {
      if (x0 < 0) x0 = x;
      x1 = x;
    }
  }
  if (x0 < 0 || x1 - x0 < 20) return std::nullopt;
  const cv::Mat templ = sj.image(cv::Range(b0 - sj.b_first, b1 - sj.b_first + 1), cv::Range(x0, x1 + 1));
  const cv::Mat img = si.image(cv::Range(b0 - si.b_first, b1 - si.b_first + 1),
                               cv::Range(x0 + si_shift - search, x1 + si_shift + search + 2));
  cv::Mat result;
  cv::matchTemplate(img, templ, result, cv::TM_CCOEFF_NORMED);
  cv::Point best;
  cv::minMaxLoc(result, nullptr, nullptr, nullptr, &best);
  if (best.x <= 0 || best.x >= result.cols - 1) return std::nullopt;
  const double a = result.at<float>(0, best.x - 1), b = result.at<float>(0, best.x), c = result.at<float>(0, best.x + 1);
  const double den = a - 2 * b + c;
  const double off = std::abs(den) > 1e-12 ? 0.5 * (a - c) / den : 0.0;
  return si_shift - search + best.x + off;
}

// The overlap NCC of the band-passed frames i and j (anatomy and foreign objects, no ruler) for
// the along-ruler shift s, the translation's scale searched within the windows (parallax: the
// anatomy lies in another plane than the ruler); `scale` receives where it peaked.
Overlap anatomy_overlap(const RulerAlignmentFrame& fi, const RulerAlignmentFrame& fj, double s, double pitch,
                        const std::vector<std::pair<double, double>>& windows, double& scale_at_peak) {
  const RulerThread& ti = fi.ruler->thread;
  const RulerThread& tj = fj.ruler->thread;
  // Samples a quarter graduation apart (the band-passed content is smooth below that); the coarse
  // scale sweep on a grid twice as sparse.
  const int stride = std::max(2, int(std::lround(pitch / 4)));
  Overlap top;
  double top_scale = 1;
  auto allowed = [&](double scale) {
    return std::any_of(windows.begin(), windows.end(),
                       [&](const auto& w) { return scale >= w.first - 1e-9 && scale <= w.second + 1e-9; });
  };
  auto try_scale = [&](double scale, int grid) {
    PairMap m = pair_map(ti, tj, s);
    const Eigen::Vector2d centre = ti.centre;
    m.offset = centre - m.R * centre + scale * (m.offset - (centre - m.R * centre));
    const Overlap o = overlap_ncc(fi, fj, m, grid);
    if (o.ncc > top.ncc) top = o, top_scale = scale;
  };
  // Coarse steps that move the frame by a quarter graduation at most (the band-passed edges
  // correlate over about that), then a third of a step around the best.
  const double travel = std::max(1.0, std::hypot(s, ti.offset_px - tj.offset_px));
  const double step = std::clamp(pitch / (4 * travel), 0.002, 0.03);
  for (const auto& [lo, hi] : windows)
    for (double scale = lo; scale <= hi + 1e-9; scale += step) try_scale(scale, 2 * stride);
  top = Overlap{};
  const double coarse = top_scale;
  for (double scale = coarse - step; scale <= coarse + step + 1e-9; scale += step / 3)
    if (allowed(scale)) try_scale(scale, stride);
  scale_at_peak = top_scale;
  return top;
}

// A graduation-aligned candidate translation of a pair and how the images agree with it.
struct PairCandidate {
  long K;                // graduation count: local index in j + K = local index in i
  double s, ruler;       // along-ruler shift (a_i = a_j + s), the ruler strips' NCC
  Overlap o;             // the raw frames' overlap at the ruler's scale
  double score = -1e9, ncc = -1, scale = 1;  // score, the anatomy's NCC and the scale it peaked at
};

struct PairResult {
  bool ok = false;
  long index_offset = 0;  // local graduation index in j + index_offset = local index in i
  double shift = 0;       // a_i = a_j + shift
  std::optional<double> refined;
  Overlap overlap;
  double ruler_ncc = 0;
  double image_scale = 1;  // translation scale at which the anatomy correlated best
  bool decisive = false;   // a 50 mm mark fixed the graduation count
  double score = -1e9, runner_up = -1e9;  // the chosen candidate's score, the best other count's
  bool ambiguous = false;  // refused only because another count scored nearly as well
  long modulus = 1;        // the graduation counts the marks allow differ by multiples of it
  std::vector<PairCandidate> candidates;  // those whose overlap correlates, for the chain's decision
  std::string problem;
};

// The frame's anatomy and foreign objects for the NCC: band-passed (the slow shading of the soft
// tissue and the pixel noise removed, edges kept) and without the ruler, whose periodic marks would
// reward any graduation-aligned shift; the ruler has its own, parallax-free score.
// The scales follow the graduation pitch, the one length every set shows (5 mm on the ruler).
RulerAlignmentFrame band_pass(const RulerAlignmentFrame& f, double pitch) {
  RulerAlignmentFrame h;
  cv::Mat fine, coarse;
  cv::GaussianBlur(f.image, fine, cv::Size(0, 0), std::max(1.0, pitch / 8));
  // The coarse (shading) level on a grid a quarter of the blur apart: a wide Gaussian at full
  // resolution would cost more than all the correlations.
  const double sigma = 0.6 * pitch;
  const int factor = std::max(1, int(sigma / 4));
  if (factor > 1) {
    cv::Mat small;
    cv::resize(f.image, small, cv::Size((f.image.cols + factor - 1) / factor, (f.image.rows + factor - 1) / factor), 0, 0,
               cv::INTER_AREA);
    cv::GaussianBlur(small, small, cv::Size(0, 0), sigma / factor);
    cv::resize(small, coarse, f.image.size(), 0, 0, cv::INTER_LINEAR);
  } else {
    cv::GaussianBlur(f.image, coarse, cv::Size(0, 0), sigma);
  }
  h.image = fine - coarse;
  const int e = 2 * int(std::lround(0.6 * pitch)) + 1;
  h.mask = erode_ellipse(f.mask, e);  // cv::erode's pixels; the 41 x 41 ellipse at 1024^2 was slow there
  if (f.ruler) {
    const RulerThread& t = f.ruler->thread;
    const Eigen::Vector2d e = t.direction(), n = t.normal();
    const double b0 = f.ruler->strip.b_first - 8, b1 = f.ruler->strip.b_first + f.ruler->strip.image.rows + 8;
    const double L = 2.0 * std::hypot(f.image.cols, f.image.rows);
    std::vector<cv::Point> band;
    for (const auto& [a, b] : {std::pair{-L, b0}, {L, b0}, {L, b1}, {-L, b1}}) {
      const Eigen::Vector2d p = t.centre + a * e + (t.offset_px + b) * n;
      band.emplace_back(int(std::lround(p.x())), int(std::lround(p.y())));
    }
    cv::fillConvexPoly(h.mask, band, cv::Scalar(0));
  }
  h.ruler = f.ruler;
  return h;
}

// Makes candidate c the pair's translation (the sub-pixel refinement is separate).
void adopt(PairResult& r, const PairCandidate& c) {
  r.ok = true, r.index_offset = c.K, r.shift = c.s;
  r.overlap = {c.ncc, c.o.fraction};
  r.ruler_ncc = c.ruler;
  r.image_scale = c.scale;
}

// The sub-pixel shift of the chosen candidate, when the ruler strips' peak is the lattice's.
void refine(PairResult& r, const RulerFrame& ri, const RulerFrame& rj) {
  r.refined = refine_shift(ri, rj, r.shift);
  if (r.refined && std::abs(*r.refined - r.shift) > 1.0) r.refined.reset();  // not the same peak
}

// fi, fj: the frames band-passed (band_pass); fi_raw, fj_raw: as given.
PairResult measure_pair(const RulerAlignmentFrame& fi_raw, const RulerAlignmentFrame& fj_raw, const RulerAlignmentFrame& fi,
                        const RulerAlignmentFrame& fj, double pitch, const RulerAlignmentOptions& opt,
                        const std::vector<double>& depth_scales = {}) {
  PairResult best;
  const RulerFrame& ri = *fi.ruler;
  const RulerFrame& rj = *fj.ruler;
  const double base = ri.phase_px - rj.phase_px;
  const double reach = std::hypot(fi.image.cols, fi.image.rows);
  const long kmin = long(std::floor((-reach - base) / pitch)), kmax = long(std::ceil((reach - base) / pitch));
  // Every graduation-aligned candidate sharing enough of the frame, scored by the ruler strips;
  // the promising ones also by the whole overlap, where the scale of the translation is let free
  // within +-15 % since the bone lies in another plane than the ruler (parallax).
  std::vector<PairCandidate> scored;
  double best_fraction = 0;
  // The marks' lengths restrict the graduation count: a 10 mm mark must meet a 10 mm mark, a 50 mm
  // mark a 50 mm mark (then the candidates are 50 mm apart, far beyond any parallax).
  const long modulus = (ri.long_residue >= 0 && rj.long_residue >= 0) ? 10
                       : (ri.medium_parity >= 0 && rj.medium_parity >= 0) ? 2 : 1;
  const long residue = modulus == 10 ? ri.long_residue - rj.long_residue
                       : modulus == 2 ? ri.medium_parity - rj.medium_parity : 0;
  for (long K = kmin; K <= kmax; ++K) {
    if ((((K - residue) % modulus) + modulus) % modulus != 0) continue;
    const double s = base + double(K) * pitch;
    const Overlap o = overlap_ncc(fi_raw, fj_raw, pair_map(ri.thread, rj.thread, s), std::max(4, fi.image.cols / 128));
    best_fraction = std::max(best_fraction, o.fraction);
    if (o.fraction < opt.min_overlap) continue;
    scored.push_back({K, s, strip_ncc(ri, rj, s), o});
  }
  // A candidate whose ruler strips cannot be compared (they share too few unhidden columns: a
  // long shift, the clamp) is given the best agreement any candidate's strips reached: missing
  // evidence must not count against it (it did, as -1, and let a shorter shift win on the ruler
  // alone), so it wins or ties on the anatomy.
  double best_ruler = 0;
  for (const PairCandidate& c : scored)
    if (c.ruler > -1) best_ruler = std::max(best_ruler, c.ruler);
  double best_score = -1e9;
  // Where only the 10 mm marks fix the count, a 10 mm error and a 15 % parallax look alike: the
  // scale then comes from the pairs that a 50 mm mark fixed (the same for every pair).
  std::vector<std::pair<double, double>> windows;
  if (modulus < 10 && !depth_scales.empty())
    for (double h : depth_scales) windows.emplace_back(h - 0.02, h + 0.02);
  else
    windows.emplace_back(0.85, 1.15);
  for (PairCandidate& c : scored) {
    double top_scale = 1;
    const Overlap top = anatomy_overlap(fi, fj, c.s, pitch, windows, top_scale);
    // Candidates 50 mm apart: the anatomy decides (a wire across the ruler, at its own depth, can
    // spoil the strips' correlation); 10 mm apart: the ruler's long marks have their say too.
    const double score = top.ncc + (modulus == 10 ? 0.0 : c.ruler > -1 ? c.ruler : best_ruler);
    c.score = score;
    c.ncc = top.ncc;
    c.scale = top_scale;
    // A candidate whose overlap does not correlate cannot be the translation, however well the
    // ruler's periodic marks line up: it wins only over others that do not correlate either.
    const bool correlates = top.ncc >= opt.min_ncc, best_correlates = best.ok && best.overlap.ncc >= opt.min_ncc;
    if (correlates > best_correlates || (correlates == best_correlates && score > best_score)) {
      best_score = score;
      adopt(best, c);
      best.decisive = modulus == 10;
    }
  }
  for (const PairCandidate& c : scored)
    if (c.K != best.index_offset && c.ncc >= opt.min_ncc) best.runner_up = std::max(best.runner_up, c.score);
  for (const PairCandidate& c : scored)
    if (c.ncc >= opt.min_ncc) best.candidates.push_back(c);
  best.modulus = modulus;
  best.score = best_score;
  char why[256];
  if (!best.ok) {
    std::snprintf(why, sizeof why, "no graduation-aligned translation overlaps the previous frame by %.0f%% (at most %.0f%%)",
                  100 * opt.min_overlap, 100 * best_fraction);
    best.problem = why;
    return best;
  }
  // Where only the 10 mm marks fix the count, the anatomy must tell candidates 10 mm apart; when
  // another count scores nearly as well it cannot, and a guess would be a length off by a
  // graduation: refused instead.
  if (modulus < 10 && best.overlap.ncc >= opt.min_ncc && best_score - best.runner_up < opt.min_margin) {
    std::snprintf(why, sizeof why,
                  "the graduation count to the previous frame is ambiguous: no 50 mm mark fixes it and two counts "
                  "10 mm apart score within %.2f (needs %.2f)",
                  best_score - best.runner_up, opt.min_margin);
    best.problem = why;
    best.ok = false;
    best.ambiguous = true;
    return best;
  }
  if (best.overlap.ncc < opt.min_ncc) {
    std::snprintf(why, sizeof why,
                  "no overlap with the previous frame correlates: best NCC %.2f (needs %.2f) over %.0f%% of the frame",
                  best.overlap.ncc, opt.min_ncc, 100 * best.overlap.fraction);
    best.problem = why;
    best.ok = false;
    return best;
  }
  refine(best, ri, rj);
  return best;
}

// The pairs j = a+1 .. c of a run whose inner frames show no 50 mm mark while frames a and c do:
// their counts must sum to the residues' difference modulo 10 (chain_counts.hpp). When one
// combination leads every other by the margin, its candidates are the pairs' translations, even
// where a pair alone was ambiguous; otherwise the pairs keep their own decisions, and an ambiguous
// pair's reason says that the chain did not decide it either.
void settle_run(const std::vector<RulerAlignmentFrame>& frames, std::vector<std::optional<PairResult>>& pairs, int a, int c,
                const RulerAlignmentOptions& opt) {
  std::vector<std::vector<CountCandidate>> counts;
  for (int j = a + 1; j <= c; ++j) {
    counts.emplace_back();
    for (const PairCandidate& k : pairs[size_t(j)]->candidates) counts.back().push_back({k.K, k.score});
  }
  const long residue = frames[size_t(a)].ruler->long_residue - frames[size_t(c)].ruler->long_residue;
  const auto settled = settle_chain_counts(counts, residue, 10);
  if (!settled) return;
  // The run's score sums m pairs' scores, so its spread is about sqrt(m) times a pair's: the lead
  // a pair needs, times sqrt(m).
  const double margin = opt.min_margin * std::sqrt(double(c - a));
  if (settled->lead < margin) {
    char why[160];
    std::snprintf(why, sizeof why, "; with the 50 mm marks of frames %d and %d the best counts lead by %.2f (needs %.2f)",
                  a, c, settled->lead, margin);
    for (int j = a + 1; j <= c; ++j)
      if (pairs[size_t(j)]->ambiguous) pairs[size_t(j)]->problem += why;
    return;
  }
  for (int j = a + 1; j <= c; ++j) {
    PairResult& r = *pairs[size_t(j)];
    const PairCandidate& k = r.candidates[settled->chosen[size_t(j - a - 1)]];
    if (r.ok && r.index_offset == k.K) continue;
    adopt(r, k);
    r.ambiguous = false;
    r.problem.clear();
    refine(r, *frames[size_t(j - 1)].ruler, *frames[size_t(j)].ruler);
  }
}

// Every run of consecutive pairs across frames without a 50 mm mark, between two that show one.
void settle_runs(const std::vector<RulerAlignmentFrame>& frames, std::vector<std::optional<PairResult>>& pairs,
                 const RulerAlignmentOptions& opt) {
  const int n = int(frames.size());
  const auto has_long = [&](int i) { return frames[size_t(i)].ruler && frames[size_t(i)].ruler->long_residue >= 0; };
  const auto measured = [&](int j) { return pairs[size_t(j)] && !pairs[size_t(j)]->candidates.empty(); };
  for (int a = 0; a < n; ++a) {
    if (!has_long(a)) continue;
    int c = a + 1;
    while (c < n && measured(c) && !has_long(c)) ++c;
    if (c < n && c - a >= 2 && measured(c) && has_long(c)) settle_run(frames, pairs, a, c, opt);
  }
}

}  // namespace

RulerAlignment align_on_ruler(const std::vector<RulerAlignmentFrame>& given, const RulerAlignmentOptions& opt) {
  const int n = int(given.size());
  RulerAlignment out;
  out.frames.resize(size_t(n));
  std::vector<double> pitches;
  for (const auto& f : given)
    if (f.ruler) pitches.push_back(f.ruler->pitch_px);
  if (pitches.empty()) {
    for (auto& p : out.frames) p.problem = "no ruler found";
    return out;
  }
  std::nth_element(pitches.begin(), pitches.begin() + long(pitches.size() / 2), pitches.end());
  const double pitch0 = pitches[pitches.size() / 2];
  // Every frame sees the ruler at one depth, fronto-parallel: one graduation pitch. A frame whose
  // lattice was fitted to every other mark (twice the pitch: the 5 mm marks too faint to pass, in
  // small images) numbers its marks in other units, and counted with the others it would shift
  // every frame of the adjustment (tens of pixels on a 256^2 set): its ruler is not used.
  std::vector<RulerAlignmentFrame> frames = given;
  std::vector<std::string> ruler_problem(size_t(n), "no ruler found");
  for (int i = 0; i < n; ++i) {
    auto& r = frames[size_t(i)].ruler;
    if (r && std::abs(r->pitch_px / pitch0 - 1) > opt.max_pitch_deviation) {
      char why[160];
      std::snprintf(why, sizeof why, "its graduation pitch (%.2f px) is not the other frames' (%.2f px), so its marks cannot be counted",
                    r->pitch_px, pitch0);
      ruler_problem[size_t(i)] = why;
      r.reset();
    }
  }

  std::vector<RulerAlignmentFrame> filtered(static_cast<size_t>(n));
  tbb::parallel_for(0, n, [&](int i) { filtered[size_t(i)] = band_pass(frames[size_t(i)], pitch0); });
  auto measure = [&](int i, int j, const std::vector<double>& hint) {
    return measure_pair(frames[size_t(i)], frames[size_t(j)], filtered[size_t(i)], filtered[size_t(j)], pitch0, opt, hint);
  };
  // Consecutive pairs first, in parallel: most frames align to the previous one.
  std::vector<std::optional<PairResult>> consecutive(static_cast<size_t>(n));
  tbb::parallel_for(1, n, [&](int j) {
    if (frames[size_t(j - 1)].ruler && frames[size_t(j)].ruler) consecutive[size_t(j)] = measure(j - 1, j, {});
  });
  // The anatomy's scale relative to the ruler (parallax), from the consecutive pairs whose count a
  // 50 mm mark fixed; the other pairs are measured again with it.
  std::vector<double> scales;
  for (int j = 1; j < n; ++j)
    if (consecutive[size_t(j)] && consecutive[size_t(j)]->ok && consecutive[size_t(j)]->decisive)
      scales.push_back(consecutive[size_t(j)]->image_scale);
  std::vector<double> scale_hint = scales;
  if (!scales.empty()) {
    tbb::parallel_for(1, n, [&](int j) {
      if (consecutive[size_t(j)] && !consecutive[size_t(j)]->decisive) consecutive[size_t(j)] = measure(j - 1, j, scale_hint);
    });
  }

  settle_runs(frames, consecutive, opt);

  // Chain: every frame to its nearest aligned predecessor (the previous frame, else the one before).
  std::vector<long> index_offset(size_t(n), 0);  // frame-local graduation index + offset = global index
  // Along-ruler position of each aligned frame from the chain's shifts: a_0 = a_i + position[i].
  std::vector<double> position(size_t(n), 0.0);
  // A pair's candidate is chosen on the two frames' overlap alone. Where it puts frame j over
  // another aligned frame k as well (by min_check_overlap), frame k's image must agree there too,
  // by the standard a pair must meet: a wrong count (or a thread found off the true one) that
  // happened to correlate with frame i on a small overlap lands the frame where frame k shows other
  // anatomy. The scale is searched over the whole parallax range, as for a pair without hints.
  // Returns the reason, or "".
  const std::vector<std::pair<double, double>> any_depth = {{0.85, 1.15}};
  auto placement_conflict = [&](int i, int j) -> std::string {
    for (int k = 0; k < j; ++k) {
      if (k == i || !out.frames[size_t(k)].aligned) continue;
      const double s = position[size_t(j)] - position[size_t(k)];
      const RulerThread& tk = frames[size_t(k)].ruler->thread;
      const RulerThread& tj = frames[size_t(j)].ruler->thread;
      const Overlap raw = overlap_ncc(frames[size_t(k)], frames[size_t(j)], pair_map(tk, tj, s),
                                      std::max(4, frames[size_t(k)].image.cols / 128));
      if (raw.fraction < opt.min_check_overlap) continue;
      double scale = 1;
      const Overlap o = anatomy_overlap(filtered[size_t(k)], filtered[size_t(j)], s, pitch0, any_depth, scale);
      if (o.ncc >= opt.min_ncc) continue;
      char why[256];
      std::snprintf(why, sizeof why,
                    "its placement from frame %d puts it over %.0f%% of frame %d, whose image does not agree there "
                    "(NCC %.2f, needs %.2f)",
                    i, 100 * raw.fraction, k, o.ncc, opt.min_ncc);
      return why;
    }
    return "";
  };
  struct Shift { int i, j; double s; };
  std::vector<Shift> shifts;
  if (frames[0].ruler) {
    out.frames[0].aligned = true;
    out.frames[0].ncc = 1;
  } else {
    out.frames[0].problem = ruler_problem[0] + " (the reference frame)";
  }
  for (int j = 1; j < n; ++j) {
    RulerPlacement& pj = out.frames[size_t(j)];
    if (!frames[size_t(j)].ruler) {
      pj.problem = ruler_problem[size_t(j)];
      continue;
    }
    for (int i = j - 1; i >= std::max(0, j - 2); --i) {
      if (!out.frames[size_t(i)].aligned) continue;
      const PairResult r = (i == j - 1 && consecutive[size_t(j)]) ? *consecutive[size_t(j)] : measure(i, j, scale_hint);
      if (!r.ok) {
        if (pj.problem.empty()) pj.problem = r.problem + " (frame " + std::to_string(i) + ")";
        continue;
      }
      // The placement must agree with every aligned frame it lands on, not only with frame i.
      position[size_t(j)] = position[size_t(i)] + r.shift;
      const std::string conflict = placement_conflict(i, j);
      if (!conflict.empty()) {
        if (pj.problem.empty()) pj.problem = conflict;
        continue;
      }
      pj.aligned = true;
      pj.problem.clear();
      pj.predecessor = i;
      pj.ncc = r.overlap.ncc;
      pj.overlap = r.overlap.fraction;
      pj.refinement_px = r.refined ? *r.refined - r.shift : 0;
      index_offset[size_t(j)] = index_offset[size_t(i)] + r.index_offset;
      if (r.refined) shifts.push_back({i, j, *r.refined});
      break;
    }
    if (!pj.aligned && pj.problem.empty()) pj.problem = "no aligned frame before it to align to";
  }

  // One adjustment of everything: S_i the along-ruler position of frame i's origin (S_0 = 0), the
  // common pitch p and phase q; every graduation k of frame i gives S_i + a = (k + K_i) p + q, every
  // matchTemplate shift gives S_j - S_i = s. Errors do not run along the chain: every frame is tied
  // to the one lattice.
  std::vector<int> unknown(size_t(n), -1);
  int nu = 0;
  for (int i = 1; i < n; ++i)
    if (out.frames[size_t(i)].aligned) unknown[size_t(i)] = nu++;
  const int ip = nu, iq = nu + 1;
  std::vector<Eigen::VectorXd> rows;
  std::vector<double> rhs, weight;
  const double sigma_mark = 0.05, sigma_shift = 0.15;  // px: typical graduation and NCC precision
  int marks = 0;
  for (int i = 0; i < n; ++i) {
    if (!out.frames[size_t(i)].aligned) continue;
    const RulerFrame& r = *frames[size_t(i)].ruler;
    for (size_t m = 0; m < r.mark_a.size(); ++m) {
      Eigen::VectorXd row = Eigen::VectorXd::Zero(nu + 2);
      if (unknown[size_t(i)] >= 0) row(unknown[size_t(i)]) = 1;
      row(ip) = -double(r.mark_k[m] + index_offset[size_t(i)]);
      row(iq) = -1;
      rows.push_back(row), rhs.push_back(-r.mark_a[m]), weight.push_back(1 / sigma_mark);
      ++marks;
    }
  }
  for (const Shift& s : shifts) {
    Eigen::VectorXd row = Eigen::VectorXd::Zero(nu + 2);
    row(unknown[size_t(s.j)]) = 1;
    if (unknown[size_t(s.i)] >= 0) row(unknown[size_t(s.i)]) = -1;
    rows.push_back(row), rhs.push_back(s.s), weight.push_back(1 / sigma_shift);
  }
  out.graduations_used = marks;
  if (!out.frames[0].aligned || rows.size() < size_t(nu + 3)) return out;
  Eigen::MatrixXd A(long(rows.size()), nu + 2);
  Eigen::VectorXd b(long(rows.size()));
  for (size_t k = 0; k < rows.size(); ++k) A.row(long(k)) = rows[k].transpose() * weight[k], b(long(k)) = rhs[k] * weight[k];
  const Eigen::VectorXd x = A.colPivHouseholderQr().solve(b);
  const Eigen::VectorXd res = A * x - b;  // in units of sigma
  std::vector<double> res_px;
  for (size_t k = 0; k < rows.size(); ++k) res_px.push_back(res(long(k)) / weight[k]);
  double ss = 0;
  for (double r : res_px) ss += r * r;
  out.residual_rms_px = std::sqrt(ss / double(res_px.size()));
  const double dof = std::max(1.0, double(rows.size()) - double(nu + 2));
  const double scale2 = std::max(1.0, res.squaredNorm() / dof);  // never claim better than the sigmas
  const Eigen::MatrixXd cov = (A.transpose() * A).inverse() * scale2;
  out.pitch_px = x(ip);
  out.pitch_sigma_px = std::sqrt(cov(ip, ip));

  const RulerThread& t0 = frames[0].ruler->thread;
  for (int i = 0; i < n; ++i) {
    RulerPlacement& p = out.frames[size_t(i)];
    if (!p.aligned) continue;
    const RulerFrame& r = *frames[size_t(i)].ruler;
    const double S = unknown[size_t(i)] >= 0 ? x(unknown[size_t(i)]) : 0.0;
    p.along_sigma_px = unknown[size_t(i)] >= 0 ? std::sqrt(cov(unknown[size_t(i)], unknown[size_t(i)])) : 0.0;
    p.rotation_rad = std::remainder(t0.angle_rad - r.thread.angle_rad, 2 * M_PI);
    p.translation_px = t0.direction() * S + t0.normal() * (t0.offset_px - r.thread.offset_px);
    // Confidence: the overlap's correlation times the graduations' support (8 or more: full).
    p.confidence = std::max(0.0, p.ncc) * std::min(1.0, double(r.mark_a.size()) / 8.0);
  }
  return out;
}

}  // namespace fluoro

// fluoro register-points: paired-point rigid registration with FRE and the Fitzpatrick-West TRE
// prediction at targets (shared/docs/FORMATS.md).
#include <cmath>
#include <cstdio>
#include <optional>
#include <string>

#include "apps/fluoro/commands.hpp"
#include "apps/fluoro/global_options.hpp"
#include "apps/fluoro/provenance.hpp"
#include "apps/fluoro/result_files.hpp"
#include "engine/error.hpp"
#include "engine/json_io.hpp"
#include "engine/point_list_io.hpp"
#include "pipelines/calibration/paired_point_registration.hpp"

namespace fluoro::cli {
namespace {

struct RegisterPointsOptions {
  std::string fixed, moving, targets, out;
  double fle_mm = 0;
  bool fle_given = false;
};

// The moving file's optional "weights": one positive number per point (a weighted Horn solution,
// weight ~ 1 / FLE_i^2). Empty when absent.
std::vector<double> read_weights(const std::string& path, size_t points) {
  const nlohmann::json doc = read_json(path);
  if (!doc.contains("weights")) return {};
  const nlohmann::json& w = doc["weights"];
  if (!w.is_array() || w.size() != points)
    throw_input_error(path, "\"weights\" must hold one number per point (" + std::to_string(points) + ")");
  std::vector<double> out;
  for (const auto& x : w) {
    if (!x.is_number() || !std::isfinite(x.get<double>()) || !(x.get<double>() > 0))
      throw_input_error(path, "weight " + std::to_string(out.size()) + " must be a positive number");
    out.push_back(x.get<double>());
  }
  return out;
}

void run(const RegisterPointsOptions& o) {
  std::optional<double> fle;
  if (o.fle_given) {
    if (!std::isfinite(o.fle_mm) || o.fle_mm < 0) throw_input_error("--fle-mm", "must be a non-negative number");
    fle = o.fle_mm;
  }
  StageTimer timer;
  const std::vector<Eigen::Vector3d> fixed = read_complete_points_3d(o.fixed);
  const std::vector<Eigen::Vector3d> moving = read_complete_points_3d(o.moving);
  if (fixed.size() != moving.size())
    throw_input_error(o.moving, std::to_string(moving.size()) + " points, but " + o.fixed + " has " +
                                    std::to_string(fixed.size()) + ": the lists must pair point by point");
  std::vector<Eigen::Vector3d> targets;
  if (!o.targets.empty()) targets = read_complete_points_3d(o.targets);
  const std::vector<double> weights = read_weights(o.moving, moving.size());
  timer.lap("read");
  const PairedRegistration reg = register_paired_points(fixed, moving, targets, fle, weights);
  timer.lap("register");

  nlohmann::json doc;
  doc["status"] = reg.ok ? "ok" : "failed";
  if (!reg.ok) doc["reason"] = reg.failure_reason;
  doc["points"] = moving.size();
  if (reg.ok) {
    doc["T_fixed_moving"] = pose_to_json(reg.T_fixed_moving)["T_world_ct"];
    doc["fre_rms_mm"] = reg.fre_rms_mm;
    doc["fre_max_mm"] = reg.fre_max_mm;
    doc["weighted"] = !weights.empty();
    if (!o.targets.empty()) {
      doc["predicted_tre_rms_mm"] = reg.predicted_tre_rms_mm;
      doc["fle_rms_mm"] = reg.fle_rms_mm;
      doc["fle_source"] = std::string(reg.fle_estimated ? "estimated from FRE: FLE^2 = FRE^2 N / (N - 2) (Fitzpatrick et al. 1998)"
                                                         : "given (--fle-mm)") +
                          (weights.empty() ? "" : "; per point FLE_i^2 ~ 1 / weight_i with this RMS, TRE by first-order propagation");
    }
    if (reg.fle_check) {
      const FleCheck& c = *reg.fle_check;
      nlohmann::json check = {{"fle_from_residuals_mm", c.fle_from_residuals_mm},
                              {"chi2", c.chi2},
                              {"chi2_limit", c.chi2_limit},
                              {"consistent", c.consistent}};
      if (!c.consistent && !o.targets.empty()) check["predicted_tre_rms_mm"] = c.predicted_tre_rms_mm;
      doc["fle_check"] = check;
    }
  }
  nlohmann::json inputs = {{"fixed", file_digest(o.fixed)}, {"moving", file_digest(o.moving)}};
  if (!o.targets.empty()) inputs["targets"] = file_digest(o.targets);
  doc["inputs"] = inputs;
  doc["provenance"] = provenance("register-points",
                                 {{"fle_mm", fle ? nlohmann::json(*fle) : nlohmann::json("estimated from the FRE")},
                                  {"weighted", !weights.empty()},
                                  {"targets", targets.size()}},
                                 inputs);
  doc["timings_s"] = timer.json();
  write_json(doc, o.out);
  if (!reg.ok) throw MethodFailed(o.out + ": registration failed: " + reg.failure_reason);
  if (!quiet()) {
    std::printf("%s: %zu point pairs, FRE rms %.3f mm (max %.3f mm)\n", o.out.c_str(), moving.size(), reg.fre_rms_mm,
                reg.fre_max_mm);
    if (!o.targets.empty())
      std::printf("  predicted TRE at %zu targets with FLE %.3f mm (%s)\n", targets.size(), reg.fle_rms_mm,
                  reg.fle_estimated ? "estimated from FRE" : "given");
  }
  // A TRE predicted with an FLE the residuals refute is optimistic: said on stdout (which -q closes,
  // as for every line on success) and in the file's fle_check.
  if (reg.fle_check && !reg.fle_check->consistent)
    std::printf("%s: the residuals imply an FLE of %.3f mm, more than --fle-mm %.3f allows (chi^2 %.1f > %.1f, "
                "p < 0.001): the predicted TRE is optimistic%s\n",
                o.out.c_str(), reg.fle_check->fle_from_residuals_mm, reg.fle_rms_mm, reg.fle_check->chi2, reg.fle_check->chi2_limit,
                o.targets.empty() ? "" : " (fle_check.predicted_tre_rms_mm: with the residuals' FLE)");
}

}  // namespace

void add_register_points_command(CLI::App& app) {
  auto o = std::make_shared<RegisterPointsOptions>();
  auto* cmd = app.add_subcommand("register-points", "Paired-point rigid registration with FRE and predicted TRE");
  cmd->add_option("--fixed", o->fixed, "Point list in the fixed frame")->required();
  cmd->add_option("--moving", o->moving, "The same points, same order, in the moving frame")->required();
  cmd->add_option("--targets", o->targets, "Target points (moving frame) for the predicted TRE");
  auto* fle = cmd->add_option("--fle-mm", o->fle_mm, "RMS 3D fiducial localisation error (default: estimated from the FRE)");
  cmd->add_option("--out", o->out, "Result JSON: T_fixed_moving, fre_rms_mm, predicted_tre_rms_mm")->required();
  cmd->callback([o, fle] {
    o->fle_given = fle->count() > 0;
    run(*o);
  });
}

}  // namespace fluoro::cli

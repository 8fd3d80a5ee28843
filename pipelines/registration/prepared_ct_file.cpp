#include "pipelines/registration/prepared_ct_file.hpp"

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zlib.h>

#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>
#include <tbb/task_group.h>

#include <algorithm>
#include <atomic>
#include <bit>
#include <chrono>
#include <cstring>
#include <fstream>
#include <optional>
#include <span>

#include "engine/atomic_file.hpp"
#include "engine/error.hpp"
#include "engine/sha256.hpp"
#include "engine/version.hpp"

namespace fluoro {
namespace {

// The file stores numbers as they are in memory; every platform the project builds on is
// little-endian, and a big-endian one would have to swap them.
static_assert(std::endian::native == std::endian::little, "prepared files are little-endian");

constexpr char kMagic[8] = {'F', 'L', 'U', 'O', 'P', 'R', 'E', 'P'};
constexpr char kEndMarker[4] = {'P', 'E', 'N', 'D'};
constexpr size_t kFixedHead = 24;  // magic, format version, header length, file length
constexpr size_t kTrailer = 8;     // CRC-32, end marker
constexpr size_t kAlign = 64;

size_t align_up(size_t n) { return (n + kAlign - 1) / kAlign * kAlign; }

// CRC-32 (zlib) of `bytes`: pieces of 32 MiB in parallel, joined with crc32_combine.
uint32_t crc32_of(std::span<const uint8_t> bytes) {
  constexpr size_t kPiece = size_t(32) << 20;
  const size_t pieces = std::max<size_t>(1, (bytes.size() + kPiece - 1) / kPiece);
  std::vector<uLong> crcs(pieces);
  tbb::parallel_for(size_t(0), pieces, [&](size_t i) {
    const size_t begin = i * kPiece, n = std::min(kPiece, bytes.size() - std::min(begin, bytes.size()));
    crcs[i] = crc32(crc32(0L, Z_NULL, 0), bytes.data() + begin, uInt(n));
  });
  uLong crc = crcs[0];
  for (size_t i = 1; i < pieces; ++i)
    crc = crc32_combine(crc, crcs[i], z_off_t(std::min(kPiece, bytes.size() - i * kPiece)));
  return uint32_t(crc);
}

nlohmann::json geometry_json(const VolumeGeometry& g) {
  nlohmann::json d = nlohmann::json::array();
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) d.push_back(g.direction(r, c));
  return {{"size", {g.size.x(), g.size.y(), g.size.z()}},
          {"origin_mm", {g.origin.x(), g.origin.y(), g.origin.z()}},
          {"spacing_mm", {g.spacing.x(), g.spacing.y(), g.spacing.z()}},
          {"direction", d}};
}

VolumeGeometry geometry_from_json(const nlohmann::json& j) {
  VolumeGeometry g;
  for (int a = 0; a < 3; ++a) {
    g.size[a] = j.at("size").at(size_t(a)).get<int>();
    g.origin[a] = j.at("origin_mm").at(size_t(a)).get<double>();
    g.spacing[a] = j.at("spacing_mm").at(size_t(a)).get<double>();
  }
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) g.direction(r, c) = j.at("direction").at(size_t(3 * r + c)).get<double>();
  return g;
}

template <typename T>
std::span<const uint8_t> bytes_of(const std::vector<T>& v) {
  return {reinterpret_cast<const uint8_t*>(v.data()), v.size() * sizeof(T)};
}

// A read-only map of a whole file; unmapped when it goes.
class MappedFile {
 public:
  explicit MappedFile(const std::string& path) {
    const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0) throw_input_error(path, std::string("cannot open: ") + std::strerror(errno));
    if (::fstat(fd, &stat_) != 0 || !S_ISREG(stat_.st_mode)) {
      ::close(fd);
      throw_input_error(path, "not a regular file");
    }
    size_ = size_t(stat_.st_size);
    if (size_ > 0) {
      void* p = ::mmap(nullptr, size_, PROT_READ, MAP_PRIVATE | MAP_POPULATE, fd, 0);
      if (p == MAP_FAILED) {
        ::close(fd);
        throw_input_error(path, std::string("cannot read: ") + std::strerror(errno));
      }
      data_ = static_cast<const uint8_t*>(p);
    }
    ::close(fd);
  }
  ~MappedFile() {
    if (data_) ::munmap(const_cast<uint8_t*>(data_), size_);
  }
  MappedFile(const MappedFile&) = delete;
  MappedFile& operator=(const MappedFile&) = delete;
  std::span<const uint8_t> bytes() const { return {data_, size_}; }
  const struct stat& stat() const { return stat_; }
  // Gives back the whole pages inside `part` (copied elsewhere already), so that the file's pages
  // and the volumes made from them are not all resident at once.
  void release(std::span<const uint8_t> part) const {
    const size_t page = size_t(::sysconf(_SC_PAGESIZE));
    const size_t begin = (size_t(part.data() - data_) + page - 1) / page * page;
    const size_t end = size_t(part.data() + part.size() - data_) / page * page;
    if (end > begin) ::madvise(const_cast<uint8_t*>(data_) + begin, end - begin, MADV_DONTNEED);
  }

 private:
  const uint8_t* data_ = nullptr;
  size_t size_ = 0;
  struct stat stat_ {};
};

// The SHA-256 of bytes, computed by a task beside the caller's work. Abandoned when it goes
// unasked (a file refused before its end is hashed for nothing).
class DigestOnTheSide {
 public:
  explicit DigestOnTheSide(std::span<const uint8_t> bytes) {
    tasks_.run([this, bytes] {
      constexpr size_t kPiece = size_t(1) << 20;
      Sha256 s;
      for (size_t at = 0; at < bytes.size(); at += kPiece) {
        if (abandon_.load(std::memory_order_relaxed)) return;
        s.update(bytes.data() + at, std::min(kPiece, bytes.size() - at));
      }
      hex_ = s.hex();
    });
  }
  ~DigestOnTheSide() {
    abandon_ = true;
    try {
      tasks_.wait();
    } catch (...) {  // nothing to report it to: the digest was not asked for
    }
  }
  DigestOnTheSide(const DigestOnTheSide&) = delete;
  DigestOnTheSide& operator=(const DigestOnTheSide&) = delete;
  const std::string& hex() {
    tasks_.wait();
    return hex_;
  }

 private:
  tbb::task_group tasks_;
  std::atomic<bool> abandon_{false};
  std::string hex_;
};

std::string short_digest(const std::string& sha256) { return sha256.substr(0, 12); }

// The first setting (depth first, in document order) where `a` and `b` differ, as "key a vs b".
std::string first_difference(const nlohmann::json& a, const nlohmann::json& b, const std::string& key) {
  if (a.is_object() && b.is_object()) {
    for (auto it = a.begin(); it != a.end(); ++it) {
      const std::string k = key.empty() ? it.key() : key + "." + it.key();
      if (!b.contains(it.key())) return k + " " + it.value().dump() + " against none";
      const std::string d = first_difference(it.value(), b.at(it.key()), k);
      if (!d.empty()) return d;
    }
    for (auto it = b.begin(); it != b.end(); ++it)
      if (!a.contains(it.key())) return (key.empty() ? it.key() : key + "." + it.key()) + " none against " + it.value().dump();
    return {};
  }
  if (a.is_array() && b.is_array() && a.size() == b.size()) {
    for (size_t i = 0; i < a.size(); ++i) {
      const std::string d = first_difference(a[i], b[i], key + "[" + std::to_string(i) + "]");
      if (!d.empty()) return d;
    }
    return {};
  }
  return a == b ? std::string() : key + " " + a.dump() + " against " + b.dump();
}

}  // namespace

void write_prepared_ct(const std::string& path, Backend& backend, const PreparedCt& ct, const PreparedCtSource& source) {
  // Every section's bytes first (the volumes in the backend's own form), then the header that
  // lists them with offsets relative to the first section.
  struct Section {
    nlohmann::json entry;
    std::vector<uint8_t> owned;
    std::span<const uint8_t> bytes;
  };
  std::vector<Section> sections;
  auto add = [&](nlohmann::json entry, std::vector<uint8_t> owned, std::span<const uint8_t> view) {
    sections.push_back({std::move(entry), std::move(owned), view});
    Section& s = sections.back();
    if (!s.owned.empty()) s.bytes = s.owned;
  };
  std::vector<int32_t> triangles, edges;
  for (const auto& t : ct.mesh.triangles) triangles.insert(triangles.end(), t.begin(), t.end());
  for (const auto& e : ct.mesh.edges) edges.insert(edges.end(), {e.a, e.b, e.left, e.right});
  static_assert(sizeof(Eigen::Vector3d) == 24);
  add({{"name", "mesh.vertices"}, {"count", ct.mesh.vertices.size()}}, {}, bytes_of(ct.mesh.vertices));
  add({{"name", "mesh.triangles"}, {"count", ct.mesh.triangles.size()}}, {}, bytes_of(triangles));
  add({{"name", "mesh.edges"}, {"count", ct.mesh.edges.size()}}, {}, bytes_of(edges));
  auto add_volume = [&](const std::string& name, const DeviceVolume& v) {
    add({{"name", name}, {"components", v.components()}, {"geometry", geometry_json(v.geometry())}},
        backend.save_volume(v), {});
  };
  add_volume("bone_mu", *ct.bone_mu);
  add_volume("non_bone_mu", *ct.non_bone_mu);
  for (size_t i = 0; i < ct.gradients.size(); ++i) add_volume("gradient." + std::to_string(i + 1), *ct.gradients[i]);

  nlohmann::json list = nlohmann::json::array();
  size_t offset = 0;
  for (Section& s : sections) {
    s.entry["offset"] = offset;
    s.entry["bytes"] = s.bytes.size();
    list.push_back(s.entry);
    offset = align_up(offset + s.bytes.size());
  }
  nlohmann::json header = {{"program", "fluoro"},
                           {"version", kVersion},
                           {"backend", std::string(backend.name())},
                           {"ct", {{"path", source.ct_path}, {"sha256", source.ct_sha256}}},
                           {"mask", source.mask_path.empty() ? nlohmann::json(nullptr)
                                                             : nlohmann::json{{"path", source.mask_path}, {"sha256", source.mask_sha256}}},
                           {"settings", source.settings},
                           {"sections", list}};
  const std::string text = header.dump();
  const size_t payload = align_up(kFixedHead + text.size());
  const uint64_t file_bytes = payload + offset + kTrailer;

  write_file_atomic(path, [&](const std::string& tmp) {
    std::ofstream f(tmp, std::ios::binary);
    if (!f) throw_input_error(path, "cannot write");
    uLong crc = crc32(0L, Z_NULL, 0);
    size_t written = 0;
    auto put = [&](const void* p, size_t n) {
      f.write(static_cast<const char*>(p), std::streamsize(n));
      for (size_t done = 0; done < n;) {  // zlib takes 32-bit lengths
        const size_t piece = std::min<size_t>(n - done, size_t(1) << 30);
        crc = crc32(crc, static_cast<const Bytef*>(p) + done, uInt(piece));
        done += piece;
      }
      written += n;
    };
    const std::vector<uint8_t> zeros(kAlign, 0);
    auto pad_to = [&](size_t at) { put(zeros.data(), at - written); };
    const uint32_t version = kPreparedCtFormatVersion, text_bytes = uint32_t(text.size());
    put(kMagic, 8);
    put(&version, 4);
    put(&text_bytes, 4);
    put(&file_bytes, 8);
    put(text.data(), text.size());
    for (size_t i = 0; i < sections.size(); ++i) {
      pad_to(payload + list[i]["offset"].get<size_t>());
      put(sections[i].bytes.data(), sections[i].bytes.size());
    }
    pad_to(payload + offset);
    const uint32_t sum = uint32_t(crc);
    f.write(reinterpret_cast<const char*>(&sum), 4);
    f.write(kEndMarker, 4);
    if (!f.flush()) throw_input_error(path, "write failed (disk full?)");
  });
}

std::shared_ptr<const PreparedCt> read_prepared_ct(const std::string& path, Backend& backend,
                                                   const PreparedCtSource& expected, bool digest) {
  const auto t0 = std::chrono::steady_clock::now();
  const std::string again = "prepare it again (fluoro prepare --ct CT ... --out " + path + ")";
  const MappedFile file(path);
  const std::span<const uint8_t> b = file.bytes();
  // On one core while the checks and the volumes' loading take the other (the file's pages are
  // released as volumes are made from them: the digest reads them first where it can).
  std::optional<DigestOnTheSide> side;
  if (digest) side.emplace(b);
  // Isolated: the loading's own waits (the checksum's and the volumes' parallel loops) never
  // take up the digest's task, which would hold up the loading for its whole length.
  // The digest is waited for outside: an isolated wait could not run its task itself.
  const std::shared_ptr<PreparedCt> loaded = tbb::this_task_arena::isolate([&]() -> std::shared_ptr<PreparedCt> {
    if (b.size() < 8 || std::memcmp(b.data(), kMagic, 8) != 0)
      throw_input_error(path, "not a prepared CT file (fluoro prepare writes them)");
    if (b.size() < kFixedHead + kTrailer) throw_input_error(path, "truncated: " + std::to_string(b.size()) + " bytes; " + again);
    uint32_t version = 0, text_bytes = 0;
    uint64_t file_bytes = 0;
    std::memcpy(&version, b.data() + 8, 4);
    std::memcpy(&text_bytes, b.data() + 12, 4);
    std::memcpy(&file_bytes, b.data() + 16, 8);
    if (version != kPreparedCtFormatVersion)
      throw_input_error(path, "prepared file format version " + std::to_string(version) + ", this fluoro (" + kVersion +
                                  ") reads version " + std::to_string(kPreparedCtFormatVersion) + ": " + again);
    if (b.size() < file_bytes)
      throw_input_error(path, "truncated: " + std::to_string(b.size()) + " of " + std::to_string(file_bytes) + " bytes; " + again);
    if (b.size() != file_bytes || std::memcmp(b.data() + b.size() - 4, kEndMarker, 4) != 0)
      throw_input_error(path, "corrupt: " + std::to_string(b.size()) + " bytes where its header says " +
                                  std::to_string(file_bytes) + "; " + again);
    uint32_t stored_crc = 0;
    std::memcpy(&stored_crc, b.data() + b.size() - kTrailer, 4);
    if (crc32_of(b.first(b.size() - kTrailer)) != stored_crc)
      throw_input_error(path, "corrupt: its checksum does not match its contents; " + again);

    // From here on the bytes are the ones written: a malformed header is a writer's bug, still
    // reported as bad input rather than trusted.
    nlohmann::json h;
    try {
      if (kFixedHead + size_t(text_bytes) > b.size() - kTrailer) throw std::runtime_error("header length");
      h = nlohmann::json::parse(b.begin() + kFixedHead, b.begin() + kFixedHead + text_bytes);
      const std::string program_version = h.at("version").get<std::string>();
      if (program_version != kVersion)
        throw_input_error(path, "prepared by fluoro " + program_version + ", this is fluoro " + kVersion + ": " + again);
      const std::string ct_sha = h.at("ct").at("sha256").get<std::string>();
      const std::string ct_path = h.at("ct").at("path").get<std::string>();
      if (ct_sha != expected.ct_sha256)
        throw_input_error(path, "prepared from CT " + ct_path + " (sha256 " + short_digest(ct_sha) + "...), not from " +
                                    expected.ct_path + " (sha256 " + short_digest(expected.ct_sha256) +
                                    "...): give the CT it was prepared from, or prepare this one");
      const nlohmann::json& mask = h.at("mask");
      if (mask.is_null() != expected.mask_path.empty())
        throw_input_error(path, mask.is_null() ? "prepared without a bone mask, this run gives " + expected.mask_path + ": " + again
                                               : "prepared with the bone mask " + mask.at("path").get<std::string>() +
                                                     ", this run gives none: add --mask, or " + again);
      if (!mask.is_null() && mask.at("sha256").get<std::string>() != expected.mask_sha256)
        throw_input_error(path, "prepared with the mask " + mask.at("path").get<std::string>() + " (sha256 " +
                                    short_digest(mask.at("sha256").get<std::string>()) + "...), not with " +
                                    expected.mask_path + " (sha256 " + short_digest(expected.mask_sha256) + "...)");
      const std::string difference = first_difference(h.at("settings"), expected.settings, "");
      // A file from before a change in how fields are prepared differs in a key no option sets.
      if (!difference.empty() && !h.at("settings").contains("field_axes_coarser_than_grid"))
        throw_input_error(path, "prepared by an older version of this program, whose fields' grids differ: " + again);
      if (!difference.empty())
        throw_input_error(path, "prepared with other settings than this run's (" + difference +
                                    "): give the same --iso, --tissue-hu and --mu-water, or " + again);
      const std::string prepared_backend = h.at("backend").get<std::string>();
      if (prepared_backend != backend.name())
        throw_input_error(path, "prepared for the " + prepared_backend + " backend, this run uses " +
                                    std::string(backend.name()) + ": run with --backend " + prepared_backend + ", or " + again);

      const size_t payload = align_up(kFixedHead + text_bytes);
      auto section = [&](const nlohmann::json& s, const std::string& name) {
        if (s.at("name").get<std::string>() != name) throw std::runtime_error("section order");
        const size_t offset = s.at("offset").get<size_t>(), n = s.at("bytes").get<size_t>();
        const size_t limit = b.size() - kTrailer - std::min(payload, b.size() - kTrailer);  // payload bytes
        if (offset > limit || n > limit - offset) throw std::runtime_error("section bounds");
        return b.subspan(payload + offset, n);
      };
      const nlohmann::json& list = h.at("sections");
      const size_t stages = expected.settings.at("fine_stages").size();
      if (list.size() != 5 + stages) throw std::runtime_error("section count");
      auto p = std::make_shared<PreparedCt>();
      auto counted = [&](size_t i, const std::string& name, size_t item_bytes) {
        const auto bytes = section(list[i], name);
        const size_t count = list[i].at("count").get<size_t>();
        if (bytes.size() != count * item_bytes) throw std::runtime_error("section size");
        return std::pair{bytes, count};
      };
      const auto [vertices, nv] = counted(0, "mesh.vertices", 24);
      p->mesh.vertices.resize(nv);
      for (size_t i = 0; i < nv; ++i) {
        double xyz[3];
        std::memcpy(xyz, vertices.data() + 24 * i, 24);
        p->mesh.vertices[i] = {xyz[0], xyz[1], xyz[2]};
      }
      const auto [triangles, nt] = counted(1, "mesh.triangles", 12);
      p->mesh.triangles.resize(nt);
      std::memcpy(p->mesh.triangles.data(), triangles.data(), triangles.size());
      const auto [edges, ne] = counted(2, "mesh.edges", 16);
      p->mesh.edges.resize(ne);
      std::memcpy(p->mesh.edges.data(), edges.data(), edges.size());
      // A copy: clang 14 cannot capture a structured binding (C++20 allows it, clang 16 does).
      auto in_range = [vertex_count = nv](int v) { return v >= 0 && size_t(v) < vertex_count; };
      for (const auto& t : p->mesh.triangles)
        if (!in_range(t[0]) || !in_range(t[1]) || !in_range(t[2])) throw std::runtime_error("triangle index");
      for (const auto& e : p->mesh.edges)
        if (!in_range(e.a) || !in_range(e.b) || !in_range(e.left) || !in_range(e.right)) throw std::runtime_error("edge index");
      auto volume = [&](size_t i, const std::string& name) {
        const auto bytes = section(list[i], name);
        auto v = backend.load_volume(geometry_from_json(list[i].at("geometry")), list[i].at("components").get<int>(), bytes,
                                     path + " (" + name + ")");
        file.release(bytes);
        return v;
      };
      p->bone_mu = volume(3, "bone_mu");
      if (p->bone_mu->components() != 1) throw std::runtime_error("bone_mu components");
      p->non_bone_mu = volume(4, "non_bone_mu");
      if (p->non_bone_mu->components() != 1) throw std::runtime_error("non_bone_mu components");
      for (size_t i = 0; i < stages; ++i) {
        p->gradients.push_back(volume(5 + i, "gradient." + std::to_string(i + 1)));
        if (p->gradients.back()->components() != 3) throw std::runtime_error("gradient components");
      }
      return p;
    } catch (const nlohmann::json::exception& e) {
      throw_input_error(path, std::string("malformed header (") + e.what() + "); " + again);
    } catch (const std::runtime_error& e) {
      if (dynamic_cast<const InputError*>(&e)) throw;
      throw_input_error(path, std::string("malformed contents (") + e.what() + "); " + again);
    }
  });
  if (side) remember_sha256_of_input(path, file.stat(), side->hex());
  loaded->seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return loaded;
}

}  // namespace fluoro

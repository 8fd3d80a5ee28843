#include "engine/nifti_header.hpp"

#include <zlib.h>

#include <Eigen/Core>
#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <limits>
#include <optional>
#include <sstream>
#include <utility>
#include <vector>

#include "engine/error.hpp"
#include "engine/volume_header_common.hpp"
#include "engine/widen_to_float.hpp"

namespace fluoro {
namespace {

// Voxel sizes a header may hold, in its units (mm, but metres and microns exist).
constexpr double kMinVoxel = 1e-9, kMaxVoxel = 1e9;

template <class T>
T read_raw(const unsigned char* p, bool swap) {
  unsigned char b[sizeof(T)];
  std::memcpy(b, p, sizeof(T));
  if (swap) std::reverse(b, b + sizeof(T));
  T v;
  std::memcpy(&v, b, sizeof(T));
  return v;
}

// The fields of either header version that the checks need, widened to the NIfTI-2 types.
struct Header {
  int version = 1;
  bool single_file = false;  // "n+1"/"n+2": the voxels follow the header in the same file
  int64_t dim[8] = {};
  int datatype = 0;
  double pixdim[8] = {};
  double vox_offset = 0;
  int qform_code = 0, sform_code = 0;
  double quatern[3] = {}, qoffset[3] = {};
  double srow[3][4] = {};
  double scl_slope = 0, scl_inter = 0;
};

template <class Int, class Real>
void read_fields(Header& h, const unsigned char* p, bool swap, const size_t off_dim, size_t off_datatype,
                 size_t off_pixdim, size_t off_vox, size_t off_qcode, size_t off_scode, size_t off_quat,
                 size_t off_srow, size_t code_size) {
  for (int i = 0; i < 8; ++i) h.dim[i] = read_raw<Int>(p + off_dim + i * sizeof(Int), swap);
  h.datatype = read_raw<int16_t>(p + off_datatype, swap);
  for (int i = 0; i < 8; ++i) h.pixdim[i] = read_raw<Real>(p + off_pixdim + i * sizeof(Real), swap);
  h.vox_offset = sizeof(Real) == 4 ? double(read_raw<float>(p + off_vox, swap))
                                   : double(read_raw<int64_t>(p + off_vox, swap));
  h.qform_code = code_size == 2 ? read_raw<int16_t>(p + off_qcode, swap) : read_raw<int32_t>(p + off_qcode, swap);
  h.sform_code = code_size == 2 ? read_raw<int16_t>(p + off_scode, swap) : read_raw<int32_t>(p + off_scode, swap);
  for (int i = 0; i < 3; ++i) h.quatern[i] = read_raw<Real>(p + off_quat + i * sizeof(Real), swap);
  for (int i = 0; i < 3; ++i) h.qoffset[i] = read_raw<Real>(p + off_quat + (3 + i) * sizeof(Real), swap);
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 4; ++c) h.srow[r][c] = read_raw<Real>(p + off_srow + (4 * r + c) * sizeof(Real), swap);
}

// Bytes per voxel of the datatypes ITK reads; 0 for codes NIfTI does not define or ITK cannot read
// (float128, complex256).
int datatype_bytes(int datatype) {
  switch (datatype) {
    case 2: case 256: return 1;                  // uint8, int8
    case 4: case 512: return 2;                  // int16, uint16
    case 8: case 768: case 16: case 2304: return 4;  // int32, uint32, float32, rgba32
    case 128: return 3;                              // rgb24
    case 64: case 1024: case 1280: case 32: return 8;  // float64, (u)int64, complex64
    case 1792: return 16;                        // complex128
    default: return 0;
  }
}

// Below the smallest normal float but not 0: a subnormal in a NIfTI-1 header's float fields.
bool tiny(double v) { return v != 0 && std::abs(v) < double(std::numeric_limits<float>::min()); }

std::string number(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

[[noreturn]] void bad_nifti(const std::string& path, const std::string& problem) {
  throw_input_error(path, "NIfTI header: " + problem);
}

void check_fields(const Header& h, const std::string& path) {
  if (h.dim[0] < 1 || h.dim[0] > 7)
    bad_nifti(path, "dim[0] is " + std::to_string(h.dim[0]) + " (the number of dimensions must be 1 to 7)");
  double voxels = 1;
  for (int i = 1; i <= h.dim[0]; ++i) {
    if (h.dim[i] < 1) bad_nifti(path, "dim[" + std::to_string(i) + "] is " + std::to_string(h.dim[i]) + " (sizes must be positive)");
    voxels *= double(h.dim[i]);
  }
  const int bytes = datatype_bytes(h.datatype);
  if (bytes == 0) bad_nifti(path, "unknown or unsupported datatype " + std::to_string(h.datatype));
  if (voxels * bytes > kMaxVolumeDataBytes)
    bad_nifti(path, "describes " + number(voxels * bytes) + " bytes of voxels (more than 4 TiB)");
  for (int i = 1; i <= std::min<int64_t>(h.dim[0], 3); ++i) {
    const double s = std::abs(h.pixdim[i]);
    if (!(s >= kMinVoxel && s <= kMaxVoxel))
      bad_nifti(path, "voxel size pixdim[" + std::to_string(i) + "] is " + number(h.pixdim[i]));
  }
  if (!std::isfinite(h.vox_offset) || h.vox_offset < 0 || h.vox_offset > kMaxVolumeDataBytes)
    bad_nifti(path, "data offset vox_offset is " + number(h.vox_offset));
  if (h.qform_code > 0) {
    double q2 = 0;
    for (int i = 0; i < 3; ++i) {
      if (!std::isfinite(h.quatern[i])) bad_nifti(path, "qform quaternion has a non-finite value");
      if (tiny(h.quatern[i])) bad_nifti(path, "qform quaternion has a subnormal value");
      if (!(std::abs(h.qoffset[i]) <= kMaxVolumeCoordinate)) bad_nifti(path, "qform offset is " + number(h.qoffset[i]));
      q2 += h.quatern[i] * h.quatern[i];
    }
    // b, c, d of a unit quaternion (a is implied); a little slack for rounding in writers.
    if (q2 > 1.0001) bad_nifti(path, "qform quaternion (b, c, d) is longer than 1, not a rotation");
  }
  if (h.sform_code > 0) {
    Eigen::Matrix3d m;
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) {
        if (!std::isfinite(h.srow[r][c])) bad_nifti(path, "sform matrix has a non-finite value");
        // No writer produces subnormals; VNL's SVD (LINPACK) fails on them, printing to stderr.
        if (tiny(h.srow[r][c])) bad_nifti(path, "sform matrix has a subnormal value");
        m(r, c) = h.srow[r][c];
      }
      if (!(std::abs(h.srow[r][3]) <= kMaxVolumeCoordinate)) bad_nifti(path, "sform offset is " + number(h.srow[r][3]));
    }
    for (int c = 0; c < 3; ++c) {
      const double n = m.col(c).norm();
      if (!(n >= kMinVoxel && n <= kMaxVoxel))
        bad_nifti(path, "sform column " + std::to_string(c) + " has length " + number(n) + " (a voxel size)");
      m.col(c) /= n;
    }
    // The axes' directions must span space: ITK's SVD of a (near-)singular one fails or never ends.
    if (!(std::abs(m.determinant()) > 1e-6)) bad_nifti(path, "sform axes are (nearly) parallel, not an orientation");
  }
}

// The stored type of the datatypes read_nifti_voxels converts (the scalar ones; not rgb, complex or
// float128).
std::optional<StoredType> stored_type(int datatype) {
  switch (datatype) {
    case 2: return StoredType::u8;
    case 256: return StoredType::i8;
    case 4: return StoredType::i16;
    case 512: return StoredType::u16;
    case 8: return StoredType::i32;
    case 768: return StoredType::u32;
    case 16: return StoredType::f32;
    case 64: return StoredType::f64;
    case 1024: return StoredType::i64;
    case 1280: return StoredType::u64;
    default: return std::nullopt;
  }
}

struct GzCloser {
  gzFile f;
  ~GzCloser() { gzclose(f); }
};

std::optional<NiftiVoxels> check_nifti_file(const std::string& path, bool want_voxels) {
  gzFile f = gzopen(path.c_str(), "rb");  // zlib reads an uncompressed file transparently
  if (!f) throw_input_error(path, "cannot open file");
  GzCloser closer{f};
  unsigned char hdr[540] = {};
  const int got = gzread(f, hdr, sizeof hdr);
  if (got < 348)
    throw_input_error(path, "file truncated (" + std::to_string(std::max(got, 0)) +
                                " bytes, shorter than a NIfTI header)");
  int32_t sizeof_hdr = read_raw<int32_t>(hdr, false);
  bool swap = false;
  if (sizeof_hdr != 348 && sizeof_hdr != 540) {
    swap = true;
    sizeof_hdr = read_raw<int32_t>(hdr, true);
  }
  Header h;
  if (sizeof_hdr == 348) {
    h.single_file = std::memcmp(hdr + 344, "n+1", 4) == 0;
    read_fields<int16_t, float>(h, hdr, swap, 40, 70, 76, 108, 252, 254, 256, 280, 2);
    h.scl_slope = read_raw<float>(hdr + 112, swap);
    h.scl_inter = read_raw<float>(hdr + 116, swap);
  } else if (sizeof_hdr == 540) {
    if (got < 540) throw_input_error(path, "file truncated (shorter than a NIfTI-2 header)");
    h.version = 2;
    h.single_file = std::memcmp(hdr + 4, "n+2", 4) == 0;
    read_fields<int64_t, double>(h, hdr, swap, 16, 12, 104, 168, 344, 348, 352, 400, 4);
    h.scl_slope = read_raw<double>(hdr + 176, swap);
    h.scl_inter = read_raw<double>(hdr + 184, swap);
  } else {
    throw_input_error(path, "not a NIfTI file (header size field is " +
                                std::to_string(read_raw<int32_t>(hdr, false)) + ", expected 348 or 540)");
  }
  check_fields(h, path);
  if (!h.single_file) return std::nullopt;  // a .hdr/.img pair: the voxels live in the other file

  // ITK 5.2 reads a short file without an error and hands back garbage for the missing voxels.
  const double header_bytes = h.version == 1 ? 352 : 544;
  const auto offset = uint64_t(std::max(h.vox_offset, header_bytes));
  double voxels = 1;
  for (int i = 1; i <= h.dim[0]; ++i) voxels *= double(h.dim[i]);
  const uint64_t need = offset + uint64_t(voxels * datatype_bytes(h.datatype));
  // ITK 5.2 takes a slope of (nearly) 0 for 1 and rescales unless the intercept is 0 and the slope
  // 1: scaled files, byte-swapped ones, NIfTI-2 (which its NIfTI library refuses) and data offsets
  // below the 352 bytes ITK writes (its library floors them at 348, not 352) are left to it.
  const bool unscaled = (std::abs(h.scl_slope) < 2.2e-16 || h.scl_slope == 1) && h.scl_inter == 0;
  std::optional<NiftiVoxels> layout;
  const std::optional<StoredType> type = stored_type(h.datatype);
  if (want_voxels && h.version == 1 && h.vox_offset >= 352 && !swap && unscaled && type)
    layout = NiftiVoxels{offset, *type, uint64_t(voxels * datatype_bytes(h.datatype)), !gzdirect(f)};
  if (layout && layout->gzipped) return layout;  // read_nifti_voxels checks the length as it inflates
  uint64_t have = uint64_t(got);
  if (gzdirect(f)) {
    std::error_code ec;
    have = std::filesystem::file_size(path, ec);
  } else {
    // A gzip stream's size is only known by inflating it; stop as soon as enough has arrived.
    std::vector<char> chunk(1 << 20);
    while (have < need) {
      const int n = gzread(f, chunk.data(), unsigned(chunk.size()));
      if (n <= 0) break;
      have += uint64_t(n);
    }
  }
  if (have < need)
    throw_input_error(path, "file truncated (" + std::to_string(have) + " of the " + std::to_string(need) +
                                " bytes its header describes are present)");
  return layout;
}

}  // namespace

void check_nifti_header(const std::string& path) { check_nifti_file(path, false); }

std::optional<NiftiVoxels> check_nifti_header_for_voxels(const std::string& path) { return check_nifti_file(path, true); }

namespace {

// Reads the file's voxel bytes, from layout.offset on, into `reserve(done)`: the buffer to fill
// from `done` bytes read on (it may grow it), as large as it returns. Throws InputError naming the
// path when the file ends first.
template <class Reserve>
void read_voxel_bytes(gzFile f, const std::string& path, const NiftiVoxels& layout, Reserve reserve) {
  auto short_file = [&](uint64_t have) {
    throw_input_error(path, "file truncated (" + std::to_string(have) + " of the " +
                                std::to_string(layout.offset + layout.bytes) + " bytes its header describes are present)");
  };
  if (gzseek64(f, z_off64_t(layout.offset), SEEK_SET) != z_off64_t(layout.offset)) short_file(0);
  for (uint64_t done = 0; done < layout.bytes;) {
    const auto [dst, size] = reserve(done);
    const int n = gzread(f, dst + done, unsigned(std::min<uint64_t>(size - done, 1u << 30)));
    if (n <= 0) short_file(layout.offset + done);
    done += uint64_t(n);
  }
}

// Whether a gzip file's trailer says that it inflates to at least `bytes` (under 4 GiB): ISIZE, its
// last 4 bytes, is the last member's inflated length mod 2^32, and zlib checks it against the
// data. A file of several members (bgzip), or of 4 GiB or more, answers no and is inflated into
// a growing buffer instead, which costs two more passes over the voxels.
bool gzip_holds(const std::string& path, uint64_t bytes) {
  if (bytes >= (uint64_t(1) << 32)) return false;
  std::FILE* file = std::fopen(path.c_str(), "rb");
  if (!file) return false;
  unsigned char trailer[4] = {};
  const bool read = std::fseek(file, -4, SEEK_END) == 0 && std::fread(trailer, 1, 4, file) == 4;
  std::fclose(file);
  const uint32_t isize = uint32_t(trailer[0]) | uint32_t(trailer[1]) << 8 | uint32_t(trailer[2]) << 16 | uint32_t(trailer[3]) << 24;
  return read && isize >= bytes;
}

}  // namespace

VoxelBuffer read_nifti_voxels(const std::string& path, const NiftiVoxels& layout, size_t count) {
  if (layout.bytes != uint64_t(count) * uint64_t(stored_type_bytes(layout.type)))
    throw std::invalid_argument("read_nifti_voxels: the layout does not hold " + std::to_string(count) + " voxels");
  gzFile f = gzopen(path.c_str(), "rb");
  if (!f) throw_input_error(path, "cannot open file");
  GzCloser closer{f};
  gzbuffer(f, 1u << 20);
  if (layout.gzipped && !gzip_holds(path, layout.offset + layout.bytes)) {
    // Into a buffer that grows as the data arrive: a header that claims far more voxels than its
    // file holds fails on the data there is, before anything of the claimed size is allocated.
    std::vector<unsigned char, HugePageAllocator<unsigned char>> data;
    read_voxel_bytes(f, path, layout, [&](uint64_t done) {
      if (done == data.size()) data.resize(size_t(std::min<uint64_t>(layout.bytes, std::max<uint64_t>(2 * done, 1 << 24))));
      return std::pair{data.data(), uint64_t(data.size())};
    });
    VoxelBuffer out(count);
    widen_to_float(layout.type, data.data(), out.data(), count);
    return out;
  }
  // A plain file, whose length check_nifti_header_for_voxels has checked, or a gzipped one whose
  // trailer says it holds the voxels.
  return read_widened(layout.type, count, [&](unsigned char* dst, size_t bytes) {
    read_voxel_bytes(f, path, layout, [&](uint64_t) { return std::pair{dst, uint64_t(bytes)}; });
  });
}

}  // namespace fluoro

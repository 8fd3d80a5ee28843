// The huge-page allocator (engine/huge_page_allocator.hpp): large buffers start on 2 MiB
// boundaries and are marked for transparent huge pages; small ones come from the standard
// allocator; the volume readers hand out such buffers. Under sanitizers every buffer comes from
// the standard allocator (kOwnMappings false): then only the values are checked.
#include <gtest/gtest.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <numeric>
#include <sstream>
#include <string>

#include "engine/huge_page_allocator.hpp"
#include "engine/volume.hpp"
#include "engine/volume_io.hpp"

namespace fluoro {
namespace {

constexpr uintptr_t kTwoMiB = uintptr_t(2) << 20;

// On a huge page boundary, where the allocator maps large buffers itself.
bool on_huge_page_boundary(const void* p) {
  return !HugePageAllocator<float>::kOwnMappings || reinterpret_cast<uintptr_t>(p) % kTwoMiB == 0;
}

std::string read_text(const std::string& path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

// The "THPeligible" line of /proc/self/smaps for the mapping that holds p; empty if not found.
std::string thp_eligible_of_mapping(const void* p) {
  std::istringstream smaps(read_text("/proc/self/smaps"));
  const uintptr_t a = reinterpret_cast<uintptr_t>(p);
  bool inside = false;
  for (std::string line; std::getline(smaps, line);) {
    uintptr_t lo = 0, hi = 0;
    char dash = 0;
    std::istringstream head(line);
    if (head >> std::hex >> lo >> dash >> hi && dash == '-' && line.find(':') > line.find(' ')) {
      inside = lo <= a && a < hi;
      continue;
    }
    if (inside && line.starts_with("THPeligible:")) return line;
  }
  return {};
}

TEST(HugePageAllocatorTest, LargeBuffersStartOnHugePagesAndKeepTheirValues) {
  VoxelBuffer big(3'000'000);  // 12 MB
  ASSERT_TRUE(on_huge_page_boundary(big.data()));
  std::iota(big.begin(), big.end(), 0.0f);
  EXPECT_EQ(big[2'999'999], 2'999'999.0f);
  big.resize(6'000'000);  // reallocation keeps the values and the alignment
  EXPECT_TRUE(on_huge_page_boundary(big.data()));
  EXPECT_EQ(big[2'999'999], 2'999'999.0f);
  EXPECT_EQ(big[5'999'999], 0.0f);
  VoxelBuffer copy = big;
  EXPECT_TRUE(copy == big);

  // A request whose size in bytes would wrap around is refused, not served small.
  EXPECT_THROW(HugePageAllocator<float>().allocate(SIZE_MAX / 2), std::bad_array_new_length);

  // Under kMinBytes: the standard allocator (no 2 MiB rounding of small buffers).
  const size_t small_count = HugePageAllocator<float>::kMinBytes / sizeof(float) - 1;
  VoxelBuffer small(small_count, 1.0f);
  EXPECT_EQ(small.back(), 1.0f);

  // Where the kernel offers transparent huge pages on request, the large mapping asks for them.
  const std::string mode = read_text("/sys/kernel/mm/transparent_hugepage/enabled");
  if (HugePageAllocator<float>::kOwnMappings &&
      (mode.find("[madvise]") != std::string::npos || mode.find("[always]") != std::string::npos)) {
    const std::string eligible = thp_eligible_of_mapping(big.data());
    if (!eligible.empty()) {
      EXPECT_NE(eligible.find('1'), std::string::npos) << eligible;
    }
  }
}

TEST(HugePageAllocatorTest, TheVolumeReadersHandOutHugePageBuffers) {
  const std::filesystem::path dir = std::filesystem::temp_directory_path() / "fluoro_huge_page_test";
  std::filesystem::create_directories(dir);
  Volume v;
  v.geometry.size = {128, 128, 96};  // 6 MB of floats
  v.voxels.assign(v.geometry.voxel_count(), 0.0f);
  for (size_t i = 0; i < v.voxels.size(); ++i) v.voxels[i] = float(i % 977);
  for (const char* name : {"v.nii", "v.mha"}) {
    SCOPED_TRACE(name);
    const std::string path = (dir / name).string();
    write_volume(v, path);
    const Volume back = read_volume(path);
    EXPECT_TRUE(on_huge_page_boundary(back.voxels.data()));
    EXPECT_TRUE(back.voxels == v.voxels);
  }
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace fluoro

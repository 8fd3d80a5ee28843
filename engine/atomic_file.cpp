#include "engine/atomic_file.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <atomic>
#include <filesystem>
#include <random>
#include <string_view>
#include <system_error>

#include "engine/error.hpp"

namespace fluoro {
namespace {

namespace fs = std::filesystem;

// The suffix a writer looks at: the last extension, plus the one before it when the last is a
// compression suffix, so "ct.nii.gz" gives ".nii.gz" and the temporary is still a gzipped NIfTI.
std::string writer_extension(const std::string& filename) {
  const size_t last = filename.rfind('.');
  if (last == std::string::npos || last == 0) return {};
  const std::string_view ext = std::string_view(filename).substr(last);
  if (ext == ".gz" || ext == ".bz2" || ext == ".xz" || ext == ".zst") {
    const size_t prev = filename.rfind('.', last - 1);
    if (prev != std::string::npos && prev != 0) return filename.substr(prev);
  }
  return std::string(ext);
}

// Unique among concurrent writers: the pid separates processes, the counter separates threads and
// calls, the random part guards against a stale temporary left by a killed process with our pid.
fs::path temporary_path(const fs::path& target) {
  static std::atomic<unsigned> counter{0};
  thread_local std::mt19937 rng{std::random_device{}()};
  const std::string name = target.filename().string();
  const std::string ext = writer_extension(name);
  const std::string stem = name.substr(0, name.size() - ext.size());
  for (;;) {
    const std::string tag = ".tmp" + std::to_string(::getpid()) + "-" +
                            std::to_string(counter.fetch_add(1)) + "-" +
                            std::to_string(rng() % 1000000u);
    fs::path candidate = target.parent_path() / (stem + tag + ext);
    std::error_code ec;
    if (!fs::exists(candidate, ec)) return candidate;
  }
}

// The writers close their files but do not sync them; without this a power loss after the rename
// could leave the new name pointing at incomplete data.
void sync_file(const fs::path& path) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return;  // the rename below reports a missing file
  ::fsync(fd);
  ::close(fd);
}

}  // namespace

void write_file_atomic(const std::string& path,
                       const std::function<void(const std::string&)>& write) {
  const fs::path target(path);
  if (target.filename().empty()) throw_input_error(path, "output path names a directory");
  const fs::path dir = target.parent_path();
  std::error_code ec;
  if (!dir.empty() && !fs::is_directory(dir, ec))
    throw_input_error(path, "output directory does not exist");
  if (fs::is_directory(target, ec)) throw_input_error(path, "output path is a directory");

  const fs::path tmp = temporary_path(target);
  try {
    write(tmp.string());
    sync_file(tmp);
    fs::rename(tmp, target);
  } catch (const InputError&) {
    fs::remove(tmp, ec);
    throw;
  } catch (const std::exception& e) {
    fs::remove(tmp, ec);  // best effort; the message names the target, not the temporary
    throw_input_error(path, std::string("cannot write: ") + e.what());
  }
}

}  // namespace fluoro

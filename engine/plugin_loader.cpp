#include "engine/plugin_loader.hpp"

#include <dlfcn.h>
#include <link.h>

#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <map>
#include <mutex>
#include <stdexcept>
#include <vector>

#include "engine/plugin_build_id.hpp"

namespace fluoro {
namespace {

namespace fs = std::filesystem;

// The file this code was loaded from: the program itself (whose dladdr name is only argv[0],
// perhaps a bare name found through PATH, so /proc/self/exe instead), or the shared library it
// is linked into (the Python module). Empty when neither is known as an absolute path.
fs::path own_file() {
  Dl_info info{};
  struct link_map* map = nullptr;
  if (!dladdr1(reinterpret_cast<void*>(&own_file), &info, reinterpret_cast<void**>(&map), RTLD_DL_LINKMAP))
    return {};
  std::error_code ec;
  if (map && map->l_name && *map->l_name == '\0') {  // the main program
    const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
    return ec ? fs::path() : exe;
  }
  const fs::path file = map && map->l_name ? map->l_name : (info.dli_fname ? info.dli_fname : "");
  if (!file.is_absolute()) return {};
  const fs::path resolved = fs::canonical(file, ec);
  return ec ? fs::path() : resolved;
}

std::vector<fs::path> plugin_directories() {
  std::vector<fs::path> dirs;
  if (const char* env = std::getenv("FLUORO_PLUGIN_DIR"); env && *env) dirs.emplace_back(env);
  if (const fs::path self = own_file(); !self.empty()) {
    const fs::path dir = self.parent_path();
    dirs.push_back((dir / FLUORO_PLUGIN_FROM_BIN).lexically_normal());
    if (dir.filename() == "python" && dir.parent_path().filename() == "fluoro") dirs.push_back(dir.parent_path());
  }
  dirs.emplace_back(FLUORO_PLUGIN_INSTALL_DIR);
  return dirs;
}

}  // namespace

void* plugin_symbol(const std::string& name, const char* symbol) {
  static std::mutex mutex;
  static std::map<std::string, void*> handles;
  const std::lock_guard lock(mutex);
  void*& handle = handles[name];
  if (!handle) {
    const std::string file = "lib" + name + ".so";
    const std::vector<fs::path> dirs = plugin_directories();
    std::string searched, reasons;
    for (const fs::path& dir : dirs) {
      searched += (searched.empty() ? "" : ", ") + dir.string();
      const fs::path candidate = dir / file;
      std::error_code ec;
      if (!fs::is_regular_file(candidate, ec)) continue;
      handle = dlopen(candidate.c_str(), RTLD_NOW | RTLD_LOCAL);
      if (handle) break;
      const char* why = dlerror();
      reasons += "; " + candidate.string() + ": " + (why ? why : "not loadable");
    }
    if (!handle)
      throw std::runtime_error("fluoro's installation lacks the module " + file + " (searched " + searched + reasons +
                               "; set FLUORO_PLUGIN_DIR to the directory that holds it)");
  }
  dlerror();
  void* address = dlsym(handle, symbol);
  if (!address) {
    const char* why = dlerror();
    throw std::runtime_error("the module lib" + name + ".so has no " + symbol + " (" + (why ? why : "null") +
                             "): it is from another build of fluoro");
  }
  return address;
}

void check_plugin_build(const std::string& name, const char* build_id) {
  if (!build_id || std::strcmp(build_id, kPluginBuildId) != 0)
    throw std::runtime_error("the module lib" + name + ".so is from another build of fluoro (" +
                             (build_id ? build_id : "unknown") + "; this is " + kPluginBuildId + ")");
}

}  // namespace fluoro

#include "engine/plugin_loader.hpp"

#include <dlfcn.h>

#include <cstdlib>
#include <filesystem>
#include <map>
#include <mutex>
#include <stdexcept>
#include <vector>

namespace fluoro {
namespace {

namespace fs = std::filesystem;

std::vector<fs::path> plugin_directories() {
  std::vector<fs::path> dirs;
  if (const char* env = std::getenv("FLUORO_PLUGIN_DIR"); env && *env) dirs.emplace_back(env);
  Dl_info info{};
  if (dladdr(reinterpret_cast<void*>(&plugin_directories), &info) && info.dli_fname && *info.dli_fname) {
    std::error_code ec;
    const fs::path self = fs::canonical(info.dli_fname, ec);
    if (!ec) {
      const fs::path dir = self.parent_path();
      dirs.push_back(dir);
      dirs.push_back(dir.parent_path() / "lib" / "fluoro");
      dirs.push_back(dir.parent_path());
    }
  }
  dirs.emplace_back(FLUORO_PLUGIN_BUILD_DIR);
  dirs.emplace_back(FLUORO_PLUGIN_INSTALL_DIR);
  return dirs;
}

}  // namespace

void* plugin_symbol(const std::string& name, const char* symbol) {
  static std::mutex mutex;
  static std::map<std::string, void*> handles;
  const std::lock_guard lock(mutex);
  void*& handle = handles[name];
  std::string reasons;
  if (!handle) {
    const std::string file = "lib" + name + ".so";
    for (const fs::path& dir : plugin_directories()) {
      const fs::path candidate = dir / file;
      std::error_code ec;
      if (!fs::is_regular_file(candidate, ec)) continue;
      handle = dlopen(candidate.c_str(), RTLD_NOW | RTLD_LOCAL);
      if (handle) break;
      const char* why = dlerror();
      reasons += "; " + candidate.string() + ": " + (why ? why : "not loadable");
    }
    if (!handle) {
      std::string searched;
      for (const fs::path& dir : plugin_directories()) searched += (searched.empty() ? "" : ", ") + dir.string();
      throw std::runtime_error("cannot load the module " + file + " (searched " + searched + reasons +
                               "; set FLUORO_PLUGIN_DIR to the directory that holds it)");
    }
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

}  // namespace fluoro

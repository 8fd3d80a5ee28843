#pragma once
// Backends by name. The built-in backends (reference, cpu, and vulkan where built) are listed here
// explicitly, in the library that compiles them: nothing depends on static-initialisation side
// effects, which a static library's linker would drop with any object nothing else references.
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "engine/backend.hpp"

namespace fluoro {

// "reference", "cpu" (and "vulkan" where built). A name may carry an option after a colon, handed
// to the backend's factory: "vulkan:1" is the vulkan backend on device 1. Throws InputError
// listing the available names for an unknown one, and BackendUnavailable when a backend that is
// built cannot run on this machine (say, no Vulkan device).
std::unique_ptr<Backend> make_backend(std::string_view name);
std::vector<std::string> backend_names();

// A backend from outside this library, under `name` (replacing a built-in of that name). The
// factory gets the option after the colon of "name:option" ("" without one); a backend that takes
// no option throws InputError for a non-empty one (see no_backend_option). Thread-safe.
using BackendFactory = std::unique_ptr<Backend> (*)(std::string_view option);
void register_backend(std::string_view name, BackendFactory factory);
void no_backend_option(std::string_view name, std::string_view option);

}  // namespace fluoro

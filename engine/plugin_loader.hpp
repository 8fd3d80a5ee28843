#pragma once
// Optional parts of the engine built as modules and loaded when first needed: libraries whose
// mere presence in the program costs every command its start-up (GDCM parses its DICOM dictionary
// in static initialisers; HDF5 pulls in curl, TLS and Kerberos). docs/benchmarks.md, "Start-up".
//
// A module lib<name>.so is looked for in, in order: $FLUORO_PLUGIN_DIR; LIBDIR/fluoro relative to
// the directory of the program (or shared library) this code is linked into, as installed
// (PREFIX/bin/fluoro finds PREFIX/LIBDIR/fluoro; the build tree mirrors that layout); the
// directory above it when that is LIBDIR/fluoro/python (the Python module); the configured
// prefix's LIBDIR/fluoro. Modules stay loaded until the process ends.
#include <string>

namespace fluoro {

// The address of `symbol` in module `name` (e.g. "fluoro_dicom"), loading it at the first call.
// Throws std::runtime_error naming the module, the places searched and the loader's reason: a
// fault of the installation, not of the input.
void* plugin_symbol(const std::string& name, const char* symbol);

// Throws std::runtime_error unless `build_id` (what module `name`'s entry point reports) is this
// build's kPluginBuildId (engine/plugin_build_id.hpp): same interface, compiler and sanitizers.
void check_plugin_build(const std::string& name, const char* build_id);

}  // namespace fluoro

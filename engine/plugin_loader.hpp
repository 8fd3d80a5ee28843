#pragma once
// Optional parts of the engine built as modules and loaded when first needed: libraries whose
// mere presence in the program costs every command its start-up (GDCM parses its DICOM dictionary
// in static initialisers; HDF5 pulls in curl, TLS and Kerberos). docs/benchmarks.md, "Start-up".
//
// A module lib<name>.so is looked for in, in order: $FLUORO_PLUGIN_DIR; beside the object this
// code is linked into and in its ../lib/fluoro and .. (an installed program in PREFIX/bin, the
// Python module in PREFIX/lib/fluoro/python); the build tree's lib/fluoro; the install prefix's
// lib/fluoro. Modules stay loaded until the process ends.
#include <string>

namespace fluoro {

// The address of `symbol` in module `name` (e.g. "fluoro_dicom"), loading it at the first call.
// Throws std::runtime_error naming the module, the places searched and the loader's reason: an
// installation fault, not the input's.
void* plugin_symbol(const std::string& name, const char* symbol);

}  // namespace fluoro

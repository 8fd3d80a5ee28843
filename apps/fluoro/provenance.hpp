#pragma once
// The "provenance" object of every result file (docs/cli.md, "Provenance"): which program and
// version wrote it, with which arguments and effective settings, on how many threads, from which
// exact input files (their SHA-256 digests).
#include <nlohmann/json.hpp>
#include <string>

namespace fluoro::cli {

// `command`: the subcommand ("register", "dewarp fit"); `settings`: the command's effective
// settings, defaults included; `inputs`: the result's "inputs" object or array as the command
// writes it: every object in it with a "path" is digested (so the two can never disagree).
nlohmann::json provenance(const std::string& command, const nlohmann::json& settings, const nlohmann::json& inputs);

// SHA-256 of a regular file's bytes; of a directory (a DICOM series), the SHA-256 of the lines
// "<sha256 of the file>  <name>\n" of its regular files (not hidden ones), sorted by name byte by
// byte, which `LC_ALL=C sha256sum * | sha256sum` in the directory reproduces. Null otherwise.
nlohmann::json input_sha256(const std::string& path);

}  // namespace fluoro::cli

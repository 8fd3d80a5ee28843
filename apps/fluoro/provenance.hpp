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

// SHA-256 of a regular file's bytes, or of a directory's listing (a DICOM series; engine/sha256.hpp).
// Null for anything else.
nlohmann::json input_sha256(const std::string& path);

}  // namespace fluoro::cli

#pragma once
// The prepared-CT file (`fluoro prepare --out CT.fluoroprep`, layout in docs/cli.md, "Prepared
// CT files"): a PreparedCt saved in the backend's own resident form, with what it was made from
// (the CT's and mask's SHA-256, the preparation settings, the program and format versions) and a
// CRC-32 over everything, so that a registration never runs on a field of another CT, other
// settings or damaged bytes.
#include <memory>
#include <nlohmann/json.hpp>
#include <string>

#include "engine/backend.hpp"
#include "pipelines/registration/prepared_ct.hpp"

namespace fluoro {

// Bumped whenever the layout or what preparation computes changes (a file of another format
// version is refused: its fields could differ from what this program would compute).
// 2: the cpu backend's bricks are 2 voxels a side in volumes of 2.5 mm voxels or coarser.
// 3: the non-bone attenuation (PreparedCt::non_bone_mu) after the bone's.
inline constexpr uint32_t kPreparedCtFormatVersion = 3;

// What a prepared file was made from, and what a registration that loads it must match.
struct PreparedCtSource {
  std::string ct_path, ct_sha256;      // the CT file (or DICOM directory) and its digest
  std::string mask_path, mask_sha256;  // empty without a mask
  nlohmann::json settings;             // preparation_settings()
};

// Writes atomically (a temporary beside `path`, renamed when complete). Throws BackendUnavailable
// when the backend cannot save its volumes, InputError naming `path` when it cannot be written.
void write_prepared_ct(const std::string& path, Backend& backend, const PreparedCt& ct, const PreparedCtSource& source);

// Reads and checks a prepared file before anything in it is used: its magic, format version,
// size and checksum, then that it was made by this program's version, from `expected`'s CT (and
// mask) with `expected`'s settings, for this backend. Throws InputError naming `path` and what
// differs (the CLI's exit 2). With `digest`, the file's SHA-256 is computed from the same bytes
// on the side (a result's provenance records it; engine/sha256.hpp's sha256_of_input then gives
// it back without reading the file again).
std::shared_ptr<const PreparedCt> read_prepared_ct(const std::string& path, Backend& backend,
                                                   const PreparedCtSource& expected, bool digest = false);

}  // namespace fluoro

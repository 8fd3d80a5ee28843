#pragma once
// NRRD (.nrrd, .nhdr) headers checked before ITK reads them. A fuzzed 1 KB file named .nrrd
// without the NRRD magic went on to ITK's other format probes, which spent 25 s and 1.8 GB on it
// (fuzz_volume_nrrd's "sizes_beyond_file"); and a detached header (.nhdr) could promise gigabytes
// of voxels from a small data file, which only the read itself noticed.
#include <string>

namespace fluoro {

// Throws InputError naming the path unless the file starts with a NRRD magic line ("NRRD0001" to
// "NRRD0005") and a header whose type (a scalar type), dimension (1 to 16), sizes (positive),
// encoding (one ITK reads: raw, text, hex or gzip), byte skip and line skip are sane, and whose
// data (the bytes after the header's blank line, or the "data file" it names) can hold the voxels
// it describes: the exact byte count for raw data, two characters a byte for hex, a character a
// value for text, and 1/1032 of the bytes (deflate's largest ratio) for gzip. Data spread over
// several files ("LIST" or a "pattern min max step" list) is left to ITK to size.
void check_nrrd_header(const std::string& path);

}  // namespace fluoro

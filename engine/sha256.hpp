#pragma once
// SHA-256 (FIPS 180-4), for the digests of a result file's inputs (docs/cli.md, "Provenance").
// The project links no crypto library (Debian's allowed list has none it needs otherwise), and a
// digest is all it needs: about a hundred lines, checked against NIST's test vectors.
#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

#include <sys/stat.h>

namespace fluoro {

// Incremental: update() any number of times with pieces of the message, then hex() once.
class Sha256 {
 public:
  Sha256();
  void update(const void* data, size_t bytes);
  void update(std::string_view s) { update(s.data(), s.size()); }
  // The digest as 64 lower-case hex digits. Ends the computation (the object is spent).
  std::string hex();

 private:
  void block(const uint8_t* p);
  std::array<uint32_t, 8> h_;
  std::array<uint8_t, 64> buffer_{};
  size_t buffered_ = 0;
  uint64_t length_ = 0;  // message length in bytes so far
};

std::string sha256_hex(std::string_view data);

// The digest of a file's bytes, read in 1 MiB pieces (a CT of 1 GB never sits in memory). Throws
// InputError naming the path when it cannot be read.
std::string sha256_file(const std::string& path);

// The digest of a directory's files (a DICOM series): the SHA-256 of the lines
// "<sha256 of the file>  <name>\n" of its regular, non-hidden files sorted by name byte by byte,
// which `cd DIR && LC_ALL=C sha256sum * | sha256sum` reproduces. Subdirectories are not entered.
std::string sha256_directory(const std::string& dir);

// The digest of an input as result files record it: sha256_file of a regular file,
// sha256_directory of a directory. Remembered per path and the file's identity (device, inode,
// size, modification and status-change times), so that a command that checks a digest (a
// prepared file's CT) and then records it reads the file once. Throws InputError naming the path
// when it is neither.
std::string sha256_of_input(const std::string& path);

// Leaves with sha256_of_input the digest of a regular file that a caller computed from the bytes
// it read itself (a mapped prepared file), `st` being fstat of the descriptor it read them from:
// the digest is given back only while the path still names that same, unchanged file.
void remember_sha256_of_input(const std::string& path, const struct stat& st, const std::string& digest);

}  // namespace fluoro

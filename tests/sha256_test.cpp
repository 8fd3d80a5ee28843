// engine/sha256: NIST's FIPS 180-4 example vectors (csrc.nist.gov, "SHA256.pdf" and
// "SHA2_Additional.pdf"), the same digest whatever pieces the message comes in, and files read in
// pieces. About 10 ms.
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>


#include <filesystem>
#include <fstream>
#include <string>

#include "engine/error.hpp"
#include "engine/sha256.hpp"

namespace fluoro {
namespace {

TEST(Sha256, NistVectors) {
  EXPECT_EQ(sha256_hex("abc"), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
  EXPECT_EQ(sha256_hex(""), "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
  // 448 bits: the padding's length no longer fits the block, a second block is needed.
  EXPECT_EQ(sha256_hex("abcdbcdecdefdefgefghfghighijhijkijkljklmklmnlmnomnopnopq"),
            "248d6a61d20638b8e5c026930c3e6039a33ce45964ff2167f6ecedd419db06c1");
  EXPECT_EQ(sha256_hex("abcdefghbcdefghicdefghijdefghijkefghijklfghijklmghijklmnhijklmnoijklmnopjklmnopqklmnopqrlmnopqrs"
                       "mnopqrstnopqrstu"),
            "cf5b16a778af8380036ce59e7b0492370b249b11e8f07a51afac45037afee9d1");
  EXPECT_EQ(sha256_hex(std::string(1000000, 'a')), "cdc76e5c9914fb9281a1c7e284d73e67f1809a48a497200e046d39ccc7112cd0");
  // Lengths either side of the padding boundary (55 and 56 bytes of 0x00, NIST's additional vectors).
  EXPECT_EQ(sha256_hex(std::string(55, '\0')), "02779466cdec163811d078815c633f21901413081449002f24aa3e80f0b88ef7");
  EXPECT_EQ(sha256_hex(std::string(56, '\0')), "d4817aa5497628e7c77e6b606107042bbba3130888c5f47a375e6179be789fbb");
}

TEST(Sha256, PiecesGiveTheSameDigest) {
  std::string message;
  for (int i = 0; i < 1000; ++i) message += char(i * 7 + 3);
  const std::string whole = sha256_hex(message);
  for (size_t piece : {1u, 3u, 63u, 64u, 65u, 200u}) {
    Sha256 s;
    for (size_t at = 0; at < message.size(); at += piece) s.update(std::string_view(message).substr(at, piece));
    EXPECT_EQ(s.hex(), whole) << piece;
  }
}

TEST(Sha256, FilesAreReadInPieces) {
  const auto path = std::filesystem::temp_directory_path() / ("fluoro_sha256_" + std::to_string(::getpid()) + ".bin");
  std::string content((size_t(1) << 20) + 7, '\0');  // one byte past the reader's 1 MiB piece
  for (size_t i = 0; i < content.size(); ++i) content[i] = char(i * 31 % 251);
  std::ofstream(path, std::ios::binary) << content;
  EXPECT_EQ(sha256_file(path.string()), sha256_hex(content));
  std::filesystem::remove(path);
  EXPECT_THROW(sha256_file(path.string()), InputError);
}

// A digest left by a reader of the file's bytes is given back for that file only while it is the
// same file, unchanged: not after it is rewritten in place, even with its time put back, nor after
// another file of the same size and time takes its name.
TEST(Sha256, ARememberedDigestHoldsOnlyForTheSameUnchangedFile) {
  namespace fs = std::filesystem;
  const auto path = fs::temp_directory_path() / ("fluoro_sha256_known_" + std::to_string(::getpid()) + ".bin");
  const auto other = fs::path(path.string() + ".new");
  std::ofstream(path, std::ios::binary) << "first";
  struct stat st {};
  ASSERT_EQ(::stat(path.c_str(), &st), 0);
  const std::string remembered(64, 'f');  // no file's digest: shows where the answer came from
  remember_sha256_of_input(path.string(), st, remembered);
  EXPECT_EQ(sha256_of_input(path.string()), remembered);

  // Rewritten in place with its modification time put back (as `cp -p` or `touch -r` do): the
  // same inode, size and time; only the status-change time tells.
  const auto time = fs::last_write_time(path);
  std::ofstream(path, std::ios::binary) << "other";
  fs::last_write_time(path, time);
  EXPECT_EQ(sha256_of_input(path.string()), sha256_hex("other"));

  ASSERT_EQ(::stat(path.c_str(), &st), 0);
  remember_sha256_of_input(path.string(), st, remembered);
  std::ofstream(other, std::ios::binary) << "third";  // renamed over it: same size and time, another inode
  fs::last_write_time(other, fs::last_write_time(path));
  fs::rename(other, path);
  EXPECT_EQ(sha256_of_input(path.string()), sha256_hex("third"));
  fs::remove(path);
}

// A DICOM series: the digest of the sha256sum-style listing of its files, as
// `cd DIR && LC_ALL=C sha256sum * | sha256sum` printed for this directory (hidden files and
// subdirectories left out; "C.txt" before "a.txt": bytes, not the locale's order).
TEST(Sha256, DirectoriesAreTheirSortedListing) {
  const auto dir = std::filesystem::temp_directory_path() / ("fluoro_sha256_dir_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir / "sub");
  std::ofstream(dir / "b.txt") << "abc";
  std::ofstream(dir / "a.txt");
  std::ofstream(dir / "C.txt") << "A";
  std::ofstream(dir / ".hidden") << "x";
  std::ofstream(dir / "sub" / "ignored.txt") << "y";
  EXPECT_EQ(sha256_directory(dir.string()), "2e58686e9e6c5f63c383f03a88fe41e394519c292b1a09dc2656419fea234a66");
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace fluoro

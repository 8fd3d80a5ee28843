#include "engine/sha256.hpp"

#include <sys/stat.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <map>
#include <memory>
#include <mutex>
#include <tuple>
#include <vector>

#include "engine/error.hpp"

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#include <cpuid.h>
#include <immintrin.h>
#define FLUORO_SHA256_X86 1
#endif

namespace fluoro {
namespace {

// FIPS 180-4 section 4.2.2: the first 32 bits of the fractional parts of the cube roots of the
// first 64 primes.
constexpr uint32_t kK[64] = {
    0x428a2f98, 0x71374491, 0xb5c0fbcf, 0xe9b5dba5, 0x3956c25b, 0x59f111f1, 0x923f82a4, 0xab1c5ed5,
    0xd807aa98, 0x12835b01, 0x243185be, 0x550c7dc3, 0x72be5d74, 0x80deb1fe, 0x9bdc06a7, 0xc19bf174,
    0xe49b69c1, 0xefbe4786, 0x0fc19dc6, 0x240ca1cc, 0x2de92c6f, 0x4a7484aa, 0x5cb0a9dc, 0x76f988da,
    0x983e5152, 0xa831c66d, 0xb00327c8, 0xbf597fc7, 0xc6e00bf3, 0xd5a79147, 0x06ca6351, 0x14292967,
    0x27b70a85, 0x2e1b2138, 0x4d2c6dfc, 0x53380d13, 0x650a7354, 0x766a0abb, 0x81c2c92e, 0x92722c85,
    0xa2bfe8a1, 0xa81a664b, 0xc24b8b70, 0xc76c51a3, 0xd192e819, 0xd6990624, 0xf40e3585, 0x106aa070,
    0x19a4c116, 0x1e376c08, 0x2748774c, 0x34b0bcb5, 0x391c0cb3, 0x4ed8aa4a, 0x5b9cca4f, 0x682e6ff3,
    0x748f82ee, 0x78a5636f, 0x84c87814, 0x8cc70208, 0x90befffa, 0xa4506ceb, 0xbef9a3f7, 0xc67178f2};

constexpr uint32_t rotr(uint32_t x, int n) { return (x >> n) | (x << (32 - n)); }

#ifdef FLUORO_SHA256_X86
// The same compression with the x86 SHA extensions (Intel's SHA-NI, on AMD since Zen and on
// Intel since Ice Lake / Goldmont): about 5x the portable code, which matters for prepared CT files
// of hundreds of MB whose digest every result records. The state lives as ABEF / CDGH halves,
// the layout sha256rnds2 works on; four message words and four rounds per step.
__attribute__((target("sha,sse4.1"))) void blocks_sha_ni(uint32_t h[8], const uint8_t* p, size_t n) {
  const __m128i byteswap = _mm_set_epi64x(0x0c0d0e0f08090a0bLL, 0x0405060700010203LL);
  __m128i tmp = _mm_shuffle_epi32(_mm_loadu_si128(reinterpret_cast<const __m128i*>(h)), 0xB1);  // CDAB
  __m128i state1 = _mm_shuffle_epi32(_mm_loadu_si128(reinterpret_cast<const __m128i*>(h + 4)), 0x1B);  // EFGH
  __m128i state0 = _mm_alignr_epi8(tmp, state1, 8);     // ABEF
  state1 = _mm_blend_epi16(state1, tmp, 0xF0);          // CDGH
  for (; n > 0; --n, p += 64) {
    const __m128i abef = state0, cdgh = state1;
    __m128i w[4];
    for (int i = 0; i < 16; ++i) {
      __m128i& wi = w[i & 3];
      if (i < 4) {
        wi = _mm_shuffle_epi8(_mm_loadu_si128(reinterpret_cast<const __m128i*>(p + 16 * i)), byteswap);
      } else {
        // W[t] = s1(W[t-2]) + W[t-7] + s0(W[t-15]) + W[t-16], four at a time.
        const __m128i w4 = w[i & 3], w3 = w[(i + 1) & 3], w2 = w[(i + 2) & 3], w1 = w[(i + 3) & 3];
        wi = _mm_sha256msg2_epu32(_mm_add_epi32(_mm_sha256msg1_epu32(w4, w3), _mm_alignr_epi8(w1, w2, 4)), w1);
      }
      __m128i msg = _mm_add_epi32(wi, _mm_loadu_si128(reinterpret_cast<const __m128i*>(kK + 4 * i)));
      state1 = _mm_sha256rnds2_epu32(state1, state0, msg);
      msg = _mm_shuffle_epi32(msg, 0x0E);
      state0 = _mm_sha256rnds2_epu32(state0, state1, msg);
    }
    state0 = _mm_add_epi32(state0, abef);
    state1 = _mm_add_epi32(state1, cdgh);
  }
  tmp = _mm_shuffle_epi32(state0, 0x1B);        // FEBA
  state1 = _mm_shuffle_epi32(state1, 0xB1);     // DCHG
  state0 = _mm_blend_epi16(tmp, state1, 0xF0);  // DCBA
  state1 = _mm_alignr_epi8(state1, tmp, 8);     // HGFE
  _mm_storeu_si128(reinterpret_cast<__m128i*>(h), state0);
  _mm_storeu_si128(reinterpret_cast<__m128i*>(h + 4), state1);
}

// CPUID itself (leaf 1: SSE4.1 in ECX bit 19; leaf 7: SHA in EBX bit 29): clang 14's
// __builtin_cpu_supports knows no "sha" and stops the build (the sanitizer pass is a clang build).
bool has_sha_ni() {
  static const bool yes = [] {
    unsigned a = 0, b = 0, c = 0, d = 0;
    if (!__get_cpuid(1, &a, &b, &c, &d) || !(c & (1u << 19))) return false;
    return __get_cpuid_count(7, 0, &a, &b, &c, &d) && (b & (1u << 29)) != 0;
  }();
  return yes;
}
#endif

}  // namespace

// Section 5.3.3: the initial hash value (square roots of the first 8 primes).
Sha256::Sha256()
    : h_{0x6a09e667, 0xbb67ae85, 0x3c6ef372, 0xa54ff53a, 0x510e527f, 0x9b05688c, 0x1f83d9ab, 0x5be0cd19} {}

// Section 6.2.2: one 512-bit block.
void Sha256::block(const uint8_t* p) {
  uint32_t w[64];
  for (int t = 0; t < 16; ++t)
    w[t] = uint32_t(p[4 * t]) << 24 | uint32_t(p[4 * t + 1]) << 16 | uint32_t(p[4 * t + 2]) << 8 | uint32_t(p[4 * t + 3]);
  for (int t = 16; t < 64; ++t) {
    const uint32_t s0 = rotr(w[t - 15], 7) ^ rotr(w[t - 15], 18) ^ (w[t - 15] >> 3);
    const uint32_t s1 = rotr(w[t - 2], 17) ^ rotr(w[t - 2], 19) ^ (w[t - 2] >> 10);
    w[t] = w[t - 16] + s0 + w[t - 7] + s1;
  }
  uint32_t a = h_[0], b = h_[1], c = h_[2], d = h_[3], e = h_[4], f = h_[5], g = h_[6], h = h_[7];
  for (int t = 0; t < 64; ++t) {
    const uint32_t t1 = h + (rotr(e, 6) ^ rotr(e, 11) ^ rotr(e, 25)) + ((e & f) ^ (~e & g)) + kK[t] + w[t];
    const uint32_t t2 = (rotr(a, 2) ^ rotr(a, 13) ^ rotr(a, 22)) + ((a & b) ^ (a & c) ^ (b & c));
    h = g;
    g = f;
    f = e;
    e = d + t1;
    d = c;
    c = b;
    b = a;
    a = t1 + t2;
  }
  h_[0] += a, h_[1] += b, h_[2] += c, h_[3] += d, h_[4] += e, h_[5] += f, h_[6] += g, h_[7] += h;
}

void Sha256::update(const void* data, size_t bytes) {
  const auto* p = static_cast<const uint8_t*>(data);
  length_ += bytes;
  if (buffered_) {  // complete the partial block first
    const size_t take = std::min(bytes, 64 - buffered_);
    std::copy(p, p + take, buffer_.begin() + long(buffered_));
    buffered_ += take, p += take, bytes -= take;
    if (buffered_ < 64) return;
#ifdef FLUORO_SHA256_X86
    if (has_sha_ni()) blocks_sha_ni(h_.data(), buffer_.data(), 1);
    else
#endif
      block(buffer_.data());
    buffered_ = 0;
  }
#ifdef FLUORO_SHA256_X86
  if (has_sha_ni() && bytes >= 64) {
    const size_t n = bytes / 64;
    blocks_sha_ni(h_.data(), p, n);
    p += 64 * n, bytes -= 64 * n;
  }
#endif
  for (; bytes >= 64; p += 64, bytes -= 64) block(p);
  std::copy(p, p + bytes, buffer_.begin());
  buffered_ = bytes;
}

// Section 5.1.1: a 1 bit, zeros to 448 mod 512 bits, then the length in bits, big-endian.
std::string Sha256::hex() {
  const uint64_t bits = length_ * 8;
  const uint8_t one = 0x80, zero = 0;
  update(&one, 1);
  while (buffered_ != 56) update(&zero, 1);
  uint8_t len[8];
  for (int i = 0; i < 8; ++i) len[i] = uint8_t(bits >> (56 - 8 * i));
  update(len, 8);
  static const char digits[] = "0123456789abcdef";
  std::string out;
  for (uint32_t word : h_)
    for (int shift = 28; shift >= 0; shift -= 4) out += digits[(word >> shift) & 0xf];
  return out;
}

std::string sha256_hex(std::string_view data) {
  Sha256 s;
  s.update(data);
  return s.hex();
}

namespace {

// The digest of an open file's bytes, read in 1 MiB pieces.
std::string sha256_of_stream(FILE* f, const std::string& path) {
  std::vector<uint8_t> piece(size_t(1) << 20);
  Sha256 s;
  for (;;) {
    const size_t n = std::fread(piece.data(), 1, piece.size(), f);
    s.update(piece.data(), n);
    if (n < piece.size()) break;
  }
  if (std::ferror(f)) throw_input_error(path, "read error while computing its digest");
  return s.hex();
}

}  // namespace

std::string sha256_file(const std::string& path) {
  std::unique_ptr<FILE, int (*)(FILE*)> f(std::fopen(path.c_str(), "rb"), &std::fclose);
  if (!f) throw_input_error(path, "cannot open to compute its digest");
  return sha256_of_stream(f.get(), path);
}

std::string sha256_directory(const std::string& dir) {
  namespace fs = std::filesystem;
  std::vector<std::string> names;
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator(dir, ec)) {
    const std::string name = entry.path().filename().string();
    if (name[0] != '.' && entry.is_regular_file(ec)) names.push_back(name);
  }
  if (ec) throw_input_error(dir, "cannot list the directory to compute its digest");
  std::sort(names.begin(), names.end());  // std::string's order is byte order, as LC_ALL=C's
  Sha256 listing;
  for (const auto& name : names) listing.update(sha256_file((fs::path(dir) / name).string()) + "  " + name + "\n");
  return listing.hex();
}

namespace {

// A file as sha256_of_input remembers it: its absolute path and what stat says of its contents'
// identity: device, inode, size, and the modification and status-change times to the
// nanosecond. A file replaced by a rename has another inode; one rewritten in place another
// status-change time, even when its modification time is put back (`cp -p`, `touch -r`), which
// no program can set.
using InputKey = std::tuple<std::string, dev_t, ino_t, off_t, long long, long long, long long, long long>;

InputKey input_key(const std::string& path, const struct stat& st) {
  std::error_code ec;
  return {std::filesystem::absolute(path, ec).string(),
          st.st_dev,
          st.st_ino,
          st.st_size,
          (long long)st.st_mtim.tv_sec,
          (long long)st.st_mtim.tv_nsec,
          (long long)st.st_ctim.tv_sec,
          (long long)st.st_ctim.tv_nsec};
}

std::mutex known_mutex;
std::map<InputKey, std::string>& known_digests() {
  static std::map<InputKey, std::string> known;
  return known;
}

}  // namespace

std::string sha256_of_input(const std::string& path) {
  namespace fs = std::filesystem;
  std::error_code ec;
  const auto status = fs::status(path, ec);
  if (!fs::is_regular_file(status) && !fs::is_directory(status)) throw_input_error(path, "no such file or directory");
  // A directory's own time changes when files come or go; editing a file in place changes only
  // the file's, so directories are never remembered.
  if (fs::is_directory(status)) return sha256_directory(path);
  // The key from the descriptor that is read, so that the digest is the bytes of the file the
  // key names.
  std::unique_ptr<FILE, int (*)(FILE*)> f(std::fopen(path.c_str(), "rb"), &std::fclose);
  if (!f) throw_input_error(path, "cannot open to compute its digest");
  struct stat st {};
  if (::fstat(::fileno(f.get()), &st) != 0) throw_input_error(path, "cannot open to compute its digest");
  const InputKey key = input_key(path, st);
  {
    std::lock_guard lock(known_mutex);
    if (auto it = known_digests().find(key); it != known_digests().end()) return it->second;
  }
  std::string digest = sha256_of_stream(f.get(), path);
  std::lock_guard lock(known_mutex);
  known_digests().emplace(key, digest);
  return digest;
}

void remember_sha256_of_input(const std::string& path, const struct stat& st, const std::string& digest) {
  std::lock_guard lock(known_mutex);
  known_digests().insert_or_assign(input_key(path, st), digest);
}

}  // namespace fluoro

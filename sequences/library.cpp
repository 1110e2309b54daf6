#include "sequences/library.hpp"

#include <algorithm>
#include <array>
#include <cerrno>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <sstream>

#include "sequences/parser.hpp"
#include "sequences/profile_generator.hpp"
#include "sequences/sequence_error.hpp"

namespace imucal::sequences {
namespace fs = std::filesystem;

namespace {

// ---- SHA-256, FIPS 180-4 §6.2 -------------------------------------------------------------
constexpr std::array<uint32_t, 64> kK = {
    0x428a2f98, 0x71374491, 0xb5c0fbcf, 0xe9b5dba5, 0x3956c25b, 0x59f111f1, 0x923f82a4, 0xab1c5ed5,
    0xd807aa98, 0x12835b01, 0x243185be, 0x550c7dc3, 0x72be5d74, 0x80deb1fe, 0x9bdc06a7, 0xc19bf174,
    0xe49b69c1, 0xefbe4786, 0x0fc19dc6, 0x240ca1cc, 0x2de92c6f, 0x4a7484aa, 0x5cb0a9dc, 0x76f988da,
    0x983e5152, 0xa831c66d, 0xb00327c8, 0xbf597fc7, 0xc6e00bf3, 0xd5a79147, 0x06ca6351, 0x14292967,
    0x27b70a85, 0x2e1b2138, 0x4d2c6dfc, 0x53380d13, 0x650a7354, 0x766a0abb, 0x81c2c92e, 0x92722c85,
    0xa2bfe8a1, 0xa81a664b, 0xc24b8b70, 0xc76c51a3, 0xd192e819, 0xd6990624, 0xf40e3585, 0x106aa070,
    0x19a4c116, 0x1e376c08, 0x2748774c, 0x34b0bcb5, 0x391c0cb3, 0x4ed8aa4a, 0x5b9cca4f, 0x682e6ff3,
    0x748f82ee, 0x78a5636f, 0x84c87814, 0x8cc70208, 0x90befffa, 0xa4506ceb, 0xbef9a3f7, 0xc67178f2};

inline uint32_t rotr(uint32_t x, int n) { return (x >> n) | (x << (32 - n)); }

void compress(std::array<uint32_t, 8>& h, const unsigned char* block) {
  uint32_t w[64];
  for (int t = 0; t < 16; ++t)
    w[t] = (uint32_t(block[4 * t]) << 24) | (uint32_t(block[4 * t + 1]) << 16) |
           (uint32_t(block[4 * t + 2]) << 8) | uint32_t(block[4 * t + 3]);
  for (int t = 16; t < 64; ++t) {
    const uint32_t s0 = rotr(w[t - 15], 7) ^ rotr(w[t - 15], 18) ^ (w[t - 15] >> 3);
    const uint32_t s1 = rotr(w[t - 2], 17) ^ rotr(w[t - 2], 19) ^ (w[t - 2] >> 10);
    w[t] = w[t - 16] + s0 + w[t - 7] + s1;
  }
  uint32_t a = h[0], b = h[1], c = h[2], d = h[3], e = h[4], f = h[5], g = h[6], hh = h[7];
  for (int t = 0; t < 64; ++t) {
    const uint32_t S1 = rotr(e, 6) ^ rotr(e, 11) ^ rotr(e, 25);
    const uint32_t ch = (e & f) ^ (~e & g);
    const uint32_t t1 = hh + S1 + ch + kK[t] + w[t];
    const uint32_t S0 = rotr(a, 2) ^ rotr(a, 13) ^ rotr(a, 22);
    const uint32_t maj = (a & b) ^ (a & c) ^ (b & c);
    const uint32_t t2 = S0 + maj;
    hh = g;
    g = f;
    f = e;
    e = d + t1;
    d = c;
    c = b;
    b = a;
    a = t1 + t2;
  }
  h[0] += a;
  h[1] += b;
  h[2] += c;
  h[3] += d;
  h[4] += e;
  h[5] += f;
  h[6] += g;
  h[7] += hh;
}

std::string read_file_bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw SequenceError(path, 0, std::string("cannot open file: ") + std::strerror(errno));
  std::ostringstream buf;
  buf << in.rdbuf();
  if (in.bad()) throw SequenceError(path, 0, "error while reading file");
  return buf.str();
}

bool is_regular_file(const std::string& p) {
  std::error_code ec;
  return fs::is_regular_file(p, ec);
}

}  // namespace

std::string sha256_hex(std::string_view bytes) {
  std::array<uint32_t, 8> h = {0x6a09e667, 0xbb67ae85, 0x3c6ef372, 0xa54ff53a,
                               0x510e527f, 0x9b05688c, 0x1f83d9ab, 0x5be0cd19};
  const auto* p = reinterpret_cast<const unsigned char*>(bytes.data());
  const size_t n = bytes.size();
  size_t off = 0;
  for (; off + 64 <= n; off += 64) compress(h, p + off);
  // Padding: 0x80, zeros, then the message length in bits as a 64-bit big-endian integer.
  unsigned char tail[128] = {};
  const size_t rem = n - off;
  std::memcpy(tail, p + off, rem);
  tail[rem] = 0x80;
  const size_t tail_len = rem + 1 + 8 <= 64 ? 64 : 128;
  const uint64_t bits = static_cast<uint64_t>(n) * 8u;
  for (int i = 0; i < 8; ++i) tail[tail_len - 1 - i] = static_cast<unsigned char>(bits >> (8 * i));
  compress(h, tail);
  if (tail_len == 128) compress(h, tail + 64);

  static const char* kHex = "0123456789abcdef";
  std::string out;
  out.reserve(64);
  for (uint32_t word : h)
    for (int shift = 28; shift >= 0; shift -= 4) out.push_back(kHex[(word >> shift) & 0xf]);
  return out;
}

namespace {

std::mutex g_dir_mutex;
std::string g_configured_dir;  ///< set_sequence_dir(); "" = none

bool is_dir(const fs::path& p) {
  std::error_code ec;
  return fs::is_directory(p, ec);
}

/// <prefix>/share/imucal/sequences of an installed program (<prefix>/bin/<tool>), found from the
/// running executable so that a relocated install (a package unpacked elsewhere) finds its own.
std::string installed_dir_next_to_executable() {
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  if (ec) return "";
  const fs::path dir = exe.parent_path().parent_path() / "share" / "imucal" / "sequences";
  return is_dir(dir) ? dir.string() : "";
}

}  // namespace

void set_sequence_dir(const std::string& dir) {
  std::lock_guard<std::mutex> lock(g_dir_mutex);
  g_configured_dir = dir;
}

std::string sequence_dir() {
  {
    std::lock_guard<std::mutex> lock(g_dir_mutex);
    if (!g_configured_dir.empty()) return g_configured_dir;
  }
  const char* env = std::getenv("IMUCAL_SEQUENCE_DIR");
  if (env && *env) return env;
  if (std::string installed = installed_dir_next_to_executable(); !installed.empty())
    return installed;
  // A build tree uses its own sources; a program installed from it, where the sources are not
  // there (another machine, or a service with ProtectHome), the install prefix's data.
  if (is_dir(IMUCAL_SEQUENCE_DIR) || !is_dir(IMUCAL_INSTALLED_SEQUENCE_DIR))
    return IMUCAL_SEQUENCE_DIR;
  return IMUCAL_INSTALLED_SEQUENCE_DIR;
}

std::vector<std::string> available_sequences() {
  std::vector<std::string> names;
  std::error_code ec;
  for (fs::directory_iterator it(sequence_dir(), ec), end; !ec && it != end; it.increment(ec)) {
    const fs::path& p = it->path();
    if (p.extension() == ".toml" && is_regular_file(p.string())) names.push_back(p.stem().string());
  }
  std::sort(names.begin(), names.end());
  return names;
}

std::string resolve_sequence(const std::string& name_or_path) {
  if (!name_or_path.empty() && is_regular_file(name_or_path)) return name_or_path;
  // A bare name (no directory part) is looked up in the library.
  if (!name_or_path.empty() && name_or_path.find('/') == std::string::npos) {
    std::string file = name_or_path;
    if (fs::path(file).extension() != ".toml") file += ".toml";
    const std::string candidate = (fs::path(sequence_dir()) / file).string();
    if (is_regular_file(candidate)) return candidate;
  }
  std::string names;
  for (const std::string& n : available_sequences()) names += (names.empty() ? "" : ", ") + n;
  // A bare name is a library name to the user; a path is a file.
  if (name_or_path.find('/') == std::string::npos)
    throw SequenceError::unknown_name(name_or_path, sequence_dir(), names);
  throw SequenceError(name_or_path, 0,
                      "no such sequence file (library " + sequence_dir() + ": " +
                          (names.empty() ? "(none)" : names) + ")");
}

MotionProfile load_profile(const std::string& name_or_path, const TableLimits& station) {
  const Sequence seq = parse_sequence_file(resolve_sequence(name_or_path));
  validate_or_throw(seq, effective_limits(station, seq.limits));
  return generate_profile(seq);
}

std::string sequence_hash(const std::string& path) { return sha256_hex(read_file_bytes(path)); }

}  // namespace imucal::sequences

#include "digest.hpp"

#include <cstdio>
#include <fstream>

namespace bimanual_skills::io {

void Digest::add(const void* bytes, std::size_t size) noexcept {
  const auto* byte = static_cast<const unsigned char*>(bytes);
  for (std::size_t i = 0; i < size; ++i) {
    hash_ ^= byte[i];
    hash_ *= 1099511628211ull;
  }
}

std::string Digest::hex() const {
  char text[17];
  std::snprintf(text, sizeof text, "%016llx", static_cast<unsigned long long>(hash_));
  return text;
}

std::string fileDigest(const std::vector<std::string>& paths) {
  if (paths.empty()) return {};
  Digest digest;
  for (const std::string& path : paths) {
    if (path.empty()) return {};
    std::ifstream in(path, std::ios::binary);
    if (!in) return {};
    std::uint64_t length = 0;
    char buffer[4096];
    while (in.read(buffer, sizeof buffer) || in.gcount() > 0) {
      digest.add(buffer, static_cast<std::size_t>(in.gcount()));
      length += static_cast<std::uint64_t>(in.gcount());
    }
    if (in.bad()) return {};
    if (paths.size() > 1) {
      unsigned char bytes[8];
      for (int b = 0; b < 8; ++b) bytes[b] = static_cast<unsigned char>(length >> (8 * b));
      digest.add(bytes, sizeof bytes);
    }
  }
  return digest.hex();
}

}  // namespace bimanual_skills::io

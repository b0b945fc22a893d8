#include "digest.hpp"

#include <cstdint>
#include <cstdio>
#include <fstream>
#include <iterator>

namespace bimanual_skills::io {

std::string fileDigest(const std::vector<std::string>& paths) {
  if (paths.empty()) return {};
  std::uint64_t hash = 14695981039346656037ull;  // FNV-1a, 64 bits
  const auto mix = [&hash](unsigned char byte) {
    hash ^= byte;
    hash *= 1099511628211ull;
  };
  for (const std::string& path : paths) {
    if (path.empty()) return {};
    std::ifstream in(path, std::ios::binary);
    if (!in) return {};
    std::uint64_t length = 0;
    for (std::istreambuf_iterator<char> c(in), end; c != end; ++c, ++length) mix(static_cast<unsigned char>(*c));
    if (in.bad()) return {};
    if (paths.size() > 1) {
      for (int b = 0; b < 8; ++b) mix(static_cast<unsigned char>(length >> (8 * b)));
    }
  }
  char text[17];
  std::snprintf(text, sizeof text, "%016llx", static_cast<unsigned long long>(hash));
  return text;
}

}  // namespace bimanual_skills::io

/// \file
/// Digests of bytes (64-bit FNV-1a as 16 hex digits): whether two hosts, or a run and its resume, read the same
/// configuration, and whether two machines computed the same bits. Not cryptographic: it tells an edited or different
/// file, or a result that differs in one bit, from the same one.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace bimanual_skills::io {

/// A digest fed piece by piece.
class Digest {
 public:
  void add(const void* bytes, std::size_t size) noexcept;
  void add(const std::string& text) noexcept { add(text.data(), text.size()); }
  /// The digest of everything added so far, 16 hex digits.
  std::string hex() const;

 private:
  std::uint64_t hash_ = 14695981039346656037ull;
};

/// The digest of the bytes of the files `paths`, in order (each file's bytes, then its length when there are
/// several); "" when one cannot be read or the list is empty.
std::string fileDigest(const std::vector<std::string>& paths);

}  // namespace bimanual_skills::io

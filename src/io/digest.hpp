/// \file
/// Digests of files' bytes (64-bit FNV-1a as 16 hex digits): whether two hosts, or a run and its resume, read the
/// same configuration. Not cryptographic: it tells an edited or different file from the same one.
#pragma once

#include <string>
#include <vector>

namespace bimanual_skills::io {

/// The digest of the bytes of the files `paths`, in order (each file's bytes, then its length); "" when one cannot
/// be read or the list is empty.
std::string fileDigest(const std::vector<std::string>& paths);

}  // namespace bimanual_skills::io

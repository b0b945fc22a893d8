/// \file
/// A file written whole or not at all: the content goes to PATH.part, which is then renamed over PATH, so a reader
/// (or a run resumed after SIGKILL) sees the old file or the new one, never half of one.
#pragma once

#include <functional>
#include <ostream>
#include <string>

namespace bimanual_skills::io {

/// Writes what `write` puts on the stream into `path`, whole or not at all. Returns false (and leaves `path` as it
/// was, no PATH.part behind) when the file cannot be written or renamed; an exception from `write` is passed on,
/// likewise.
bool writeWhole(const std::string& path, const std::function<void(std::ostream&)>& write);

}  // namespace bimanual_skills::io

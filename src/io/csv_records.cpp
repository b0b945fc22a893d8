#include "io/csv_records.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <stdexcept>
#include <utility>

namespace bimanual_skills::io {

namespace {

[[noreturn]] void fail(const std::string& what, const std::string& path) {
  throw std::runtime_error(what + " '" + path + "': " + std::strerror(errno));
}

}  // namespace

std::size_t dropPartialRecord(const std::string& path) {
  const int fd = ::open(path.c_str(), O_RDWR);
  if (fd < 0) {
    if (errno == ENOENT) return 0;
    fail("cannot open", path);
  }
  struct stat info {};
  if (::fstat(fd, &info) != 0) {
    ::close(fd);
    fail("cannot read", path);
  }
  // Scan back from the end for the last newline, a block at a time.
  off_t end = info.st_size, keep = 0;
  char block[4096];
  for (off_t at = end; at > 0 && keep == 0;) {
    const off_t from = at > static_cast<off_t>(sizeof block) ? at - static_cast<off_t>(sizeof block) : 0;
    const ssize_t got = ::pread(fd, block, static_cast<std::size_t>(at - from), from);
    if (got != at - from) {
      ::close(fd);
      fail("cannot read", path);
    }
    for (ssize_t i = got - 1; i >= 0; --i) {
      if (block[i] == '\n') {
        keep = from + i + 1;
        break;
      }
    }
    at = from;
  }
  const std::size_t dropped = static_cast<std::size_t>(end - keep);
  if (dropped > 0 && ::ftruncate(fd, keep) != 0) {
    ::close(fd);
    fail("cannot truncate", path);
  }
  ::close(fd);
  return dropped;
}

CsvAppender::CsvAppender(const std::string& path, const std::string& header) : path_(path) {
  dropPartialRecord(path);
  fd_ = ::open(path.c_str(), O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0644);
  if (fd_ < 0) fail("cannot open", path);
  struct stat info {};
  if (::fstat(fd_, &info) != 0) fail("cannot read", path);
  if (info.st_size == 0) append(header);
}

CsvAppender::~CsvAppender() {
  if (fd_ >= 0) ::close(fd_);
}

CsvAppender::CsvAppender(CsvAppender&& other) noexcept
    : path_(std::move(other.path_)), fd_(std::exchange(other.fd_, -1)) {}

CsvAppender& CsvAppender::operator=(CsvAppender&& other) noexcept {
  if (this != &other) {
    if (fd_ >= 0) ::close(fd_);
    path_ = std::move(other.path_);
    fd_ = std::exchange(other.fd_, -1);
  }
  return *this;
}

void CsvAppender::append(const std::string& record) {
  if (fd_ < 0) throw std::runtime_error("CsvAppender: not open");
  const std::string line = record + '\n';
  const ssize_t written = ::write(fd_, line.data(), line.size());
  if (written != static_cast<ssize_t>(line.size())) fail("cannot write", path_);
}

}  // namespace bimanual_skills::io

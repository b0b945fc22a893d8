#include "io/csv_records.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <stdexcept>
#include <utility>

namespace bimanual_skills::io {

namespace {

[[noreturn]] void fail(const std::string& what, const std::string& path) {
  throw std::runtime_error(what + " '" + path + "': " + std::strerror(errno));
}

}  // namespace

std::vector<std::string> splitCsv(const std::string& line) {
  std::vector<std::string> out(1);
  bool quoted = false;
  for (std::size_t i = 0; i < line.size(); ++i) {
    const char c = line[i];
    if (quoted) {
      if (c == '"' && i + 1 < line.size() && line[i + 1] == '"') {
        out.back() += '"';
        ++i;
      } else if (c == '"') {
        quoted = false;
      } else {
        out.back() += c;
      }
    } else if (c == '"') {
      quoted = true;
    } else if (c == ',') {
      out.emplace_back();
    } else {
      out.back() += c;
    }
  }
  return out;
}

std::string quotedField(const std::string& text) {
  std::string out = "\"";
  for (const char c : text) {
    if (c == '\n') {
      out += ' ';
    } else {
      if (c == '"') out += '"';
      out += c;
    }
  }
  return out + '"';
}

std::string exactNumber(double value) {
  char buffer[32];
  std::snprintf(buffer, sizeof buffer, "%.17g", value);
  return buffer;
}

double parseNumber(const std::string& text, const std::string& where) {
  // strtod, not stod: a denormal written by exactNumber() must read back (stod refuses it as out of range).
  char* end = nullptr;
  const double value =
      text.empty() || std::isspace(static_cast<unsigned char>(text.front())) ? 0.0 : std::strtod(text.c_str(), &end);
  if (end != text.c_str() + text.size() || text.empty()) {
    throw std::invalid_argument(where + ": '" + text + "' is not a number");
  }
  return value;
}

int parseInteger(const std::string& text, const std::string& where) {
  const double value = parseNumber(text, where);
  if (value != std::floor(value) || std::abs(value) > 2147483647.0) {
    throw std::invalid_argument(where + ": '" + text + "' is not an integer");
  }
  return static_cast<int>(value);
}

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

/// \file
/// Append-only CSV files of whole records, for long runs that resume after being killed: a record (one line) is
/// formatted in memory and written with one write(2), so the file holds whole records and at most one partial last
/// line (when the process was killed during the write); opening the file for appending first cuts such a line off.
#pragma once

#include <string>
#include <vector>

namespace bimanual_skills::io {

/// The fields of one CSV line; a field in double quotes may hold commas and doubled quotes.
std::vector<std::string> splitCsv(const std::string& line);
/// `text` as one quoted CSV field (quotes doubled, newlines as spaces).
std::string quotedField(const std::string& text);
/// `value` with every digit a double has (%.17g): read back bit for bit.
std::string exactNumber(double value);
/// A whole field as a number or integer. \throws std::invalid_argument naming `where` and the text.
double parseNumber(const std::string& text, const std::string& where);
int parseInteger(const std::string& text, const std::string& where);

/// Cuts a final line without its newline off `path` (truncating the file to the end of its last whole record).
/// Returns the number of bytes dropped (0 for a whole file or no file). \throws std::runtime_error on I/O errors.
std::size_t dropPartialRecord(const std::string& path);

/// An append-only CSV file. Not copyable; closes on destruction.
class CsvAppender {
 public:
  CsvAppender() = default;
  /// Opens `path` for appending after dropPartialRecord(); writes `header` if the file is new or empty.
  /// \throws std::runtime_error when it cannot be opened or written.
  CsvAppender(const std::string& path, const std::string& header);
  ~CsvAppender();
  CsvAppender(CsvAppender&& other) noexcept;
  CsvAppender& operator=(CsvAppender&& other) noexcept;
  CsvAppender(const CsvAppender&) = delete;
  CsvAppender& operator=(const CsvAppender&) = delete;

  /// Appends `record` (no newline in it) and its newline with one write(2). \throws std::runtime_error.
  void append(const std::string& record);
  const std::string& path() const noexcept { return path_; }

 private:
  std::string path_;
  int fd_ = -1;
};

}  // namespace bimanual_skills::io

/// \file
/// Test helpers for programs and the files they write: run a command quietly, read a text file, read a CSV file.
/// Not installed; for the gtests.
#pragma once

#include <gtest/gtest.h>

#include <sys/wait.h>

#include <cmath>
#include <cstdlib>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

namespace bimanual_skills::testing {

/// Runs a shell command with its output discarded; its exit status, −1 if it did not exit normally.
inline int runQuietly(const std::string& command) {
  const int status = std::system((command + " > /dev/null 2>&1").c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

/// The whole text of a file ("" if it cannot be read).
inline std::string readTextFile(const std::string& path) {
  std::ifstream file(path);
  std::stringstream text;
  text << file.rdbuf();
  return text.str();
}

using CsvRow = std::map<std::string, std::string>;

/// The rows of a CSV file with a header line, as column → value maps; a row of the wrong width is a test failure.
/// A cell in double quotes may hold commas (the experiment programs quote algorithm names such as
/// "DR-DMP0_MCMU(3,7)"); its value is the text between the quotes.
inline std::vector<CsvRow> readCsv(const std::string& path) {
  std::ifstream file(path);
  std::string line;
  std::vector<std::string> header;
  std::vector<CsvRow> rows;
  const auto split = [](const std::string& text) {
    std::vector<std::string> cells(1);
    bool quoted = false;
    for (const char c : text) {
      if (c == '"') {
        quoted = !quoted;
      } else if (c == ',' && !quoted) {
        cells.emplace_back();
      } else {
        cells.back() += c;
      }
    }
    return cells;
  };
  if (std::getline(file, line)) header = split(line);
  while (std::getline(file, line)) {
    const std::vector<std::string> cells = split(line);
    if (cells.size() != header.size()) {
      ADD_FAILURE() << path << ": row with " << cells.size() << " cells, header has " << header.size();
      continue;
    }
    CsvRow row;
    for (std::size_t i = 0; i < cells.size(); ++i) row[header[i]] = cells[i];
    rows.push_back(row);
  }
  return rows;
}

/// The number in column `key` of a CSV row (NaN and a test failure if there is no such column).
inline double csvNumber(const CsvRow& row, const std::string& key) {
  const auto found = row.find(key);
  if (found == row.end()) {
    ADD_FAILURE() << "no column " << key;
    return std::nan("");
  }
  return std::stod(found->second);
}

}  // namespace bimanual_skills::testing

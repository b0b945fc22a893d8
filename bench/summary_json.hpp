/// \file
/// summary.json of the experiment programs: {"program", "experiment", "seed", "quick", "results": [rows]}, one row
/// per result with its keys in the order they were added; numbers with 10 significant digits.
#pragma once

#include "experiment_cli.hpp"

#include <cmath>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace bimanual_skills::bench {

/// One row of summary.json.
class JsonRow {
 public:
  JsonRow& add(const std::string& key, const std::string& value) {
    std::string escaped;
    for (const char c : value) {
      if (c == '"' || c == '\\') escaped += '\\';
      escaped += c;
    }
    return field(key, '"' + escaped + '"');
  }
  JsonRow& add(const std::string& key, const char* value) { return add(key, std::string(value)); }
  JsonRow& add(const std::string& key, bool value) { return field(key, value ? "true" : "false"); }
  template <typename Number>
  JsonRow& add(const std::string& key, Number value) {
    if (!std::isfinite(static_cast<double>(value))) return field(key, "null");  // JSON has no NaN or infinity
    std::ostringstream text;
    text.precision(10);
    text << value;
    return field(key, text.str());
  }
  const std::string& text() const { return text_; }

 private:
  JsonRow& field(const std::string& key, const std::string& value) {
    text_ += (text_.empty() ? "" : ", ") + ('"' + key + "\": ") + value;
    return *this;
  }
  std::string text_;
};

/// Writes DIR/summary.json. \throws std::runtime_error when the file cannot be written.
inline void writeSummaryJson(const ExperimentOptions& options, const std::string& program,
                             const std::vector<JsonRow>& rows) {
  const std::string path = options.out + "/summary.json";
  std::ofstream json(path);
  json << "{\n  \"program\": \"" << program << "\",\n  \"experiment\": \"" << options.experiment
       << "\",\n  \"seed\": " << options.seed << ",\n  \"quick\": " << (options.quick ? "true" : "false")
       << ",\n  \"results\": [\n";
  for (std::size_t i = 0; i < rows.size(); ++i) {
    json << "    {" << rows[i].text() << "}" << (i + 1 < rows.size() ? "," : "") << "\n";
  }
  json << "  ]\n}\n";
  if (!json) throw std::runtime_error("cannot write " + path);
}

}  // namespace bimanual_skills::bench

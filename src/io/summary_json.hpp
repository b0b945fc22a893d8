/// \file
/// summary.json of the experiment programs and the learner: {"program", "experiment", "seed", "quick", "numerics",
/// "results": [rows]}, one row per result with its keys in the order they were added, written with nlohmann-json (every
/// string escaped; a non-finite number, which JSON lacks, as null).
#pragma once

#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

namespace bimanual_skills::io {

/// One row of summary.json.
class JsonRow {
 public:
  JsonRow& add(const std::string& key, const std::string& value) {
    row_[key] = value;
    return *this;
  }
  JsonRow& add(const std::string& key, const char* value) { return add(key, std::string(value)); }
  JsonRow& add(const std::string& key, bool value) {
    row_[key] = value;
    return *this;
  }
  template <typename Number>
  JsonRow& add(const std::string& key, Number value) {
    if (std::isfinite(static_cast<double>(value))) {
      row_[key] = value;
    } else {
      row_[key] = nullptr;
    }
    return *this;
  }
  const nlohmann::ordered_json& json() const { return row_; }

 private:
  nlohmann::ordered_json row_ = nlohmann::ordered_json::object();
};

/// What a summary.json says of the run that wrote it.
struct SummaryHeader {
  std::string program, experiment;
  std::uint32_t seed = 0;
  bool quick = false;
  /// Whether the program ran with its numerics pinned (cli::numericsState()); "" leaves the key out.
  std::string numerics;
};

/// Writes `path` (a summary.json) whole: to a temporary file renamed over it, so a reader never sees half of it.
/// \throws std::runtime_error when the file cannot be written.
void writeSummaryJson(const std::string& path, const SummaryHeader& header, const std::vector<JsonRow>& rows);

}  // namespace bimanual_skills::io

#include "io/summary_json.hpp"

#include "io/whole_file.hpp"

#include <stdexcept>

namespace bimanual_skills::io {

void writeSummaryJson(const std::string& path, const SummaryHeader& header, const std::vector<JsonRow>& rows) {
  nlohmann::ordered_json summary;
  summary["program"] = header.program;
  summary["experiment"] = header.experiment;
  summary["seed"] = header.seed;
  summary["quick"] = header.quick;
  if (!header.numerics.empty()) summary["numerics"] = header.numerics;
  summary["results"] = nlohmann::ordered_json::array();
  for (const JsonRow& row : rows) summary["results"].push_back(row.json());
  if (!writeWhole(path, [&summary](std::ostream& out) { out << summary.dump(2) << '\n'; })) {
    throw std::runtime_error("cannot write " + path);
  }
}

}  // namespace bimanual_skills::io

#include "bimanual_skills/dynamics/friction_log.hpp"

#include <cmath>
#include <cstdlib>
#include <fstream>
#include <map>
#include <sstream>
#include <stdexcept>
#include <vector>

namespace bimanual_skills::dynamics {
namespace {

[[noreturn]] void fail(const std::string& message) {
  throw std::invalid_argument(message);
}

}  // namespace

FrictionLog readFrictionLog(const std::string& path) {
  std::ifstream file(path);
  if (!file) fail("cannot read friction log '" + path + "'");
  std::string line;
  if (!std::getline(file, line)) fail("friction log '" + path + "' is empty");
  std::vector<std::string> header;
  {
    std::stringstream stream(line);
    std::string name;
    while (std::getline(stream, name, ',')) header.push_back(name);
  }
  std::map<std::string, int> column;
  for (std::size_t i = 0; i < header.size(); ++i) column[header[i]] = static_cast<int>(i);
  if (!column.count("t")) fail("friction log '" + path + "': no column 't'");
  int n = 0;
  while (column.count("q" + std::to_string(n + 1))) ++n;
  if (n == 0) fail("friction log '" + path + "': no columns q1, q2, ...");
  for (const char* prefix : {"qd", "qdd", "tau"}) {
    for (int j = 1; j <= n; ++j) {
      if (!column.count(prefix + std::to_string(j))) {
        fail("friction log '" + path + "': missing column '" + prefix + std::to_string(j) + "'");
      }
    }
  }
  std::vector<std::vector<double>> rows;
  int line_number = 1;
  while (std::getline(file, line)) {
    ++line_number;
    if (line.empty()) continue;
    std::vector<double> values;
    std::stringstream stream(line);
    std::string cell;
    while (std::getline(stream, cell, ',')) {
      char* end = nullptr;
      const double v = std::strtod(cell.c_str(), &end);
      if (cell.empty() || *end != '\0' || !std::isfinite(v)) {
        fail("friction log '" + path + "' line " + std::to_string(line_number) + ": '" + cell + "' is not a number");
      }
      values.push_back(v);
    }
    if (values.size() != header.size()) {
      fail("friction log '" + path + "' line " + std::to_string(line_number) + ": " + std::to_string(values.size()) +
           " values for " + std::to_string(header.size()) + " columns");
    }
    rows.push_back(std::move(values));
  }
  if (rows.size() < 10) fail("friction log '" + path + "' has fewer than 10 samples");
  FrictionLog log;
  const auto m = static_cast<Eigen::Index>(rows.size());
  log.t.resize(m);
  log.q.resize(m, n);
  log.qd.resize(m, n);
  log.qdd.resize(m, n);
  log.tau.resize(m, n);
  for (Eigen::Index r = 0; r < m; ++r) {
    const auto& row = rows[static_cast<std::size_t>(r)];
    log.t[r] = row[static_cast<std::size_t>(column["t"])];
    if (r > 0 && !(log.t[r] > log.t[r - 1])) {
      fail("friction log '" + path + "': time does not increase at sample " + std::to_string(r + 1));
    }
    for (int j = 0; j < n; ++j) {
      const std::string k = std::to_string(j + 1);
      log.q(r, j) = row[static_cast<std::size_t>(column["q" + k])];
      log.qd(r, j) = row[static_cast<std::size_t>(column["qd" + k])];
      log.qdd(r, j) = row[static_cast<std::size_t>(column["qdd" + k])];
      log.tau(r, j) = row[static_cast<std::size_t>(column["tau" + k])];
    }
  }
  return log;
}

void writeFrictionLog(const FrictionLog& log, const std::string& path) {
  std::ofstream file(path);
  if (!file) fail("cannot write friction log '" + path + "'");
  file.precision(17);
  file << "t";
  for (const char* prefix : {"q", "qd", "qdd", "tau"}) {
    for (int j = 1; j <= log.joints(); ++j) file << ',' << prefix << j;
  }
  file << '\n';
  for (int r = 0; r < log.samples(); ++r) {
    file << log.t[r];
    for (const Eigen::MatrixXd* m : {&log.q, &log.qd, &log.qdd, &log.tau}) {
      for (int j = 0; j < log.joints(); ++j) file << ',' << (*m)(r, j);
    }
    file << '\n';
  }
  if (!file) fail("cannot write friction log '" + path + "'");
}

}  // namespace bimanual_skills::dynamics

#include "bimanual_skills/learning/student_t.hpp"

#include <cmath>
#include <numeric>
#include <stdexcept>

namespace bimanual_skills::learning {

namespace {

// t_{0.975, ν} for ν = 1..30 (standard tables, 3 decimals).
constexpr double kTable[30] = {12.706, 4.303, 3.182, 2.776, 2.571, 2.447, 2.365, 2.306, 2.262, 2.228,
                               2.201,  2.179, 2.160, 2.145, 2.131, 2.120, 2.110, 2.101, 2.093, 2.086,
                               2.080,  2.074, 2.069, 2.064, 2.060, 2.056, 2.052, 2.048, 2.045, 2.042};

}  // namespace

double studentT975(int degrees_of_freedom) {
  if (degrees_of_freedom < 1) throw std::invalid_argument("studentT975: degrees of freedom must be >= 1");
  if (degrees_of_freedom <= 30) return kTable[degrees_of_freedom - 1];
  const double z = 1.959963984540054, v = degrees_of_freedom;
  const double z3 = z * z * z, z5 = z3 * z * z, z7 = z5 * z * z;
  return z + (z3 + z) / (4.0 * v) + (5.0 * z5 + 16.0 * z3 + 3.0 * z) / (96.0 * v * v) +
         (3.0 * z7 + 19.0 * z5 + 17.0 * z3 - 15.0 * z) / (384.0 * v * v * v);
}

MeanInterval meanInterval95(const std::vector<double>& values) {
  if (values.empty()) throw std::invalid_argument("meanInterval95: no values");
  MeanInterval m;
  m.n = static_cast<int>(values.size());
  m.mean = std::accumulate(values.begin(), values.end(), 0.0) / m.n;
  if (m.n < 2) return m;
  double squares = 0.0;
  for (double v : values) squares += (v - m.mean) * (v - m.mean);
  m.std_dev = std::sqrt(squares / (m.n - 1));
  m.half_width = studentT975(m.n - 1) * m.std_dev / std::sqrt(static_cast<double>(m.n));
  return m;
}

}  // namespace bimanual_skills::learning

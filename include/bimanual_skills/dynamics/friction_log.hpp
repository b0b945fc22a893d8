/// \file
/// Logged joint data for friction identification (thesis Sec. 4.2) and its CSV files. Offline: allocates and throws.
#pragma once

#include <Eigen/Core>

#include <string>

namespace bimanual_skills::dynamics {

/// Logged samples, one row per sample and one column per joint (time in s, SI units).
struct FrictionLog {
  Eigen::VectorXd t;
  Eigen::MatrixXd q, qd, qdd, tau;  ///< tau: the torque the controller applied, u_c of (2.12).

  int samples() const noexcept { return static_cast<int>(t.size()); }
  int joints() const noexcept { return static_cast<int>(q.cols()); }
};

/// Reads a CSV log whose header names the columns t, q1..qn, qd1..qdn, qdd1..qddn, tau1..taun (any order).
/// \throws std::invalid_argument naming the file, line and column of any problem (missing columns, bad numbers,
/// non-increasing time, fewer than 10 samples).
FrictionLog readFrictionLog(const std::string& path);
/// Writes a log as readFrictionLog() reads it, with 17 significant digits. \throws std::invalid_argument when the
/// file cannot be written.
void writeFrictionLog(const FrictionLog& log, const std::string& path);

}  // namespace bimanual_skills::dynamics

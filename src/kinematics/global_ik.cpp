#include "bimanual_skills/kinematics/global_ik.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace bimanual_skills::kinematics {
namespace {

constexpr double kTwoPi = 2.0 * M_PI;

}  // namespace

ClikParameters GlobalIkParameters::defaultLocal() {
  ClikParameters local;
  local.inverse = InverseOperator::ErrorDamping;
  local.limits = LimitScheme::None;
  local.max_iterations = 40;
  return local;
}

ClikParameters GlobalIkParameters::defaultRefine() {
  ClikParameters refine;
  refine.inverse = InverseOperator::ErrorDamping;
  refine.limits = LimitScheme::None;
  refine.clamp_to_limits = true;
  refine.max_iterations = 100;
  return refine;
}

void GlobalIkParameters::validate() const {
  local.validate();
  refine.validate();
  if (refine.mode != local.mode) {
    throw std::invalid_argument("GlobalIkParameters: refine.mode must equal local.mode");
  }
  const auto require = [](bool ok, const char* what) {
    if (!ok) throw std::invalid_argument(std::string("GlobalIkParameters: ") + what);
  };
  require(std::isfinite(timeout) && timeout > 0.0, "timeout must be positive");
  require(max_attempts >= 1, "max_attempts must be >= 1");
  require(std::isfinite(distinct_tolerance) && distinct_tolerance > 0.0, "distinct_tolerance must be positive");
  require(max_solutions >= 1, "max_solutions must be >= 1");
}

GlobalIkSolver::GlobalIkSolver(const ChainModel& model, const GlobalIkParameters& parameters)
    : model_(model),
      parameters_(parameters),
      local_(parameters.local),
      refine_(parameters.refine),
      data_(model, parameters.local),
      refine_data_(model, parameters.refine),
      candidate_(model.nq()),
      best_(model.nq()),
      start_(model.nq()),
      solutions_(static_cast<std::size_t>(std::max(1, parameters.max_solutions)), Eigen::VectorXd::Zero(model.nq())) {
  parameters_.validate();
}

bool GlobalIkSolver::wrapIntoLimits(Eigen::Ref<Eigen::VectorXd> q) const noexcept {
  const auto& joints = model_.joints();
  for (int i = 0; i < model_.nq(); ++i) {
    const double lo = model_.lowerLimits()[i];
    const double hi = model_.upperLimits()[i];
    if (joints[static_cast<std::size_t>(i)].type != JointType::Revolute) continue;
    if (q[i] > hi) q[i] -= kTwoPi * std::ceil((q[i] - hi) / kTwoPi);
    if (q[i] < lo) q[i] += kTwoPi * std::ceil((lo - q[i]) / kTwoPi);
  }
  return model_.withinLimits(q);
}

bool GlobalIkSolver::isKnownSolution(const Eigen::VectorXd& q) const noexcept {
  for (int i = 0; i < solution_count_; ++i) {
    if ((solutions_[static_cast<std::size_t>(i)] - q).cwiseAbs().maxCoeff() < parameters_.distinct_tolerance) {
      return true;
    }
  }
  return false;
}

GlobalIkResult GlobalIkSolver::solve(const Eigen::Isometry3d& target, const Eigen::Ref<const Eigen::VectorXd>& seed,
                                     Eigen::Ref<Eigen::VectorXd> q, double timeout) noexcept {
  GlobalIkResult result;
  const double budget = timeout > 0.0 && std::isfinite(timeout) ? timeout : parameters_.timeout;
  solution_count_ = 0;
  const int n = model_.nq();
  if (seed.size() != n || q.size() != n || !seed.allFinite() || !target.matrix().allFinite()) return result;

  using Clock = std::chrono::steady_clock;
  const auto start_time = Clock::now();
  const auto elapsed = [&] { return std::chrono::duration<double>(Clock::now() - start_time).count(); };
  rng_.seed(parameters_.seed);
  double best_residual = std::numeric_limits<double>::infinity();
  double best_distance = std::numeric_limits<double>::infinity();
  bool found = false;
  bool out_of_time = false;

  for (int attempt = 0; attempt < parameters_.max_attempts; ++attempt) {
    const double remaining = budget - elapsed();
    if (remaining <= 0.0) {
      out_of_time = true;
      break;
    }
    // The caller's seed first, then uniform draws within the limits (±π for unlimited joints).
    if (attempt == 0) {
      start_ = seed;
    } else {
      for (int i = 0; i < n; ++i) {
        const double lo = std::isfinite(model_.lowerLimits()[i]) ? model_.lowerLimits()[i] : -M_PI;
        const double hi = std::isfinite(model_.upperLimits()[i]) ? model_.upperLimits()[i] : M_PI;
        start_[i] = std::uniform_real_distribution<double>(lo, hi)(rng_);
      }
    }
    candidate_ = start_;
    local_.timeout = remaining;
    IkResult local = kinematics::solve(model_, local_, data_, candidate_, target);
    ++result.attempts;
    result.iterations += local.iterations;
    if (local.status == IkStatus::InvalidInput) return result;
    bool valid = local.status == IkStatus::Converged && wrapIntoLimits(candidate_);
    if (!valid && parameters_.refine_enabled && local_.limits != LimitScheme::None &&
        local.status != IkStatus::Timeout) {
      refine_.timeout = std::max(budget - elapsed(), 1e-9);
      local = kinematics::solve(model_, refine_, refine_data_, candidate_, target);
      result.iterations += local.iterations;
      valid = local.status == IkStatus::Converged && wrapIntoLimits(candidate_);
    }
    if (!valid) {
      if (!found && local.residual < best_residual) {
        best_residual = local.residual;
        best_ = candidate_;
      }
      if (local.status == IkStatus::Timeout) {
        out_of_time = true;
        break;
      }
      continue;
    }
    const double distance = (candidate_ - seed).norm();
    if (!found || distance < best_distance) {
      best_ = candidate_;
      best_distance = distance;
      best_residual = local.residual;
    }
    found = true;
    if (parameters_.mode == SolutionMode::FirstFound) break;
    if (parameters_.mode == SolutionMode::AllDistinct && !isKnownSolution(candidate_)) {
      solutions_[static_cast<std::size_t>(solution_count_++)] = candidate_;
      if (solution_count_ >= parameters_.max_solutions) break;
    }
  }

  if (found && parameters_.mode != SolutionMode::AllDistinct) {
    solutions_[0] = best_;
    solution_count_ = 1;
  }
  result.residual = best_residual;
  if (std::isfinite(best_residual)) {
    q = best_;
  } else {
    q = seed;
  }
  result.status = found ? IkStatus::Converged : out_of_time ? IkStatus::Timeout : IkStatus::MaxIterations;
  return result;
}

}  // namespace bimanual_skills::kinematics

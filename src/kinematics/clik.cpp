// The CLIK solver: parameters, data, one step (evaluate + the configured scheme) and the iteration of solve().
#include "clik_internal.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace bimanual_skills::kinematics {
namespace {

/// FK, Jacobian and weighted task error at q. False on invalid input.
bool evaluate(const ChainModel& model, const ClikParameters& p, ClikData& data,
              const Eigen::Ref<const Eigen::VectorXd>& q, const Eigen::Isometry3d& target) noexcept {
  if (!target.matrix().allFinite()) return false;
  if (computeJacobian(model, data.kinematics, q) != KinematicsStatus::Success) return false;
  const int m = taskDimension(p.mode);
  poseError(data.kinematics.tipPose(), target, p.mode, data.error);
  data.task = data.error;
  data.jacobian = data.kinematics.jacobian.topRows(m);
  if (p.mode == TaskMode::Pose) {
    data.task.tail<3>() *= p.rotation_weight;
    data.jacobian.bottomRows<3>() *= p.rotation_weight;
  }
  return true;
}

/// The step of the configured scheme with activation buffer `beta`, from the state left by evaluate(). False on a
/// numerical failure.
bool computeStep(const ChainModel& model, const ClikParameters& p, double beta, ClikData& data,
                 const Eigen::Ref<const Eigen::VectorXd>& q) noexcept {
  using namespace clik_detail;
  const double E = 0.5 * data.task.squaredNorm();
  bool ok = false;
  switch (p.limits) {
    case LimitScheme::None:
      ok = stepWithoutLimits(p, E, data);
      break;
    case LimitScheme::JointWeighting:
      ok = stepJointWeighting(model, p, E, data, q);
      break;
    case LimitScheme::GradientProjection:
      ok = stepGradientProjection(model, p, E, data, q);
      break;
    case LimitScheme::JointClamping:
      ok = stepJointClamping(model, p, beta, E, data, q);
      break;
    case LimitScheme::TaskAugmentation:
      ok = stepTaskAugmentation(model, p, beta, E, data, q);
      break;
    case LimitScheme::TaskPriority:
      ok = stepTaskPriority(model, p, beta, E, data, q);
      break;
    case LimitScheme::ContinuousTaskPriority:
      ok = stepContinuousTaskPriority(model, p, beta, E, data, q);
      break;
  }
  return ok && data.dq.allFinite();
}

}  // namespace

void ClikParameters::validate() const {
  const auto require = [](bool ok, const char* what) {
    if (!ok) throw std::invalid_argument(std::string("ClikParameters: ") + what);
  };
  require(std::isfinite(rotation_weight) && rotation_weight > 0.0, "rotation_weight must be positive");
  require(std::isfinite(pinv_tolerance) && pinv_tolerance >= 0.0, "pinv_tolerance must be >= 0");
  require(std::isfinite(lambda) && lambda > 0.0, "lambda must be positive");
  require(std::isfinite(filter_epsilon) && filter_epsilon > 0.0, "filter_epsilon must be positive");
  require(std::isfinite(lambda_max) && lambda_max > 0.0, "lambda_max must be positive");
  require(std::isfinite(ied_omega) && ied_omega >= 0.0, "ied_omega must be >= 0");
  require(std::isfinite(sigma0) && sigma0 > 0.0, "sigma0 must be positive");
  require(std::isfinite(nu) && nu > sigma0 && nu * sigma0 < 2.0, "nu must satisfy sigma0 < nu < 2 / sigma0 (3.11)");
  require(std::isfinite(gamma_max) && gamma_max > 0.0, "gamma_max must be positive");
  require(std::isfinite(gp_gain), "gp_gain must be finite");
  require(std::isfinite(beta) && beta > 0.0, "beta must be positive");
  require(stall_window >= 1, "stall_window must be >= 1");
  require(std::isfinite(beta_decay) && beta_decay > 0.0 && beta_decay <= 1.0, "beta_decay must be in (0, 1]");
  require(std::isfinite(lambda_jl) && lambda_jl >= 0.0, "lambda_jl must be >= 0");
  require(max_iterations >= 1, "max_iterations must be >= 1");
  require(!(limits == LimitScheme::ContinuousTaskPriority && inverse == InverseOperator::Transpose),
          "CTP needs an inverse operator inside its continuous pseudoinverse; the transpose (JT) is none");
  require(std::isfinite(tolerance) && tolerance > 0.0, "tolerance must be positive");
  require(std::isfinite(timeout) && timeout >= 0.0, "timeout must be >= 0 (0: none)");
}

double limitActivation(double q, double lower, double upper, double beta) noexcept {
  const double distance = std::min(q - lower, upper - q);
  if (!(distance < beta)) return 0.0;  // also for infinite limits
  if (distance <= 0.0) return 1.0;
  const double x = distance / beta;
  return 0.5 * (1.0 + std::tanh(1.0 / x - 1.0 / (1.0 - x)));
}

ClikData::ClikData(const ChainModel& model, const ClikParameters& parameters)
    : kinematics(model),
      error(taskDimension(parameters.mode)),
      task(taskDimension(parameters.mode)),
      jacobian(taskDimension(parameters.mode), model.nq()),
      dq(Eigen::VectorXd::Zero(model.nq())),
      svd_augmented(taskDimension(parameters.mode) + model.nq(), model.nq()),
      svd_inverse(model.nq(), taskDimension(parameters.mode)),
      gram(taskDimension(parameters.mode), taskDimension(parameters.mode)),
      gram_llt(taskDimension(parameters.mode)),
      activation(Eigen::VectorXd::Zero(model.nq())),
      centre(model.nq()),
      scale(Eigen::VectorXd::Ones(model.nq())),
      previous_gradient(Eigen::VectorXd::Zero(model.nq())),
      column_norms(model.nq()),
      limit_step(model.nq()),
      task_step(model.nq()),
      centring_gradient(model.nq()),
      null_space_part(model.nq()),
      component(model.nq()),
      task_residual(taskDimension(parameters.mode)),
      task_image(taskDimension(parameters.mode)),
      gains(taskDimension(parameters.mode) + model.nq()),
      task_scratch(taskDimension(parameters.mode) + model.nq()),
      columns(taskDimension(parameters.mode), model.nq()),
      augmented(taskDimension(parameters.mode) + model.nq(), model.nq()),
      augmented_task(taskDimension(parameters.mode) + model.nq()),
      inverse(model.nq(), taskDimension(parameters.mode)),
      scattered(model.nq(), taskDimension(parameters.mode)) {
  parameters.validate();
  const int m = taskDimension(parameters.mode);
  const int n = model.nq();
  if (n > kClikMaxJoints) {
    throw std::invalid_argument("ClikData: chains of more than " + std::to_string(kClikMaxJoints) +
                                " joints are not supported");
  }
  svd_by_columns.reserve(static_cast<std::size_t>(n));
  for (int c = 1; c <= n; ++c) svd_by_columns.emplace_back(m, c);
  for (int i = 0; i < n; ++i) {
    const double lo = model.lowerLimits()[i];
    const double hi = model.upperLimits()[i];
    centre[i] = std::isfinite(lo) && std::isfinite(hi) ? 0.5 * (lo + hi) : 0.0;
  }
}

IkStatus step(const ChainModel& model, const ClikParameters& parameters, ClikData& data,
              const Eigen::Ref<const Eigen::VectorXd>& q, const Eigen::Isometry3d& target) noexcept {
  if (!evaluate(model, parameters, data, q, target)) return IkStatus::InvalidInput;
  return computeStep(model, parameters, parameters.beta, data, q) ? IkStatus::StepComputed : IkStatus::NumericalFailure;
}

IkResult solve(const ChainModel& model, const ClikParameters& parameters, ClikData& data, Eigen::Ref<Eigen::VectorXd> q,
               const Eigen::Isometry3d& target) noexcept {
  IkResult result;
  const auto start = std::chrono::steady_clock::now();
  data.previous_gradient.setZero();
  double beta = parameters.beta;
  double reference = std::numeric_limits<double>::infinity();  // residual at the start of the current window
  int stalled = 0;
  for (int iteration = 0;; ++iteration) {
    if (!evaluate(model, parameters, data, q, target)) {
      result.status = IkStatus::InvalidInput;
      return result;
    }
    result.iterations = iteration;
    result.residual = data.error.cwiseAbs().maxCoeff();
    if (result.residual <= parameters.tolerance) {
      result.status = IkStatus::Converged;
      return result;
    }
    if (result.residual < 0.9 * reference) {
      reference = result.residual;
      stalled = 0;
    } else if (++stalled >= parameters.stall_window) {
      beta *= parameters.beta_decay;
      reference = result.residual;
      stalled = 0;
    }
    if (iteration >= parameters.max_iterations) {
      result.status = IkStatus::MaxIterations;
      return result;
    }
    if (parameters.timeout > 0.0 &&
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count() > parameters.timeout) {
      result.status = IkStatus::Timeout;
      return result;
    }
    if (!computeStep(model, parameters, beta, data, q)) {
      result.status = IkStatus::NumericalFailure;
      return result;
    }
    q += data.dq;
    if (parameters.clamp_to_limits) q = q.cwiseMax(model.lowerLimits()).cwiseMin(model.upperLimits());
  }
}

}  // namespace bimanual_skills::kinematics

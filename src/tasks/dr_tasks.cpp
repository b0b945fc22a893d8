#include "bimanual_skills/tasks/dr_tasks.hpp"

#include "bimanual_skills/kinematics/global_ik.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace bimanual_skills::tasks {

Eigen::Vector2d planarTip(const Eigen::Ref<const Eigen::VectorXd>& q) noexcept {
  Eigen::Vector2d tip = Eigen::Vector2d::Zero();
  double angle = 0.0;
  for (Eigen::Index i = 0; i < q.size(); ++i) {
    angle += q[i];
    tip += Eigen::Vector2d(std::cos(angle), std::sin(angle));
  }
  return tip;
}

Eigen::MatrixXd perturbedMinimumJerk(int dofs, int samples, double amplitude, const std::vector<double>& centres,
                                     double width, double variance, std::mt19937& rng) {
  if (dofs < 1 || samples < 2 || !(width > 0.0) || !(variance > 0.0)) {
    throw std::invalid_argument("perturbedMinimumJerk: needs dofs >= 1, samples >= 2, width > 0, variance > 0");
  }
  std::normal_distribution<double> normal(0.0, std::sqrt(variance));
  Eigen::MatrixXd y(samples, dofs);
  for (int j = 0; j < dofs; ++j) {
    std::vector<double> a;
    for (std::size_t c = 0; c < centres.size(); ++c) a.push_back(normal(rng));
    for (int i = 0; i < samples; ++i) {
      const double s = static_cast<double>(i) / (samples - 1);
      y(i, j) = amplitude * minimumJerk(s);
      for (std::size_t c = 0; c < centres.size(); ++c) {
        y(i, j) += a[c] * std::exp(-(s - centres[c]) * (s - centres[c]) / (width * width));
      }
    }
  }
  return y;
}

Eigen::MatrixXd secondDifferences(const Eigen::MatrixXd& y, double dt) {
  Eigen::MatrixXd ydd = Eigen::MatrixXd::Zero(y.rows(), y.cols());
  for (Eigen::Index i = 1; i + 1 < y.rows(); ++i)
    ydd.row(i) = (y.row(i + 1) - 2.0 * y.row(i) + y.row(i - 1)) / (dt * dt);
  return ydd;
}

void rolloutDrDmp(const primitives::DrDmp& dmp, double dt, int steps, double exploration, std::mt19937& rng,
                  DrDmpRollout& out) {
  const int d = dmp.dofs();
  primitives::DrDmpState state = dmp.initialState();
  out.positions.resize(steps + 1, d);
  out.accelerations.resize(steps + 1, d);
  out.forcing.resize(steps, d);
  out.positions.row(0) = state.dmp.y.transpose();
  out.accelerations.row(0).setZero();
  std::normal_distribution<double> normal(0.0, exploration > 0.0 ? exploration : 1.0);
  for (int k = 0; k < steps; ++k) {
    if (exploration > 0.0) {
      for (int j = 0; j < d; ++j) state.exploration[j] = normal(rng);
    }
    if (dmp.step(state, dt) != primitives::DmpStatus::Success) {
      throw std::invalid_argument("rolloutDrDmp: the DR-DMP step failed at step " + std::to_string(k + 1));
    }
    out.positions.row(k + 1) = state.dmp.y.transpose();
    out.accelerations.row(k + 1) = state.dmp.ydd.transpose();
    out.forcing.row(k) = state.forcing.transpose();
  }
}

PlanarViaPointTask::PlanarViaPointTask(int dofs, std::uint32_t seed) : dofs_(dofs) {
  if (dofs < 2) throw std::invalid_argument("PlanarViaPointTask: needs at least 2 DoF");
  std::mt19937 rng(seed);
  const double amplitude = 2.0 * M_PI / dofs;
  for (int k = 0; k < kDemonstrations; ++k) {
    demonstrations_.push_back(
        perturbedMinimumJerk(dofs, kSteps + 1, amplitude, {1.0 / 3.0, 2.0 / 3.0}, 0.1, 1.0 / (4.0 * dofs), rng));
  }
  // Every joint at the same angle θ: the mean motion's tip path, which the arm follows at θ = amplitude · s(t).
  const auto pathTip = [dofs](double theta) { return planarTip(Eigen::VectorXd::Constant(dofs, theta)); };
  for (const double time : {0.3, 0.6}) {
    via_steps_.push_back(static_cast<int>(std::lround(time / kDt)));
    const double now = amplitude * minimumJerk(time);
    const Eigen::Vector2d here = pathTip(now);
    double behind = now, ahead = now + kViaAngleStep;
    // The path passes (d, 0) and the origin, d ≥ 2 apart, within one turn: some point is kViaLead away.
    while ((pathTip(ahead) - here).norm() < kViaLead && ahead < now + 2.0 * M_PI) {
      behind = ahead;
      ahead += kViaAngleStep;
    }
    for (int i = 0; i < 60; ++i) {
      const double mid = 0.5 * (behind + ahead);
      ((pathTip(mid) - here).norm() < kViaLead ? behind : ahead) = mid;
    }
    via_points_.push_back(pathTip(ahead));
  }
  acceleration_weights_ = Eigen::VectorXd::LinSpaced(dofs, dofs, 1.0);
  acceleration_weights_ *= kAccelerationWeight / acceleration_weights_.sum();
}

double PlanarViaPointTask::reward(const Eigen::MatrixXd& positions, const Eigen::MatrixXd& accelerations) const {
  if (positions.rows() != kSteps + 1 || positions.cols() != dofs_ || accelerations.rows() != kSteps + 1 ||
      accelerations.cols() != dofs_) {
    throw std::invalid_argument("PlanarViaPointTask::reward: positions and accelerations must be (steps + 1) x dofs");
  }
  double cost = 0.0;
  for (std::size_t v = 0; v < via_points_.size(); ++v) {
    cost += kViaWeight * (planarTip(positions.row(via_steps_[v]).transpose()) - via_points_[v]).squaredNorm();
  }
  cost += (accelerations.array().square().rowwise() * acceleration_weights_.transpose().array()).sum();
  return -cost;
}

PlanarTrackingTask::PlanarTrackingTask(int dofs, std::uint32_t seed) : dofs_(dofs) {
  if (dofs < 2) throw std::invalid_argument("PlanarTrackingTask: needs at least 2 DoF");
  std::mt19937 rng(seed);
  const double amplitude = M_PI / dofs;
  for (int k = 0; k < kDemonstrations; ++k) {
    demonstrations_.push_back(
        perturbedMinimumJerk(dofs, kSamples, amplitude, {1.0 / 3.0, 2.0 / 3.0}, 0.1, 1.0 / (4.0 * dofs), rng));
  }
  target_.resize(kSamples, 2);
  for (int i = 0; i < kSamples; ++i) {
    const double s = static_cast<double>(i) / (kSamples - 1);
    target_.row(i) =
        planarTip(Eigen::VectorXd::Constant(dofs, amplitude * minimumJerk(s) + 0.05 * std::sin(M_PI * s))).transpose();
  }
}

double PlanarTrackingTask::reward(const Eigen::MatrixXd& positions) const {
  if (positions.rows() != kSamples || positions.cols() != dofs_) {
    throw std::invalid_argument("PlanarTrackingTask::reward: positions must be samples x dofs");
  }
  double cost = 0.0;
  for (int i = 0; i < kSamples; ++i) {
    cost += kTrackingWeight * (planarTip(positions.row(i).transpose()) - target_.row(i).transpose()).squaredNorm();
  }
  cost += kAccelerationWeight * secondDifferences(positions, dt()).squaredNorm();
  return -cost;
}

namespace {

/// The demonstration of WamCircleTask and the circle it was made from.
struct CircleDemonstration {
  Eigen::MatrixXd positions;
  Circle3d nominal;
};

/// The demonstration of WamCircleTask: the circle through the IK solver, perturbed on the tool before IK or on the
/// joints after it, then the joints' white noise.
CircleDemonstration circleDemonstration(const kinematics::ChainModel& model, std::uint32_t seed,
                                        CirclePerturbation perturbation) {
  Eigen::VectorXd q(7);
  q << 0.0, 0.6, 0.0, 1.6, 0.0, 0.4, 0.0;
  kinematics::ChainData data(model);
  if (kinematics::forwardKinematics(model, data, q) != kinematics::KinematicsStatus::Success) {
    throw std::invalid_argument("WamCircleTask: forward kinematics failed at the nominal posture");
  }
  const Eigen::Isometry3d nominal = data.tipPose();
  const Eigen::Matrix3d tilt = Eigen::AngleAxisd(M_PI / 6.0, Eigen::Vector3d::UnitX()).toRotationMatrix();
  const Eigen::Vector3d u = tilt * Eigen::Vector3d::UnitY(), v = tilt * Eigen::Vector3d::UnitZ();
  constexpr double radius = 0.12;
  const Eigen::Vector3d centre = nominal.translation() - radius * u;  // the nominal tool position is on the circle
  kinematics::GlobalIkParameters parameters;
  parameters.timeout = 1.0;  // never binding: the same attempts, hence the same answer, on any machine
  kinematics::GlobalIkSolver solver(model, parameters);
  constexpr double duration = WamCircleTask::kDuration;
  const int samples = static_cast<int>(std::lround(duration / WamCircleTask::kDt)) + 1;
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> uniform(0.0, duration);
  const auto bump = [](double t, double centre, double width) {
    return std::exp(-(t - centre) * (t - centre) / (width * width));
  };
  // CirclePerturbation::Task: the tool's deviations, faded in and out over a second at either end.
  std::vector<std::pair<double, Eigen::Vector3d>> deviations;
  if (perturbation == CirclePerturbation::Task) {
    std::normal_distribution<double> amplitude(0.0, 0.008);
    for (int b = 0; b < 4; ++b) {
      const double c = uniform(rng);
      const double dx = amplitude(rng), dy = amplitude(rng), dz = amplitude(rng);
      deviations.emplace_back(c, Eigen::Vector3d(dx, dy, dz));
    }
  }
  Eigen::MatrixXd y(samples, 7);
  Eigen::VectorXd solution(7);
  for (int i = 0; i < samples; ++i) {
    const double t = i * WamCircleTask::kDt;
    const double angle = 2.0 * M_PI * minimumJerk(static_cast<double>(i) / (samples - 1));
    Eigen::Isometry3d target = nominal;
    target.translation() = centre + radius * (std::cos(angle) * u + std::sin(angle) * v);
    const double fade = minimumJerk(std::min(1.0, t)) * minimumJerk(std::min(1.0, duration - t));
    for (const auto& [c, a] : deviations) target.translation() += fade * bump(t, c, 1.0) * a;
    if (solver.solve(target, q, solution).status != kinematics::IkStatus::Converged) {
      throw std::invalid_argument("WamCircleTask: no IK solution at sample " + std::to_string(i));
    }
    q = solution;
    y.row(i) = q.transpose();
  }
  std::normal_distribution<double> joint_amplitude(0.0, 0.03), noise(0.0, 0.002);
  for (int j = 0; j < 7; ++j) {
    if (perturbation == CirclePerturbation::Joint) {
      for (int b = 0; b < 3; ++b) {
        const double c = uniform(rng), a = joint_amplitude(rng);
        for (int i = 0; i < samples; ++i) y(i, j) += a * bump(i * WamCircleTask::kDt, c, 0.4);
      }
    }
    for (int i = 1; i + 1 < samples; ++i) y(i, j) += noise(rng);
  }
  return {y, Circle3d{centre, u.cross(v), radius}};
}

}  // namespace

WamCircleTask::WamCircleTask(const kinematics::ChainModel& model, std::uint32_t seed, CirclePerturbation perturbation,
                             CircleTarget target)
    : model_(model.nq() == 7 ? model : throw std::invalid_argument("WamCircleTask: needs a 7-joint chain")),
      data_(model_) {
  CircleDemonstration made = circleDemonstration(model_, seed, perturbation);
  demonstration_ = std::move(made.positions);
  circle_ = target == CircleTarget::Nominal ? made.nominal : Circle3d::fit(toolPath(demonstration_));
}

Eigen::MatrixXd WamCircleTask::toolPath(const Eigen::MatrixXd& positions) {
  if (positions.cols() != 7) throw std::invalid_argument("WamCircleTask::toolPath: positions must have 7 columns");
  Eigen::MatrixXd tool(positions.rows(), 3);
  for (Eigen::Index i = 0; i < positions.rows(); ++i) {
    if (kinematics::forwardKinematics(model_, data_, positions.row(i).transpose()) !=
        kinematics::KinematicsStatus::Success) {
      throw std::invalid_argument("WamCircleTask: non-finite positions at row " + std::to_string(i));
    }
    tool.row(i) = data_.tipPose().translation().transpose();
  }
  return tool;
}

double WamCircleTask::reward(const Eigen::MatrixXd& positions, const Eigen::MatrixXd& accelerations) {
  if (positions.rows() != demonstration_.rows() || positions.cols() != 7 || accelerations.rows() != positions.rows() ||
      accelerations.cols() != 7) {
    throw std::invalid_argument("WamCircleTask::reward: positions and accelerations must be (steps + 1) x 7");
  }
  const Eigen::MatrixXd tool = toolPath(positions);
  double distance = 0.0;
  for (Eigen::Index i = 0; i < tool.rows(); ++i) distance += circle_.distance(tool.row(i).transpose());
  return -(distance + kAccelerationWeight * accelerations.squaredNorm());
}

}  // namespace bimanual_skills::tasks

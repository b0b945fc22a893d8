#include "bimanual_skills/tasks/policy_search_tasks.hpp"

#include <Eigen/QR>
#include <Eigen/SVD>

#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>
#include <string>

namespace bimanual_skills::tasks {

double minimumJerk(double s) noexcept {
  return 10 * std::pow(s, 3) - 15 * std::pow(s, 4) + 6 * std::pow(s, 5);
}

MultimodalReward MultimodalReward::inDimension(int d) {
  if (d < 2 || d % 2 != 0) {
    throw std::invalid_argument("multimodal reward: the dimension must be even and >= 2 (got " + std::to_string(d) +
                                ")");
  }
  MultimodalReward out;
  const double scale = std::sqrt(2.0 / d);
  for (Eigen::VectorXd& p : out.optima) p = (scale * p).replicate(d / 2, 1).eval();
  return out;
}

Eigen::VectorXd MultimodalReward::centroid() const {
  Eigen::VectorXd sum = Eigen::VectorXd::Zero(dimension());
  for (const Eigen::VectorXd& p : optima) sum += p;
  return sum / static_cast<double>(optima.size());
}

double MultimodalReward::operator()(const Eigen::VectorXd& theta) const {
  if (theta.size() < dimension()) {
    throw std::invalid_argument("multimodal reward: a point of " + std::to_string(theta.size()) +
                                " entries for optima of " + std::to_string(dimension()));
  }
  const auto t = theta.head(dimension());
  double r = 10.0 * (centroid() - t).norm();
  for (const Eigen::VectorXd& p : optima) r -= 5.0 * (p - t).norm();
  return r;
}

DmpRollout DmpRollout::fit(const Eigen::MatrixXd& demonstration, double dt, int kernels) {
  primitives::DmpParameters parameters;
  parameters.kernels = kernels;
  return {primitives::Dmp::fit(parameters, demonstration, dt), dt, static_cast<int>(demonstration.rows()) - 1};
}

Eigen::VectorXd DmpRollout::parameters() const {
  const Eigen::MatrixXd& w = dmp.weights();
  Eigen::VectorXd theta(w.size());
  for (Eigen::Index d = 0; d < w.rows(); ++d) theta.segment(d * w.cols(), w.cols()) = w.row(d).transpose();
  return theta;
}

void DmpRollout::rollout(const Eigen::VectorXd& theta, Eigen::MatrixXd& y, Eigen::MatrixXd& ydd) const {
  const Eigen::Index dofs = dmp.dofs(), kernels = dmp.parameters().kernels;
  if (theta.size() != dofs * kernels) {
    throw std::invalid_argument("DmpRollout: theta needs " + std::to_string(dofs * kernels) + " entries");
  }
  Eigen::MatrixXd w(dofs, kernels);
  for (Eigen::Index d = 0; d < dofs; ++d) w.row(d) = theta.segment(d * kernels, kernels).transpose();
  const primitives::Dmp sample = dmp.withWeights(w);
  primitives::DmpState state = sample.initialState();
  y.resize(steps + 1, dofs);
  ydd.resize(steps + 1, dofs);
  y.row(0) = state.y.transpose();
  ydd.row(0).setZero();
  for (int i = 1; i <= steps; ++i) {
    if (sample.step(state, dt) != primitives::DmpStatus::Success) {
      throw std::invalid_argument("DmpRollout: the DMP step failed at step " + std::to_string(i));
    }
    y.row(i) = state.y.transpose();
    ydd.row(i) = state.ydd.transpose();
  }
}

Eigen::MatrixXd DmpRollout::stepBasis() const {
  Eigen::MatrixXd basis(steps, dmp.parameters().kernels);
  primitives::DmpState state = dmp.initialState();
  Eigen::VectorXd g(basis.cols());
  for (int i = 0; i < steps; ++i) {
    dmp.basis(state.x, g);
    basis.row(i) = g.transpose();
    if (dmp.step(state, dt) != primitives::DmpStatus::Success) {
      throw std::invalid_argument("DmpRollout: the DMP step failed at step " + std::to_string(i + 1));
    }
  }
  return basis;
}

Eigen::MatrixXd BottleTask::demonstration() {
  const int samples = 101;
  Eigen::MatrixXd line(samples, 2);
  for (int i = 0; i < samples; ++i) {
    line(i, 0) = minimumJerk(static_cast<double>(i) / (samples - 1));
    line(i, 1) = 0.0;
  }
  return line;
}

DmpRollout BottleTask::initialPolicy() {
  return DmpRollout::fit(demonstration(), kDemonstrationStep, 10);
}

namespace {

/// Distance from c to the path segment ending at sample i.
double segmentDistance(const Eigen::MatrixXd& y, Eigen::Index i, const Eigen::Vector2d& c) {
  const Eigen::Vector2d b = y.row(i).transpose();
  if (i == 0) return (b - c).norm();
  const Eigen::Vector2d a = y.row(i - 1).transpose();
  const Eigen::Vector2d ab = b - a;
  const double t = ab.squaredNorm() > 0.0 ? std::clamp((c - a).dot(ab) / ab.squaredNorm(), 0.0, 1.0) : 0.0;
  return (a + t * ab - c).norm();
}

}  // namespace

double BottleTask::reward(const Eigen::MatrixXd& y, bool* satisfactory) const {
  double length = 0.0;
  for (Eigen::Index i = 1; i < y.rows(); ++i) length += (y.row(i) - y.row(i - 1)).norm();
  int down = 0;
  std::vector<double> side;
  for (const auto& c : centres) {
    double nearest = 1e300;
    double side_at = 0.0;
    bool passed = false;
    for (Eigen::Index i = 0; i < y.rows(); ++i) {
      const Eigen::Vector2d p = y.row(i).transpose();
      nearest = std::min(nearest, segmentDistance(y, i, c));
      if (!passed && p.x() >= c.x()) {
        side_at = p.y();
        passed = true;
      }
    }
    if (nearest < radius) ++down;
    side.push_back(side_at);
  }
  const bool crossed = side[0] * side[1] < 0.0;
  if (satisfactory != nullptr) *satisfactory = down == 0 && crossed;
  return -2.0 * down - 0.15 * length - (crossing_term && !crossed ? 4.0 : 0.0);
}

Circle3d Circle3d::fit(const Eigen::MatrixXd& points) {
  const auto samples = points.rows();
  if (samples < 3 || points.cols() != 3 || !points.allFinite()) {
    throw std::invalid_argument("Circle3d::fit: needs at least 3 finite points as the rows of an N x 3 matrix");
  }
  const Eigen::Vector3d centroid = points.colwise().mean().transpose();
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(points.rowwise() - centroid.transpose(), Eigen::ComputeThinV);
  const Eigen::Vector3d u = svd.matrixV().col(0), v = svd.matrixV().col(1);
  Eigen::MatrixXd A(samples, 3);
  Eigen::VectorXd rhs(samples);
  for (Eigen::Index i = 0; i < samples; ++i) {
    const Eigen::Vector3d p = points.row(i).transpose() - centroid;
    const double x = p.dot(u), z = p.dot(v);
    A.row(i) << x, z, 1.0;
    rhs[i] = x * x + z * z;
  }
  const Eigen::Vector3d fit = A.colPivHouseholderQr().solve(rhs);
  Circle3d circle;
  circle.centre = centroid + 0.5 * fit[0] * u + 0.5 * fit[1] * v;
  circle.radius = std::sqrt(fit[2] + 0.25 * (fit[0] * fit[0] + fit[1] * fit[1]));
  circle.normal = u.cross(v);
  return circle;
}

double Circle3d::distance(const Eigen::Vector3d& point) const noexcept {
  const Eigen::Vector3d p = point - centre;
  const Eigen::Vector3d in_plane = p - p.dot(normal) * normal;
  return std::hypot(p.dot(normal), in_plane.norm() - radius);
}

namespace {

/// The circle task's noisy joint-space ellipse: 20 s at 25 Hz around a nominal posture.
Eigen::MatrixXd ellipseDemonstration(std::uint32_t seed, double duration, double dt) {
  const int samples = static_cast<int>(duration / dt) + 1;
  Eigen::VectorXd q0(7), a(7), b(7);
  q0 << 0.0, 0.6, 0.0, 1.6, 0.0, 0.4, 0.0;
  a << 0.25, 0.0, 0.1, 0.15, 0.0, 0.1, 0.0;
  b << 0.0, 0.2, 0.0, -0.2, 0.1, 0.0, 0.0;
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0.0, 0.01);
  Eigen::MatrixXd demonstration(samples, 7);
  for (int i = 0; i < samples; ++i) {
    const double phase = 2.0 * M_PI * i / (samples - 1);
    for (int j = 0; j < 7; ++j) demonstration(i, j) = q0[j] + a[j] * std::sin(phase) + b[j] * (1.0 - std::cos(phase));
    if (i > 0 && i < samples - 1) {
      for (int j = 0; j < 7; ++j) demonstration(i, j) += noise(rng);
    }
  }
  return demonstration;
}

constexpr double kCircleDuration = 20.0, kCircleDt = 0.04;

}  // namespace

CircleTask::CircleTask(const kinematics::ChainModel& model, std::uint32_t seed)
    : CircleTask(model.nq() == 7 ? model : throw std::invalid_argument("CircleTask: needs a 7-joint chain"),
                 ellipseDemonstration(seed, kCircleDuration, kCircleDt)) {}

CircleTask::CircleTask(const kinematics::ChainModel& model, const Eigen::MatrixXd& demonstration)
    : model_(model), data_(model), policy_(DmpRollout::fit(demonstration, kCircleDt, 12)) {
  Eigen::MatrixXd tool(demonstration.rows(), 3);
  for (Eigen::Index i = 0; i < demonstration.rows(); ++i) {
    if (kinematics::forwardKinematics(model_, data_, demonstration.row(i).transpose()) !=
        kinematics::KinematicsStatus::Success) {
      throw std::invalid_argument("CircleTask: forward kinematics failed on the demonstration");
    }
    tool.row(i) = data_.tipPose().translation().transpose();
  }
  circle_ = Circle3d::fit(tool);
}

double CircleTask::reward(const Eigen::VectorXd& theta) {
  policy_.rollout(theta, y_, ydd_);
  double distance = 0.0;
  for (Eigen::Index i = 0; i < y_.rows(); ++i) {
    if (kinematics::forwardKinematics(model_, data_, y_.row(i).transpose()) != kinematics::KinematicsStatus::Success) {
      return -1e9;
    }
    distance += circle_.distance(data_.tipPose().translation());
  }
  return -(1000.0 * distance / static_cast<double>(y_.rows()) +
           1e-3 * ydd_.squaredNorm() / static_cast<double>(y_.rows()));
}

namespace {

DmpRollout viaPointPolicy() {
  const int samples = 101;
  Eigen::MatrixXd demonstration(samples, 1);
  for (int i = 0; i < samples; ++i) demonstration(i, 0) = minimumJerk(static_cast<double>(i) / (samples - 1));
  return DmpRollout::fit(demonstration, 0.01, 10);
}

}  // namespace

ViaPointTask::ViaPointTask()
    : policy_(viaPointPolicy()),
      basis_(policy_.stepBasis()),
      via_step_(static_cast<int>(std::lround(kViaTime / policy_.dt))) {}

Eigen::VectorXd ViaPointTask::stepCosts(const Eigen::VectorXd& theta, double* via_error) {
  policy_.rollout(theta, y_, ydd_);
  if (via_error != nullptr) *via_error = std::abs(y_(via_step_, 0) - kViaPosition);
  Eigen::VectorXd c = 1e-6 * ydd_.col(0).tail(policy_.steps).array().square().matrix();
  c[via_step_ - 1] += 1e4 * std::pow(y_(via_step_, 0) - kViaPosition, 2);
  return c;
}

double ViaPointTask::viaPointError(const Eigen::VectorXd& theta) {
  policy_.rollout(theta, y_, ydd_);
  return std::abs(y_(via_step_, 0) - kViaPosition);
}

}  // namespace bimanual_skills::tasks

#include "bimanual_skills/tasks/nao_walking.hpp"

#include "bimanual_skills/control/zmp_preview.hpp"
#include "bimanual_skills/kinematics/pose_error.hpp"

#include <Eigen/Cholesky>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <stdexcept>

namespace bimanual_skills::tasks {

namespace {

void require(bool ok, const std::string& what) {
  if (!ok) throw std::invalid_argument("NAO walk: " + what);
}

bool within(double value, double lo, double hi) {
  return std::isfinite(value) && value >= lo && value <= hi;
}

/// A sole's place: x, y on the ground and its heading.
struct Foothold {
  double x = 0.0, y = 0.0, heading = 0.0;
};

/// One swing of a foot: from → to during [start, end).
struct Swing {
  double start = 0.0, end = 0.0;
  Foothold from, to;
};

Foothold placed(double cx, double cy, double heading, double side_offset) {
  return {cx - std::sin(heading) * side_offset, cy + std::cos(heading) * side_offset, heading};
}

/// Smooth 0 → 1 with zero slope at both ends.
double ease(double s) {
  return 0.5 * (1.0 - std::cos(M_PI * std::clamp(s, 0.0, 1.0)));
}

/// A foot at time t: x, y, z, heading.
Eigen::Vector4d footAt(const Foothold& initial, const std::vector<Swing>& swings, double lift, double t) {
  Foothold where = initial;
  for (const Swing& s : swings) {
    if (t >= s.end) {
      where = s.to;
      continue;
    }
    if (t >= s.start) {
      const double phase = (t - s.start) / (s.end - s.start), k = ease(phase);
      return {s.from.x + k * (s.to.x - s.from.x), s.from.y + k * (s.to.y - s.from.y),
              lift * 0.5 * (1.0 - std::cos(2.0 * M_PI * phase)), s.from.heading + k * (s.to.heading - s.from.heading)};
    }
    break;
  }
  return {where.x, where.y, 0.0, where.heading};
}

Eigen::Isometry3d pose(double x, double y, double z, double heading) {
  Eigen::Isometry3d out = Eigen::Isometry3d::Identity();
  out.translation() = Eigen::Vector3d(x, y, z);
  out.linear() = Eigen::AngleAxisd(heading, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  return out;
}

}  // namespace

void NaoWalkParameters::validate() const {
  require(within(step_length, 0.0, 0.1), "step_length must lie in [0, 0.1] m");
  require(within(step_period, 0.1, 5.0), "step_period must lie in [0.1, 5] s");
  require(within(double_support, 0.05, 0.9), "double_support must lie in [0.05, 0.9]");
  require(within(foot_lift, 0.0, 0.1), "foot_lift must lie in [0, 0.1] m");
  require(within(torso_height, 0.1, 0.4), "torso_height must lie in [0.1, 0.4] m");
  require(within(foot_separation, 0.05, 0.3), "foot_separation must lie in [0.05, 0.3] m");
  require(within(turn, -0.5, 0.5), "turn must lie in [-0.5, 0.5] rad per step");
  require(steps >= 2 && steps <= 1000, "steps must lie in [2, 1000]");
  require(within(period, 1e-4, 0.05), "period must lie in [0.0001, 0.05] s");
  require(step_period * double_support >= 2.0 * period && step_period * (1.0 - double_support) >= 4.0 * period,
          "a step's double and single support must each span a few periods");
  require(within(rest, 0.0, 60.0), "rest must lie in [0, 60] s");
  require(within(preview, period, 10.0), "preview must lie in [period, 10] s");
}

NaoLegs NaoLegs::fromUrdfFile(const std::string& path) {
  NaoLegs legs{kinematics::ChainModel::fromUrdfFile(path, "torso", "l_sole"),
               kinematics::ChainModel::fromUrdfFile(path, "torso", "r_sole")};
  if (legs.left.nq() != 6 || legs.right.nq() != 6) {
    throw std::invalid_argument("NAO legs: " + path + " has no six joints from torso to each sole");
  }
  return legs;
}

std::vector<std::string> naoLegJointNames() {
  std::vector<std::string> names;
  for (const char* side : {"L", "R"}) {
    for (const char* joint : {"HipYawPitch", "HipRoll", "HipPitch", "KneePitch", "AnklePitch", "AnkleRoll"}) {
      names.push_back(std::string(side) + joint);
    }
  }
  return names;
}

std::string solveNaoLeg(const kinematics::ChainModel& leg, kinematics::ChainData& data, const Eigen::Isometry3d& target,
                        bool fixed_first, Eigen::Ref<Eigen::VectorXd> q) {
  // Rows: the sole's position [m] and its rotation vector, weighed 0.1 m per rad; the heading (z) row left out
  // when HipYawPitch is fixed.
  Eigen::Matrix<double, 6, 1> weight;
  weight << 1.0, 1.0, 1.0, 0.1, 0.1, fixed_first ? 0.0 : 0.1;
  Eigen::VectorXd e(6);
  double residual = 0.0;
  for (int iteration = 0; iteration < 200; ++iteration) {
    if (kinematics::computeJacobian(leg, data, q) != kinematics::KinematicsStatus::Success) {
      return "the joints are not finite";
    }
    kinematics::poseError(data.tipPose(), target, kinematics::TaskMode::Pose, e);
    const Eigen::Matrix<double, 6, 1> we = weight.cwiseProduct(e);
    residual = we.norm();
    if (residual < 1e-11) {
      for (int j = 0; j < 6; ++j) {
        if (q[j] < leg.lowerLimits()[j] - 1e-9 || q[j] > leg.upperLimits()[j] + 1e-9) {
          char said[160];
          std::snprintf(said, sizeof said, "%s at %.3f rad is out of its limits [%.3f, %.3f]",
                        leg.joints()[static_cast<std::size_t>(j)].name.c_str(), q[j], leg.lowerLimits()[j],
                        leg.upperLimits()[j]);
          return said;
        }
      }
      return "";
    }
    Eigen::Matrix<double, 6, 6> wj = weight.asDiagonal() * data.jacobian;
    if (fixed_first) wj.col(0).setZero();
    Eigen::Matrix<double, 6, 6> normal = wj.transpose() * wj;
    normal.diagonal().array() += 1e-10;
    if (fixed_first) normal(0, 0) = 1.0;
    Eigen::Matrix<double, 6, 1> dq = normal.ldlt().solve(wj.transpose() * we);
    const double size = dq.cwiseAbs().maxCoeff();
    if (size > 0.3) dq *= 0.3 / size;
    q += dq;
  }
  char said[120];
  std::snprintf(said, sizeof said, "no joints reach the sole's pose (%.1f mm from it after 200 steps: out of reach?)",
                1e3 * residual);
  return said;
}

NaoWalk generateNaoWalk(const NaoLegs& legs, const NaoWalkParameters& parameters) {
  parameters.validate();
  const NaoWalkParameters& p = parameters;
  const int n = p.steps;
  const double half = 0.5 * p.foot_separation, ds = p.double_support * p.step_period;
  // Footholds: step j (1-based) moves the left foot when odd, the right when even.
  const Foothold left0 = placed(0.0, 0.0, 0.0, half), right0 = placed(0.0, 0.0, 0.0, -half);
  std::vector<Swing> left_swings, right_swings;
  std::vector<double> starts;
  Foothold left = left0, right = right0;
  std::vector<Eigen::Vector2d> stance;  // the stance foot's centre during step j (index j − 1)
  double cx = 0.0, cy = 0.0, heading = 0.0;
  for (int j = 1; j <= n; ++j) {
    const bool left_swings_now = j % 2 == 1;
    if (j < n) {
      heading += p.turn;
      cx += p.step_length * std::cos(heading);
      cy += p.step_length * std::sin(heading);
    }
    const double start = p.rest + (j - 1) * p.step_period;
    starts.push_back(start);
    Foothold& moving = left_swings_now ? left : right;
    const Foothold& standing = left_swings_now ? right : left;
    stance.emplace_back(standing.x, standing.y);
    const Foothold to = j < n ? placed(cx, cy, heading, left_swings_now ? half : -half)
                              : placed(standing.x + std::sin(standing.heading) * (left_swings_now ? -half : half),
                                       standing.y - std::cos(standing.heading) * (left_swings_now ? -half : half),
                                       standing.heading, left_swings_now ? half : -half);
    (left_swings_now ? left_swings : right_swings).push_back({start + ds, start + p.step_period, moving, to});
    moving = to;
  }
  const Eigen::Vector2d middle0(0.0, 0.0), middle_end(0.5 * (left.x + right.x), 0.5 * (left.y + right.y));
  const double end_of_steps = p.rest + n * p.step_period, duration = end_of_steps + ds + p.rest;
  const int samples = static_cast<int>(std::floor(duration / p.period + 1e-9)) + 1;
  const auto reference = [&](double t) -> Eigen::Vector2d {
    if (t < starts.front()) return middle0;
    if (t >= end_of_steps) {
      const double s = std::clamp((t - end_of_steps) / ds, 0.0, 1.0);
      return (1.0 - s) * stance.back() + s * middle_end;
    }
    const int j = std::min(n - 1, static_cast<int>((t - p.rest) / p.step_period));
    const double into = t - starts[static_cast<std::size_t>(j)];
    const Eigen::Vector2d& to = stance[static_cast<std::size_t>(j)];
    if (into >= ds) return to;
    const Eigen::Vector2d& from = j == 0 ? middle0 : stance[static_cast<std::size_t>(j - 1)];
    return from + (into / ds) * (to - from);
  };

  NaoWalk walk;
  walk.parameters = p;
  walk.step_starts = starts;
  walk.time.resize(samples);
  walk.joints.resize(samples, 12);
  walk.com.resize(samples, 2);
  walk.zmp.resize(samples, 2);
  walk.zmp_reference.resize(samples, 2);
  walk.left_foot.resize(samples, 4);
  walk.right_foot.resize(samples, 4);
  walk.torso.resize(samples, 4);
  control::ZmpPreviewParameters preview;
  preview.period = p.period;
  preview.com_height = p.torso_height;
  preview.preview_steps = std::max(1, static_cast<int>(std::lround(p.preview / p.period)));
  const control::ZmpPreviewController controller(preview);
  const int horizon = preview.preview_steps;
  Eigen::MatrixXd refs(samples + horizon, 2);
  for (int k = 0; k < samples + horizon; ++k) refs.row(k) = reference(std::min(k, samples - 1) * p.period).transpose();
  std::array<control::ZmpPreviewController::State, 2> axes;
  kinematics::ChainData left_data(legs.left), right_data(legs.right);
  Eigen::VectorXd q_left(6), q_right(6);
  q_left << 0.0, 0.0, -0.4, 0.8, -0.4, 0.0;
  q_right = q_left;
  for (int k = 0; k < samples; ++k) {
    const double t = k * p.period;
    walk.time[k] = t;
    walk.zmp_reference.row(k) = refs.row(k);
    for (int axis = 0; axis < 2; ++axis) {
      walk.com(k, axis) = axes[static_cast<std::size_t>(axis)].x[0];
      walk.zmp(k, axis) = controller.zmp(axes[static_cast<std::size_t>(axis)]);
      const Eigen::VectorXd window = refs.col(axis).segment(k, horizon + 1);
      if (controller.step(axes[static_cast<std::size_t>(axis)], window) != control::ZmpPreviewStatus::Success) {
        throw std::invalid_argument("NAO walk: the preview control failed at t = " + std::to_string(t) + " s");
      }
    }
    const Eigen::Vector4d lf = footAt(left0, left_swings, p.foot_lift, t),
                          rf = footAt(right0, right_swings, p.foot_lift, t);
    walk.left_foot.row(k) = lf.transpose();
    walk.right_foot.row(k) = rf.transpose();
    const double torso_heading = 0.5 * (lf[3] + rf[3]);
    walk.torso.row(k) << walk.com(k, 0), walk.com(k, 1), p.torso_height, torso_heading;
    const Eigen::Isometry3d torso_inverse =
        pose(walk.com(k, 0), walk.com(k, 1), p.torso_height, torso_heading).inverse();
    const Eigen::Isometry3d left_target = torso_inverse * pose(lf[0], lf[1], lf[2], lf[3]),
                            right_target = torso_inverse * pose(rf[0], rf[1], rf[2], rf[3]);
    char when[64];
    std::snprintf(when, sizeof when, " at t = %.2f s", t);
    if (const std::string why = solveNaoLeg(legs.left, left_data, left_target, false, q_left); !why.empty()) {
      throw std::invalid_argument("NAO walk: the left leg" + std::string(when) + ": " + why);
    }
    q_right[0] = q_left[0];  // one motor
    if (const std::string why = solveNaoLeg(legs.right, right_data, right_target, true, q_right); !why.empty()) {
      throw std::invalid_argument("NAO walk: the right leg" + std::string(when) + ": " + why);
    }
    const Eigen::Matrix3d off = right_data.tipPose().linear() * right_target.linear().transpose();
    walk.right_heading_error = std::max(walk.right_heading_error, std::abs(std::atan2(off(1, 0), off(0, 0))));
    walk.joints.row(k).head(6) = q_left.transpose();
    walk.joints.row(k).tail(6) = q_right.transpose();
  }
  return walk;
}

Eigen::MatrixXd naoStride(const NaoWalk& walk, int first, int samples) {
  const int n = static_cast<int>(walk.step_starts.size());
  if (samples < 2) throw std::invalid_argument("NAO stride: at least 2 samples");
  if (first < 1 || first + 1 > n) {
    throw std::invalid_argument("NAO stride: the walk has steps 1 to " + std::to_string(n) + ", no steps " +
                                std::to_string(first) + " and " + std::to_string(first + 1));
  }
  const double from = walk.step_starts[static_cast<std::size_t>(first - 1)],
               to = first + 1 < n ? walk.step_starts[static_cast<std::size_t>(first + 1)]
                                  : walk.step_starts.back() + walk.parameters.step_period;
  const double dt = walk.parameters.period;
  Eigen::MatrixXd out(samples, walk.joints.cols());
  for (int i = 0; i < samples; ++i) {
    const double t = from + (to - from) * i / (samples - 1), index = t / dt;
    const int k = std::clamp(static_cast<int>(std::floor(index)), 0, static_cast<int>(walk.time.size()) - 2);
    const double a = std::clamp(index - k, 0.0, 1.0);
    out.row(i) = (1.0 - a) * walk.joints.row(k) + a * walk.joints.row(k + 1);
  }
  return out;
}

}  // namespace bimanual_skills::tasks

#include "bimanual_skills/control/zmp_preview.hpp"

#include <cmath>
#include <stdexcept>
#include <string>

namespace bimanual_skills::control {

namespace {

void require(bool ok, const std::string& what) {
  if (!ok) throw std::invalid_argument("ZMP preview control: " + what);
}

}  // namespace

void ZmpPreviewParameters::validate() const {
  require(std::isfinite(period) && period > 0.0 && period <= 0.1, "period must lie in (0, 0.1] s");
  require(std::isfinite(com_height) && com_height > 0.0 && com_height <= 10.0, "com_height must lie in (0, 10] m");
  require(std::isfinite(gravity) && gravity > 0.0, "gravity must be positive");
  require(std::isfinite(tracking_weight) && tracking_weight > 0.0, "tracking_weight must be positive");
  require(std::isfinite(input_weight) && input_weight > 0.0, "input_weight must be positive");
  require(preview_steps >= 1 && preview_steps <= 100000, "preview_steps must lie in [1, 100000]");
}

const char* toString(ZmpPreviewStatus status) noexcept {
  switch (status) {
    case ZmpPreviewStatus::Success:
      return "success";
    case ZmpPreviewStatus::WrongSize:
      return "the reference does not hold N + 1 values";
    case ZmpPreviewStatus::NotFinite:
      return "a non-finite state or reference";
  }
  return "unknown";
}

ZmpPreviewController::ZmpPreviewController(const ZmpPreviewParameters& parameters) : parameters_(parameters) {
  parameters_.validate();
  const double t = parameters_.period;
  a_ << 1.0, t, 0.5 * t * t, 0.0, 1.0, t, 0.0, 0.0, 1.0;
  b_ << t * t * t / 6.0, 0.5 * t * t, t;
  c_ << 1.0, 0.0, -parameters_.com_height / parameters_.gravity;
  Eigen::Matrix4d at = Eigen::Matrix4d::Zero();
  at(0, 0) = 1.0;
  at.block<1, 3>(0, 1) = c_ * a_;
  at.block<3, 3>(1, 1) = a_;
  Eigen::Vector4d bt;
  bt << c_.dot(b_), b_;
  Eigen::Matrix4d q = Eigen::Matrix4d::Zero();
  q(0, 0) = parameters_.tracking_weight;
  const double r = parameters_.input_weight;
  // P = Ãᵀ P Ã − Ãᵀ P B̃ (R + B̃ᵀ P B̃)⁻¹ B̃ᵀ P Ã + Q̃, iterated from Q̃.
  Eigen::Matrix4d p = q;
  bool converged = false;
  for (int iteration = 0; iteration < 1000000; ++iteration) {
    const Eigen::Vector4d pb = p * bt;
    const Eigen::Matrix4d next =
        at.transpose() * p * at - (at.transpose() * pb) * (pb.transpose() * at) / (r + bt.dot(pb)) + q;
    const double change = (next - p).cwiseAbs().maxCoeff();
    p = 0.5 * (next + next.transpose());
    if (change <= 1e-12 * (1.0 + p.cwiseAbs().maxCoeff())) {
      converged = true;
      break;
    }
  }
  if (!converged || !p.allFinite()) throw std::runtime_error("ZMP preview control: the Riccati iteration diverged");
  p_ = p;
  const Eigen::Vector4d pb = p * bt;
  const double gamma = 1.0 / (r + bt.dot(pb));
  const Eigen::Vector4d unit = Eigen::Vector4d::UnitX();
  gain_integral_ = gamma * pb.dot(unit);
  Eigen::Matrix<double, 4, 3> f;
  f.row(0) = c_ * a_;
  f.block<3, 3>(1, 0) = a_;
  gain_state_ = gamma * pb.transpose() * f;
  const Eigen::Matrix4d closed = at - bt * (gamma * pb.transpose() * at);
  gain_preview_.resize(parameters_.preview_steps);
  gain_preview_[0] = -gain_integral_;
  Eigen::Vector4d x = -closed.transpose() * p * unit;
  for (int j = 1; j < parameters_.preview_steps; ++j) {
    gain_preview_[j] = gamma * bt.dot(x);
    x = closed.transpose() * x;
  }
}

ZmpPreviewStatus ZmpPreviewController::step(State& state,
                                            const Eigen::Ref<const Eigen::VectorXd>& reference) const noexcept {
  const Eigen::Index n = gain_preview_.size();
  if (reference.size() != n + 1) return ZmpPreviewStatus::WrongSize;
  if (!state.x.allFinite() || !std::isfinite(state.error_sum) || !reference.allFinite()) {
    return ZmpPreviewStatus::NotFinite;
  }
  const double error_sum = state.error_sum + c_.dot(state.x) - reference[0];
  const double u = -gain_integral_ * error_sum - gain_state_.dot(state.x) - gain_preview_.dot(reference.tail(n));
  state.x = a_ * state.x + b_ * u;
  state.error_sum = error_sum;
  return ZmpPreviewStatus::Success;
}

}  // namespace bimanual_skills::control

#include "bimanual_skills/learning/time_alignment.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace bimanual_skills::learning {

namespace {

[[noreturn]] void fail(const std::string& what) {
  throw std::invalid_argument("time alignment: " + what);
}

void checkCurve(const Eigen::MatrixXd& curve, const char* name) {
  if (curve.rows() < 2 || curve.cols() < 1) {
    fail(std::string(name) + " needs at least two samples of one dimension, not " + std::to_string(curve.rows()) +
         " x " + std::to_string(curve.cols()));
  }
  if (!curve.allFinite()) fail(std::string(name) + " has a non-finite sample");
}

double phase(int i, int samples) {
  return static_cast<double>(i) / (samples - 1);
}

/// The row index below phase u and the fraction beyond it.
void locate(const Eigen::MatrixXd& curve, double u, Eigen::Index& j, double& f) {
  const double x = std::clamp(u, 0.0, 1.0) * static_cast<double>(curve.rows() - 1);
  j = std::min<Eigen::Index>(static_cast<Eigen::Index>(x), curve.rows() - 2);
  f = x - static_cast<double>(j);
}

/// C(a) and, when gradient is given, ∂C/∂a.
double costAndGradient(const Eigen::MatrixXd& curve, const Eigen::MatrixXd& reference, const TimeWarp& warp,
                       int samples, Eigen::VectorXd* gradient) {
  double cost = 0.0;
  if (gradient != nullptr) gradient->setZero(warp.a.size());
  const double scale = static_cast<double>(curve.rows() - 1);
  for (int i = 0; i < samples; ++i) {
    const double s = phase(i, samples);
    Eigen::Index j = 0;
    double f = 0.0;
    locate(curve, warp(s), j, f);
    const Eigen::RowVectorXd c = (1.0 - f) * curve.row(j) + f * curve.row(j + 1);
    const Eigen::RowVectorXd e = c - samplePhase(reference, s);
    cost += e.squaredNorm();
    if (gradient != nullptr) {
      const double along = e.dot((curve.row(j + 1) - curve.row(j)) * scale);
      for (Eigen::Index k = 0; k < warp.a.size(); ++k) {
        (*gradient)[k] += 2.0 * along * std::sin(static_cast<double>(k + 1) * M_PI * s);
      }
    }
  }
  if (gradient != nullptr) *gradient /= samples;
  return cost / samples;
}

}  // namespace

double TimeWarp::operator()(double s) const noexcept {
  double u = s;
  for (Eigen::Index k = 0; k < a.size(); ++k) u += a[k] * std::sin(static_cast<double>(k + 1) * M_PI * s);
  return u;
}

double TimeWarp::slope(double s) const noexcept {
  double d = 1.0;
  for (Eigen::Index k = 0; k < a.size(); ++k) {
    const double w = static_cast<double>(k + 1) * M_PI;
    d += a[k] * w * std::cos(w * s);
  }
  return d;
}

double TimeWarp::minSlope(int samples) const noexcept {
  double least = slope(0.0);
  for (int i = 1; i < samples; ++i) least = std::min(least, slope(phase(i, samples)));
  return least;
}

Eigen::RowVectorXd samplePhase(const Eigen::MatrixXd& curve, double u) {
  if (curve.rows() < 2) fail("a curve needs at least two samples");
  Eigen::Index j = 0;
  double f = 0.0;
  locate(curve, u, j, f);
  return (1.0 - f) * curve.row(j) + f * curve.row(j + 1);
}

Eigen::MatrixXd warpCurve(const Eigen::MatrixXd& curve, const TimeWarp& warp, int samples) {
  if (curve.rows() < 2 || samples < 2) fail("warpCurve needs at least two samples in and out");
  Eigen::MatrixXd out(samples, curve.cols());
  for (int i = 0; i < samples; ++i) out.row(i) = samplePhase(curve, warp(phase(i, samples)));
  return out;
}

void TimeAlignmentOptions::validate() const {
  if (harmonics < 1 || harmonics > 64) fail("harmonics " + std::to_string(harmonics) + " is not in [1, 64]");
  if (samples < 2 || samples > 100000) fail("samples " + std::to_string(samples) + " is not in [2, 100000]");
  if (iterations < 0 || iterations > 1000000) fail("iterations " + std::to_string(iterations) + " is not in [0, 1e6]");
  if (passes < 1 || passes > 1000) fail("passes " + std::to_string(passes) + " is not in [1, 1000]");
  if (!(min_slope > 0.0 && min_slope <= 1.0)) fail("min_slope " + std::to_string(min_slope) + " is not in (0, 1]");
  if (!(tolerance >= 0.0 && tolerance < 1.0)) fail("tolerance " + std::to_string(tolerance) + " is not in [0, 1)");
}

namespace {

void checkPair(const Eigen::MatrixXd& curve, const Eigen::MatrixXd& reference, int samples) {
  checkCurve(curve, "the curve");
  checkCurve(reference, "the reference");
  if (curve.cols() != reference.cols()) {
    fail("the curve has " + std::to_string(curve.cols()) + " dimensions, the reference " +
         std::to_string(reference.cols()));
  }
  if (samples < 2) fail("at least two phases are compared");
}

}  // namespace

double alignmentCost(const Eigen::MatrixXd& curve, const Eigen::MatrixXd& reference, const TimeWarp& warp,
                     int samples) {
  checkPair(curve, reference, samples);
  return costAndGradient(curve, reference, warp, samples, nullptr);
}

Eigen::VectorXd alignmentGradient(const Eigen::MatrixXd& curve, const Eigen::MatrixXd& reference, const TimeWarp& warp,
                                  int samples) {
  checkPair(curve, reference, samples);
  Eigen::VectorXd gradient;
  costAndGradient(curve, reference, warp, samples, &gradient);
  return gradient;
}

TimeWarp alignToReference(const Eigen::MatrixXd& curve, const Eigen::MatrixXd& reference,
                          const TimeAlignmentOptions& options, const TimeWarp& initial) {
  options.validate();
  TimeWarp warp;
  warp.a = Eigen::VectorXd::Zero(options.harmonics);
  if (initial.a.size() > 0) {
    if (initial.a.size() != options.harmonics || !initial.a.allFinite()) {
      fail("the initial warp needs " + std::to_string(options.harmonics) + " finite coefficients");
    }
    warp.a = initial.a;
  }
  if (warp.minSlope() < options.min_slope) fail("the initial warp is flatter than min_slope");
  double cost = alignmentCost(curve, reference, warp, options.samples);
  Eigen::VectorXd gradient;
  double step = 1.0;
  for (int it = 0; it < options.iterations; ++it) {
    costAndGradient(curve, reference, warp, options.samples, &gradient);
    const double g2 = gradient.squaredNorm();
    if (!(g2 > 0.0)) break;
    step *= 2.0;
    bool moved = false;
    for (int halving = 0; halving < 60; ++halving, step *= 0.5) {
      TimeWarp trial{warp.a - step * gradient};
      if (trial.minSlope() < options.min_slope) continue;
      const double c = costAndGradient(curve, reference, trial, options.samples, nullptr);
      if (c <= cost - 1e-4 * step * g2) {  // Armijo
        moved = cost - c > options.tolerance * std::max(cost, 1e-300);
        warp = trial;
        cost = c;
        break;
      }
    }
    if (!moved) break;
  }
  return warp;
}

TimeAlignment alignCurves(const std::vector<Eigen::MatrixXd>& curves, const TimeAlignmentOptions& options) {
  options.validate();
  if (curves.empty()) fail("no curves to align");
  for (const Eigen::MatrixXd& c : curves) {
    checkCurve(c, "a curve");
    if (c.cols() != curves.front().cols()) fail("the curves have different dimensions");
  }
  const int n = options.samples;
  const std::size_t count = curves.size();
  TimeAlignment result;
  result.warps.assign(count, TimeWarp{Eigen::VectorXd::Zero(options.harmonics)});
  result.aligned.resize(count);
  auto takeMean = [&] {
    result.mean.setZero(n, curves.front().cols());
    for (std::size_t k = 0; k < count; ++k) {
      result.aligned[k] = warpCurve(curves[k], result.warps[k], n);
      result.mean += result.aligned[k];
    }
    result.mean /= static_cast<double>(count);
  };
  auto spread = [&] {
    double c = 0.0;
    for (const Eigen::MatrixXd& a : result.aligned) c += (a - result.mean).squaredNorm() / n;
    return c / static_cast<double>(count);
  };
  takeMean();
  result.cost_before = spread();
  for (int pass = 0; pass < options.passes; ++pass) {
    for (std::size_t k = 0; k < count; ++k) {
      result.warps[k] = alignToReference(curves[k], result.mean, options, result.warps[k]);
    }
    Eigen::VectorXd average = Eigen::VectorXd::Zero(options.harmonics);
    for (const TimeWarp& w : result.warps) average += w.a;
    average /= static_cast<double>(count);
    for (TimeWarp& w : result.warps) {
      const TimeWarp centred{w.a - average};
      if (centred.minSlope() >= options.min_slope) w = centred;
    }
    takeMean();
  }
  result.cost_after = spread();
  return result;
}

Eigen::VectorXd rewardWeights(const Eigen::VectorXd& rewards, double h) {
  if (rewards.size() == 0) fail("no rewards to weight");
  if (!rewards.allFinite()) fail("a reward is not finite");
  if (!(h >= 0.0) || !std::isfinite(h)) fail("the weights' h must be finite and >= 0");
  const double high = rewards.maxCoeff(), range = high - rewards.minCoeff();
  if (!(range > 0.0)) return Eigen::VectorXd::Constant(rewards.size(), 1.0 / static_cast<double>(rewards.size()));
  const Eigen::VectorXd w = (h * (rewards.array() - high) / range).exp();
  return w / w.sum();
}

}  // namespace bimanual_skills::learning

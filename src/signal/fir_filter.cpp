#include "bimanual_skills/signal/fir_filter.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace bimanual_skills::signal {

Eigen::VectorXd designLowPassFir(int taps, double cutoff_hz, double rate_hz) {
  if (taps < 3 || taps % 2 == 0) throw std::invalid_argument("designLowPassFir: taps must be odd and >= 3");
  if (!(rate_hz > 0.0) || !(cutoff_hz > 0.0) || !(cutoff_hz < 0.5 * rate_hz)) {
    throw std::invalid_argument("designLowPassFir: need 0 < cutoff < rate / 2");
  }
  const double fc = cutoff_hz / rate_hz;  // cycles per sample
  const double centre = 0.5 * (taps - 1);
  Eigen::VectorXd h(taps);
  for (int k = 0; k < taps; ++k) {
    const double x = k - centre;
    const double sinc = x == 0.0 ? 2.0 * fc : std::sin(2.0 * M_PI * fc * x) / (M_PI * x);
    const double w = 0.42 - 0.5 * std::cos(2.0 * M_PI * k / (taps - 1)) + 0.08 * std::cos(4.0 * M_PI * k / (taps - 1));
    h[k] = sinc * w;
  }
  return h / h.sum();
}

Eigen::MatrixXd zeroPhaseLowPass(const Eigen::MatrixXd& data, double dt, double cutoff_hz) {
  const double rate = 1.0 / dt;
  if (cutoff_hz <= 0.0 || cutoff_hz >= 0.5 * rate) return data;
  int taps = static_cast<int>(std::ceil(4.0 * rate / cutoff_hz)) | 1;  // transition width ≈ 4 f_s / N (Blackman)
  taps = std::min(taps, 2 * static_cast<int>(data.rows()) - 1) | 1;
  if (taps < 3) return data;
  const Eigen::VectorXd h = designLowPassFir(taps, cutoff_hz, rate);
  const int half = taps / 2;
  const auto n = static_cast<int>(data.rows());
  Eigen::MatrixXd out(data.rows(), data.cols());
  for (int r = 0; r < n; ++r) {
    out.row(r).setZero();
    for (int k = 0; k < taps; ++k) {
      const int source = std::clamp(r + k - half, 0, n - 1);
      out.row(r) += h[k] * data.row(source);
    }
  }
  return out;
}

FirFilter::FirFilter(const Eigen::VectorXd& coefficients, int channels)
    : coefficients_(coefficients),
      history_(Eigen::MatrixXd::Zero(std::max(channels, 1), coefficients.size())),
      output_(Eigen::VectorXd::Zero(std::max(channels, 1))) {
  if (channels < 1 || coefficients.size() < 1 || !coefficients.allFinite()) {
    throw std::invalid_argument("FirFilter: need channels >= 1 and finite coefficients");
  }
}

SignalStatus FirFilter::filter(const Eigen::Ref<const Eigen::VectorXd>& sample) noexcept {
  if (sample.size() != output_.size()) return SignalStatus::WrongSize;
  if (!sample.allFinite()) return SignalStatus::NotFinite;
  const auto taps = static_cast<int>(coefficients_.size());
  if (!primed_) {
    history_.colwise() = sample;
    primed_ = true;
  }
  history_.col(head_) = sample;
  // y[n] = Σ_k h[k] x[n − k]: column head_ holds x[n], head_ − 1 holds x[n − 1], ...
  output_.setZero();
  for (int k = 0; k < taps; ++k) {
    const int column = (head_ - k + taps) % taps;
    output_ += coefficients_[k] * history_.col(column);
  }
  head_ = (head_ + 1) % taps;
  return SignalStatus::Success;
}

void FirFilter::reset() noexcept {
  history_.setZero();
  output_.setZero();
  head_ = 0;
  primed_ = false;
}

}  // namespace bimanual_skills::signal

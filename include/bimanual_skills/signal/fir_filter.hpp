/// \file
/// Linear-phase FIR low-pass filter for joint velocities: windowed-sinc design at init, allocation-free filtering.
#pragma once

#include "bimanual_skills/signal/signal_status.hpp"

#include <Eigen/Core>

namespace bimanual_skills::signal {

/// Coefficients of a linear-phase low-pass FIR of `taps` taps (odd, ≥ 3) with cut-off `cutoff_hz` at sample rate
/// `rate_hz`: h[k] = w[k] · 2 f_c/f_s · sinc(2 f_c/f_s (k − (N−1)/2)), w a Blackman window, scaled to unit gain at
/// 0 Hz. Symmetric, so its delay is (N − 1)/2 samples at every frequency. Blackman: stop-band rejection ≈ 74 dB
/// beyond about f_c + 5.5 f_s / N.
/// \throws std::invalid_argument for even or too few taps, or a cut-off not in (0, rate/2).
Eigen::VectorXd designLowPassFir(int taps, double cutoff_hz, double rate_hz);

/// Offline zero-phase low-pass of every column of `data` (rows = samples every dt [s]): the FIR of designLowPassFir
/// with about 4 f_s / f_c taps (at most 2 · rows − 1) applied with its delay removed, the ends padded with the end
/// values. Returns `data` unchanged for cutoff_hz ≤ 0, at or above f_s / 2, or too few samples. Allocates.
Eigen::MatrixXd zeroPhaseLowPass(const Eigen::MatrixXd& data, double dt, double cutoff_hz);

/// Filters n channels with the same FIR, one sample vector per call (ring buffer sized at construction).
class FirFilter {
 public:
  FirFilter(const Eigen::VectorXd& coefficients, int channels);

  /// Pushes one sample of every channel and writes the filtered vector into output(). Before the buffer is full,
  /// the first sample fills the history (a step, not a ramp from zero). Real-time safe: no allocation, no
  /// exceptions; a wrongly sized or non-finite sample is rejected (WrongSize, NotFinite) and changes nothing.
  [[nodiscard]] SignalStatus filter(const Eigen::Ref<const Eigen::VectorXd>& sample) noexcept;
  const Eigen::VectorXd& output() const noexcept { return output_; }
  /// Number of taps N.
  int length() const noexcept { return static_cast<int>(coefficients_.size()); }
  /// Group delay in samples, (N − 1) / 2.
  double delay() const noexcept { return 0.5 * static_cast<double>(coefficients_.size() - 1); }
  void reset() noexcept;

 private:
  Eigen::VectorXd coefficients_;
  Eigen::MatrixXd history_;  ///< channels × taps ring buffer
  Eigen::VectorXd output_;
  int head_ = 0;
  bool primed_ = false;
};

}  // namespace bimanual_skills::signal

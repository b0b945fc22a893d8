/// \file
/// Dynamic movement primitives (thesis eqs. 5.14–5.15), multi-DoF with a shared phase.
#pragma once

#include <Eigen/Core>

namespace bimanual_skills::primitives {

/// Most kernels per DoF: the real-time steps keep the basis values on the stack.
inline constexpr int kDmpMaxKernels = 256;

/// Result of Dmp::step() and CartesianDmp::step().
enum class DmpStatus {
  Success,
  VectorClamped,  ///< CartesianDmp with QuaternionVector: ‖v‖ > 1 was clamped to 1 in this step (step done).
  /// Wrong sizes, non-finite values, a non-unit quaternion, dt ≤ 0 or a dt too long for a stable step
  /// (DmpParameters::stableStep): the state is unchanged.
  InvalidInput,
};
const char* toString(DmpStatus status) noexcept;

/// Shape of a DMP. With τ the movement's duration [s] (the thesis' (5.14), written with one consistent τ):
///   τ² ÿ = α_z (β_z (g − y) − τ ẏ) + f(x),   τ ẋ = −α_x x,   f_j(x) = g(x)ᵀ ω_j (5.15),
///   g_i(x) = φ_i(x) / Σ_k φ_k(x) · x,  φ_i(x) = exp(−½ (x − c_i)² / d_i),
/// the centres c_i uniform in time (x = exp(−α_x t/τ)) and widths d_i from the spacing. With goal_scaled_forcing,
/// g_i(x) is also multiplied by (g_j − y0_j) per DoF (footnote 3), so a new goal rescales the whole movement.
struct DmpParameters {
  int kernels = 25;
  double alpha_z = 25.0;
  double beta_z = 6.25;  ///< α_z / 4: critically damped
  double alpha_x = 4.0;  ///< x(τ) = e^{−4} ≈ 0.018
  bool goal_scaled_forcing = false;
  double regularisation = 1e-8;  ///< Ridge term of the least-squares fit.

  void validate() const;
  /// Whether the steps' semi-implicit Euler of the transformation system is stable for a step dt and a duration τ:
  /// in the error e = y − g and h ė the step is linear, [[1 − k, 1 − c], [−k, 1 − c]] with c = α_z dt/τ and
  /// k = α_z β_z dt²/τ², and its eigenvalues lie inside the unit circle iff 0 < c < 2 and 2c + k < 4 (Jury's test).
  /// A longer step makes every error grow without bound. For β_z = α_z/4: dt < 0.828 · 2τ/α_z.
  bool stableStep(double dt, double tau) const noexcept;
};

/// The transformation system of (5.14) solved for the acceleration, the one home of the DMP dynamics (joint and
/// Cartesian): ÿ = (α_z (β_z e − τ ẏ) + f) / τ², e = g − y the error to the goal. T is double or a fixed-size
/// Eigen vector (no allocation); a dynamic vector allocates its result.
template <class T>
T transformationAcceleration(const DmpParameters& p, double tau, const T& error, const T& velocity, const T& forcing) {
  return (p.alpha_z * (p.beta_z * error - tau * velocity) + forcing) / (tau * tau);
}

/// The forcing value that makes the transformation system follow a demonstration (the target of the weights' fit):
/// f = τ² ÿ − α_z (β_z e − τ ẏ).
template <class T>
T forcingTarget(const DmpParameters& p, double tau, const T& error, const T& velocity, const T& acceleration) {
  return tau * tau * acceleration - p.alpha_z * (p.beta_z * error - tau * velocity);
}

/// The DMP's state while it runs (the "Data" of the model): position, velocity, phase, time, and the goal in use.
struct DmpState {
  Eigen::VectorXd y, yd, ydd;
  Eigen::VectorXd goal;
  double x = 1.0;
  double t = 0.0;
};

/// Immutable DMP: weights, kernels, start, goal and duration. Build with fit() or from weights.
class Dmp {
 public:
  /// \throws std::invalid_argument for inconsistent sizes, non-finite values or τ ≤ 0.
  Dmp(const DmpParameters& parameters, const Eigen::MatrixXd& weights, const Eigen::VectorXd& start,
      const Eigen::VectorXd& goal, double duration);

  /// Least-squares fit to a demonstration sampled every dt (rows = samples, columns = DoF): positions are smoothed
  /// by a zero-phase low-pass FIR (cut-off `smoothing_hz`, 0 = none) before velocities and accelerations are taken by
  /// central differences; the forcing term f = τ² ÿ − α_z (β_z (g − y) − τ ẏ) is then regressed on g(x).
  /// \throws std::invalid_argument for fewer than 10 samples, dt ≤ 0 or non-finite data.
  static Dmp fit(const DmpParameters& parameters, const Eigen::MatrixXd& positions, double dt,
                 double smoothing_hz = 20.0);

  /// The forcing values f = τ² ÿ − α_z (β_z (g − y) − τ ẏ) that make the transformation system (5.14) follow a
  /// demonstration (rows = samples every dt, columns = DoF; τ its duration, g its last sample), from positions
  /// smoothed as in fit() and central differences (zero velocity and acceleration at the end samples). Not
  /// goal-scaled. What fit() regresses on the basis, and the demonstrated excitation of the DR-DMP (7.26).
  /// \throws std::invalid_argument as fit().
  static Eigen::MatrixXd demonstratedForcing(const DmpParameters& parameters, const Eigen::MatrixXd& positions,
                                             double dt, double smoothing_hz = 20.0);

  /// Ridge least-squares weights W (dofs × kernels) of forcing values sampled every dt from the movement's start
  /// (rows = samples, columns = DoF): minimises Σ_k ‖f_k − W g(x_k)‖² + λ ‖W‖², x_k = exp(−α_x k dt / τ), with
  /// this DMP's kernels (5.15) and duration τ. Used by fit() and by other DMPs that build their own forcing term.
  /// \throws std::invalid_argument for a wrong number of columns, non-finite values or dt ≤ 0.
  Eigen::MatrixXd fitWeights(const Eigen::MatrixXd& forcing, double dt) const;

  int dofs() const noexcept { return static_cast<int>(start_.size()); }
  const DmpParameters& parameters() const noexcept { return parameters_; }
  const Eigen::MatrixXd& weights() const noexcept { return weights_; }  ///< dofs × kernels (ω as rows per DoF)
  const Eigen::VectorXd& start() const noexcept { return start_; }
  const Eigen::VectorXd& goal() const noexcept { return goal_; }
  double duration() const noexcept { return duration_; }

  /// A copy with another duration (time scaling) or other weights (as a policy-search sample).
  Dmp withDuration(double duration) const;
  Dmp withWeights(const Eigen::MatrixXd& weights) const;

  /// A state at the start: y = start, ẏ = 0, x = 1, goal = the model's goal (change it at any time).
  DmpState initialState() const;

  /// Basis values g(x) (kernels, normalisedGaussianBasis with scale x), written into `basis`. Real-time safe.
  void basis(double x, Eigen::Ref<Eigen::VectorXd> basis) const noexcept;

  /// One integration step of dt (semi-implicit Euler on y, exact on the phase). InvalidInput (state unchanged) for
  /// a state of the wrong size, non-finite values, dt ≤ 0 or a dt the step is unstable for
  /// (DmpParameters::stableStep with the duration). Real-time safe: no allocation, no exceptions.
  [[nodiscard]] DmpStatus step(DmpState& state, double dt) const noexcept;

  /// The same step with the forcing term f (dofs values) given by the caller instead of the weights' g(x)ᵀ ω_j
  /// (DMPs that build their forcing term otherwise, such as the coordinated DR-DMP, 7.24); used as given, also with
  /// goal_scaled_forcing. InvalidInput (state unchanged) as step(), or for a forcing of the wrong size or not finite.
  /// Real-time safe: no allocation, no exceptions.
  [[nodiscard]] DmpStatus step(DmpState& state, double dt,
                               const Eigen::Ref<const Eigen::VectorXd>& forcing) const noexcept;

 private:
  /// Whether a state and dt can be stepped: sizes, finiteness, dt > 0 and a stable step.
  bool steppable(const DmpState& state, double dt) const noexcept;
  /// Integrates ẏ and y over dt from the acceleration already in state.ydd, and advances the phase and time.
  void advance(DmpState& state, double dt) const noexcept;

  DmpParameters parameters_;
  Eigen::MatrixXd weights_;
  Eigen::VectorXd start_, goal_, centres_, widths_;
  double duration_;
};

}  // namespace bimanual_skills::primitives

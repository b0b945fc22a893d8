/// \file
/// ZMP preview control of the cart-table model (Kajita et al. 2003, "Biped walking pattern generation by using
/// preview control of zero-moment point", ICRA; the servo with integral action of Katayama et al. 1985): the centre
/// of mass c at a constant height z_c moves by its jerk u, x = [c, ċ, c̈]ᵀ,
///   x_{k+1} = A x_k + B u_k,   A = [1 T T²/2; 0 1 T; 0 0 1],   B = [T³/6; T²/2; T],
///   p_k = C x_k,   C = [1  0  −z_c/g]   (the table's zero-moment point),
/// and u minimises Σ Q_e e_k² + R Δu_k² with e_k = p_k − p_ref,k, knowing p_ref N steps ahead:
///   u_k = −G_i Σ_{i≤k} e_i − G_x x_k − Σ_{j=1}^{N} G_d(j) p_ref,k+j.
/// The gains come from the Riccati equation of the incremental system ([e; Δx], Δu): Ã = [1 CA; 0 A], B̃ = [CB; B],
/// Q̃ = diag(Q_e, 0, 0, 0); with P its solution and Γ = (R + B̃ᵀPB̃)⁻¹, G_i = Γ B̃ᵀ P Ĩ (Ĩ = [1 0 0 0]ᵀ),
/// G_x = Γ B̃ᵀ P [CA; A], A_c = Ã − B̃ Γ B̃ᵀ P Ã, G_d(1) = −G_i, X_1 = −A_cᵀ P Ĩ, G_d(j) = Γ B̃ᵀ X_{j−1},
/// X_j = A_cᵀ X_{j−1}. One controller serves each horizontal axis (x and y are decoupled). Construction allocates and
/// throws; step() is real-time safe.
#pragma once

#include <Eigen/Core>

namespace bimanual_skills::control {

struct ZmpPreviewParameters {
  double period = 0.01;          ///< T [s].
  double com_height = 0.26;      ///< z_c [m].
  double gravity = 9.81;         ///< g [m/s²].
  double tracking_weight = 1.0;  ///< Q_e.
  double input_weight = 1e-6;    ///< R (Kajita's 10⁻⁶ with Q_e = 1).
  int preview_steps = 160;       ///< N (1.6 s at 10 ms, Kajita's horizon).

  /// \throws std::invalid_argument naming the first value out of range.
  void validate() const;
};

enum class ZmpPreviewStatus { Success, WrongSize, NotFinite };
const char* toString(ZmpPreviewStatus status) noexcept;

class ZmpPreviewController {
 public:
  /// One axis: the cart's state and the running sum of the ZMP's error.
  struct State {
    Eigen::Vector3d x = Eigen::Vector3d::Zero();  ///< [c, ċ, c̈].
    double error_sum = 0.0;                       ///< Σ e_i.
  };

  /// Solves the Riccati equation (iterated to a relative change below 10⁻¹²) and the gains. \throws
  /// std::invalid_argument for invalid parameters, std::runtime_error if the iteration does not converge.
  explicit ZmpPreviewController(const ZmpPreviewParameters& parameters);

  /// One period: e_k = C x_k − p_ref,k added to the sum, u_k as above, x ← A x + B u. `reference` holds
  /// p_ref,k … p_ref,k+N (N + 1 values). WrongSize or NotFinite: the state unchanged. Real-time safe.
  [[nodiscard]] ZmpPreviewStatus step(State& state, const Eigen::Ref<const Eigen::VectorXd>& reference) const noexcept;
  /// The ZMP C x of a state.
  double zmp(const State& state) const noexcept { return c_.dot(state.x); }

  const ZmpPreviewParameters& parameters() const noexcept { return parameters_; }
  double integralGain() const noexcept { return gain_integral_; }                 ///< G_i.
  const Eigen::RowVector3d& stateGain() const noexcept { return gain_state_; }    ///< G_x.
  const Eigen::VectorXd& previewGains() const noexcept { return gain_preview_; }  ///< G_d(1) … G_d(N).
  const Eigen::Matrix3d& a() const noexcept { return a_; }
  const Eigen::Vector3d& b() const noexcept { return b_; }
  const Eigen::RowVector3d& c() const noexcept { return c_; }
  /// The Riccati equation's solution P (4 × 4).
  const Eigen::Matrix4d& riccati() const noexcept { return p_; }

 private:
  ZmpPreviewParameters parameters_;
  Eigen::Matrix3d a_;
  Eigen::Vector3d b_;
  Eigen::RowVector3d c_, gain_state_;
  Eigen::Matrix4d p_;
  double gain_integral_ = 0.0;
  Eigen::VectorXd gain_preview_;
};

}  // namespace bimanual_skills::control

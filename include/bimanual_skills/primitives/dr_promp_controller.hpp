/// \file
/// Latent-space stochastic controller of a DR-ProMP (thesis eqs. 7.6–7.12): the ProMP controller of the latent
/// state x = Ω_2† y on the projected dynamics, commanding u = Ω ν + ε_u.
#pragma once

#include "bimanual_skills/primitives/dr_promp.hpp"
#include "bimanual_skills/primitives/promp_controller.hpp"

#include <Eigen/Core>

#include <random>
#include <vector>

namespace bimanual_skills::primitives {

struct DrProMpControllerData;

/// For the d-DoF system y_{t+dt} = (I + dt A_t) y_t + B_t dt u + c_t dt (7.6), y = [q; q̇], u ∈ ℝ^d, the latent state
/// x = Ω_2† y follows (7.8) x_{t+dt} = (I + dt A_x) x_t + B_x dt ν + c_x dt with A_x = Ω_2† A_t Ω_2,
/// B_x = Ω_2† B_t Ω, c_x = Ω_2† c_t when u = Ω ν (7.7–7.10, Ω of full column rank so Ω_2† Ω_2 = I). The latent gains
/// ν = K_t x_t + κ_t (7.9) and the latent noise Σ_ν are those of a ProMpController on the latent ProMP and that
/// system (the one-step matching of (7.11), see promp_controller.hpp for the derivation and the thesis' typos). The
/// command keeps the noise in the full space, u = Ω ν + ε_u, ε_u ~ N(0, Σ_u / dt) with
///   Σ_u = Ω Σ_ν Ωᵀ + α² I,
/// which is (7.12), B† Ω_2 Σ_s Ω_2ᵀ B†ᵀ + α² I, wherever Ω_2 Σ_s Ω_2ᵀ lies in the range of B (e.g. a double
/// integrator); α > 0 explores the neighbourhood of the latent space. Steps as ProMpController's.
class DrProMpController {
 public:
  /// `systems`: one linearisation of the d-DoF robot for all steps or one per step, each with d inputs.
  /// \throws std::invalid_argument as ProMpController, for systems with other than d inputs, or α < 0.
  DrProMpController(const DrProMp& promp, const std::vector<LinearisedSystem>& systems, double dt, double alpha = 0.0,
                    double regularisation = 1e-9);

  int steps() const noexcept { return latent_.steps(); }
  double dt() const noexcept { return latent_.dt(); }
  int dofs() const noexcept { return static_cast<int>(coordination_.rows()); }
  int latentDims() const noexcept { return static_cast<int>(coordination_.cols()); }
  /// The latent controller: K_t (r × 2r), κ_t (r) of (7.9) and Σ_ν.
  const ProMpController& latent() const noexcept { return latent_; }
  /// Ω_2† (2r × 2d), which maps the measured state to the latent one.
  const Eigen::MatrixXd& stateProjection() const noexcept { return projection_; }
  /// Σ_u of a step (7.12). \throws std::out_of_range for a step outside [0, steps()).
  const Eigen::MatrixXd& inputCovariance(int step) const {
    return input_covariances_.at(static_cast<std::size_t>(step));
  }

  /// Mean command u = Ω (K_t Ω_2† y + κ_t). OutOfSchedule, WrongSize or NotFinite (u unchanged) as ProMpController.
  /// Real-time safe: no allocation, no exceptions.
  [[nodiscard]] ProMpControlStatus command(DrProMpControllerData& data, int step,
                                           const Eigen::Ref<const Eigen::VectorXd>& state,
                                           Eigen::Ref<Eigen::VectorXd> u) const noexcept;
  /// Stochastic command u = Ω ν + ε_u, ε_u ~ N(0, Σ_u / dt) drawn from `rng` through a factor computed at
  /// construction. Statuses as the mean command. Real-time safe: no allocation, no exceptions.
  [[nodiscard]] ProMpControlStatus command(DrProMpControllerData& data, int step,
                                           const Eigen::Ref<const Eigen::VectorXd>& state, std::mt19937& rng,
                                           Eigen::Ref<Eigen::VectorXd> u) const noexcept;

 private:
  Eigen::MatrixXd coordination_, projection_;
  ProMpController latent_;
  std::vector<Eigen::MatrixXd> input_covariances_, noise_factors_;
};

/// Scratch of the controller's commands, sized once: `DrProMpControllerData data(controller);`.
struct DrProMpControllerData {
  explicit DrProMpControllerData(const DrProMpController& controller);

  Eigen::VectorXd latent_state;  ///< x = Ω_2† y (2r).
  Eigen::VectorXd latent_input;  ///< ν (r).
};

}  // namespace bimanual_skills::primitives

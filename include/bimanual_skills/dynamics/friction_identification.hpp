/// \file
/// Offline identification of the friction models (thesis Sec. 2.3.2 and 4.2.2) from logged joint data (the logs'
/// CSV files are in friction_log.hpp, the models' YAML files in friction_yaml.hpp). Allocates and throws freely:
/// never call from a real-time loop. Target bimanual_skills_dynamics (NLopt, yaml-cpp).
#pragma once

#include "bimanual_skills/dynamics/friction_log.hpp"
#include "bimanual_skills/dynamics/friction_model.hpp"
#include "bimanual_skills/kinematics/chain_model.hpp"

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

namespace bimanual_skills::dynamics {

/// Friction torques observed in a log, F_f = u_c − M(q) q̈ − C(q, q̇) q̇ − G(q) (2.12), for a model of the arm.
Eigen::MatrixXd observedFriction(const kinematics::ChainModel& model, const FrictionLog& log);

/// Where sign(q̈) comes from for the hysteresis term.
enum class SignSource {
  LoggedAcceleration,  ///< sign of the log's q̈ column (loggers usually differentiate offline, without lag).
  FilteredVelocity,    ///< AccelerationSign run over the logged q̇, as a controller sees it on line.
};
Eigen::MatrixXd accelerationSigns(const FrictionLog& log, SignSource source);

struct FrictionFitOptions {
  FrictionModelType type = FrictionModelType::Advanced;
  std::vector<std::pair<int, int>> pairs;  ///< Coupled joint pairs (0-based), fitted with a reduced model each.
  double epsilon = 0.05;                   ///< Dead band of the pair switching [rad/s].
  double holdout = 0.25;                   ///< Fraction of samples, at the end of the log, kept for validation.
  int restarts = 8;                        ///< Seeded random starts of the nonlinear search.
  std::uint32_t seed = 1;
  int max_search_samples = 20000;  ///< Evenly strided subset for the nonlinear search (the final b uses all).
  double s_min = 0.5, s_max = 200.0, z_min = -3.0, z_max = 3.0, h_min = 0.2, h_max = 5.0;  ///< Search bounds.
  /// Ridge weight per sample: b minimises ‖Φ b − F‖² + ridge · samples · ‖b‖². Without it, the advanced model's
  /// linear and Fourier columns become nearly collinear when h is small against the positions visited (sin((2j−1)hq)
  /// ≈ odd powers of q), and the fit returns huge cancelling coefficients that extrapolate wildly outside the data.
  /// The default costs a coefficient of 1 N m a 1e-4 N² m² rise of the mean squared error: on the synthetic log of
  /// test_friction_identification (noise 0.02 N m) the held-out MAE and MSE of fit_friction do not change in the
  /// fourth decimal.
  double ridge = 1e-4;

  void validate() const;
};

/// Error indicators of Table 4.1 over a set of samples.
struct FrictionErrors {
  double mae = 0.0, mse = 0.0, max_error = 0.0;
  int samples = 0;
};

struct FrictionFit {
  FrictionModel model;
  std::vector<FrictionErrors> train, test;  ///< Per joint.
};

/// Fits one friction model per joint (and a reduced one per joint of each pair, on the samples where the pair's
/// switching rule selects it): for given (s, z, h) the coefficients b are the (ridge) least-squares solution of
/// Φ b = F;
/// (s, z, h) minimise the residual by NLopt's BOBYQA from `restarts` seeded starts within the bounds.
/// \param friction observed friction (observedFriction), samples × joints; \param signs sign(q̈), same shape.
FrictionFit fitFriction(const FrictionLog& log, const Eigen::MatrixXd& friction, const Eigen::MatrixXd& signs,
                        const FrictionFitOptions& options);

/// Errors of a model on samples [first, last), the pair modes evolving from sample 0.
std::vector<FrictionErrors> evaluateFriction(const FrictionModel& model, const FrictionLog& log,
                                             const Eigen::MatrixXd& friction, const Eigen::MatrixXd& signs, int first,
                                             int last);

}  // namespace bimanual_skills::dynamics

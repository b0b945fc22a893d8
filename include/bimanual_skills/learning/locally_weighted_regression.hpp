/// \file
/// Incremental locally weighted regression (in the spirit of RFWR/LWPR, thesis Sec. 2.3.1): the learned
/// alternative to the analytic dynamics, n(q, q̇) = u_c − M(q_d) q̈_d = C q̇ + G + F_f.
#pragma once

#include <Eigen/Core>

#include <vector>

namespace bimanual_skills::learning {

struct LwrParameters {
  Eigen::VectorXd width;              ///< Kernel width per input dimension (same units as the input), > 0.
  double activation_to_create = 0.2;  ///< A new field is created where no field's activation exceeds this.
  double forgetting = 0.999;          ///< RLS forgetting factor λ ∈ (0, 1].
  double initial_covariance = 100.0;  ///< RLS: P0 = p0 I of each new local model.
  int max_fields = 500;               ///< Capacity, allocated at construction.
  double prediction_cutoff = 1e-3;    ///< Fields with a smaller activation are skipped in prediction.

  void validate(int input_dim) const;
};

/// Outcome of an update or prediction. On anything but Success nothing was learned or predicted (y is zero).
enum class LwrStatus { Success, NoActiveField, WrongSize, NotFinite };
const char* toString(LwrStatus status) noexcept;

/// y ≈ Σ_k w_k(x) β_kᵀ [x − c_k; 1] / Σ_k w_k(x), w_k = exp(−½ Σ_i ((x_i − c_k,i)/width_i)²). Each field's β_k is
/// fitted by recursive weighted least squares on the samples it sees; fields are created on demand at samples
/// no field covers, up to max_fields. All storage is allocated at construction: update() and predict() are
/// real-time safe (no allocation, no exceptions).
class LocallyWeightedRegression {
 public:
  /// \throws std::invalid_argument for non-positive dimensions or invalid parameters.
  LocallyWeightedRegression(int input_dim, int output_dim, const LwrParameters& parameters);

  /// Adds one training sample: WrongSize or NotFinite (nothing learned) on bad input. Real-time safe.
  [[nodiscard]] LwrStatus update(const Eigen::Ref<const Eigen::VectorXd>& x,
                                 const Eigen::Ref<const Eigen::VectorXd>& y) noexcept;
  /// Prediction into y; NoActiveField when no field is active enough at x (y is then zero), WrongSize or NotFinite
  /// (y untouched) on bad input. Real-time safe.
  [[nodiscard]] LwrStatus predict(const Eigen::Ref<const Eigen::VectorXd>& x, Eigen::Ref<Eigen::VectorXd> y) noexcept;

  int fields() const noexcept { return count_; }
  int inputDim() const noexcept { return input_dim_; }
  int outputDim() const noexcept { return output_dim_; }

 private:
  double activation(int k, const Eigen::Ref<const Eigen::VectorXd>& x) const noexcept;

  int input_dim_, output_dim_;
  LwrParameters parameters_;
  Eigen::MatrixXd centres_;            ///< input_dim × max_fields
  std::vector<Eigen::MatrixXd> beta_;  ///< (input_dim + 1) × output_dim per field
  std::vector<Eigen::MatrixXd> P_;     ///< (input_dim + 1)² per field
  Eigen::VectorXd z_, Pz_, error_, local_;
  int count_ = 0;
};

}  // namespace bimanual_skills::learning

/// \file
/// Closed-loop inverse kinematics (CLIK) with every inverse operator and joint-limit scheme of the thesis (Ch. 3.1,
/// Table 3.1), composed as an (operator, scheme) pair: e.g. {SvfSelectiveDamping, ContinuousTaskPriority} is the
/// thesis' CTP+SD+SVF, {Pseudoinverse, None} is plain JP.
#pragma once

#include "bimanual_skills/kinematics/chain_kinematics.hpp"
#include "bimanual_skills/kinematics/pose_error.hpp"
#include "bimanual_skills/kinematics/thin_svd.hpp"

#include <Eigen/Cholesky>

#include <array>
#include <string>
#include <vector>

namespace bimanual_skills::kinematics {

/// Inverse operator J* applied to the task error (Table 3.1). Each maps a singular value σ of the (weighted) Jacobian
/// to a gain g(σ) in J* = Σ g(σ_i) v_i u_iᵀ, except the selective-damping ones, which bound each component's step.
enum class InverseOperator {
  Pseudoinverse,         ///< JP (2.7): g = 1/σ (0 below pinv_tolerance).
  Transpose,             ///< JT (3.1): Δq = α Jᵀ e with Buss's step α = ⟨e, JJᵀe⟩ / ‖JJᵀe‖².
  SelectiveDamping,      ///< SD (Buss & Kim; thesis 3.35–3.38 with σ̂ = σ): per-component step bound γ_s.
  Damping,               ///< JD (3.3): g = σ / (σ² + λ²).
  Filtering,             ///< JF (3.6): λ² = (1 − (σ_min/ε)²) λ_max² inside the singular region σ_min < ε.
  ErrorDamping,          ///< ED (3.7): g = σ / (σ² + E), E = ½ eᵀe.
  ImprovedErrorDamping,  ///< IED (3.8): g = σ / (σ² + E + ω).
  SingularValueFilter,   ///< SVF (3.10–3.12): g = 1 / h_{ν,σ0}(σ).
  SvfErrorDamping,       ///< SVF+ED: ED applied to the filtered values, g = h / (h² + E).
  SvfSelectiveDamping,   ///< SVF+SD: SD with σ̂ = h_{ν,σ0}(σ).
};

/// How joint limits (and other secondary goals) enter the step (Sec. 3.1.3–3.1.4).
enum class LimitScheme {
  None,                    ///< Δq = J* e; limits ignored (Table 3.4 methods).
  JointWeighting,          ///< JW (3.16): Δq = W^{-1/2} (J W^{-1/2})* e, W from Chan & Dubey's criterion.
  GradientProjection,      ///< GP (3.17): Δq = J* e + μ (I − J^† J) ∇H, H the joint-centring function (3.19).
  JointClamping,           ///< JC (3.20): Δq = A (J A)* e, A = I − H_β (joints blocked at their limits).
  TaskAugmentation,        ///< TA: J extended with the rows h_i e_iᵀ (push-to-centre tasks of joints near limits).
  TaskPriority,            ///< TP (3.18, 3.25): limits first with the ordinary pseudoinverse of H_β, then the pose.
  ContinuousTaskPriority,  ///< CTP (3.26–3.28; with SD 3.29–3.40): limits first, continuous pseudoinverse (3.22).
};

/// Every inverse operator and every limit scheme, in the order of the thesis' tables.
inline constexpr std::array<InverseOperator, 10> kInverseOperators = {InverseOperator::Pseudoinverse,
                                                                      InverseOperator::Transpose,
                                                                      InverseOperator::SelectiveDamping,
                                                                      InverseOperator::Damping,
                                                                      InverseOperator::Filtering,
                                                                      InverseOperator::ErrorDamping,
                                                                      InverseOperator::ImprovedErrorDamping,
                                                                      InverseOperator::SingularValueFilter,
                                                                      InverseOperator::SvfErrorDamping,
                                                                      InverseOperator::SvfSelectiveDamping};
inline constexpr std::array<LimitScheme, 7> kLimitSchemes = {LimitScheme::None,
                                                             LimitScheme::JointWeighting,
                                                             LimitScheme::GradientProjection,
                                                             LimitScheme::JointClamping,
                                                             LimitScheme::TaskAugmentation,
                                                             LimitScheme::TaskPriority,
                                                             LimitScheme::ContinuousTaskPriority};

/// Parses a thesis abbreviation as methodName() prints it ("JP", "SVF+ED", "CTP+SD+SVF", ...): false if unknown.
bool parseMethodName(const std::string& name, InverseOperator& op, LimitScheme& scheme) noexcept;

/// Human-readable thesis abbreviation ("JP", "SVF+SD", "CTP+SD+SVF", ...) of an (operator, scheme) pair.
const char* methodName(InverseOperator op, LimitScheme scheme) noexcept;

/// Every method name parseMethodName() accepts, in the order of the thesis' tables (Table 3.4's operators, then
/// Table 3.5's limit schemes).
const std::vector<std::string>& methodNames();

struct ClikParameters;

/// Gain g(σ) of the operator for one singular value σ (Table 3.2): J* = Σ g(σ_i) v_i u_iᵀ. `sigma_min` is the
/// smallest singular value of the matrix (JF's singular region), `error_energy` E = ½ eᵀe (ED, IED). The selective-
/// damping operators return their undamped gain (1/σ, 1/h(σ)); JT returns σ (without its step length).
double inverseOperatorGain(const ClikParameters& parameters, InverseOperator op, double sigma, double sigma_min,
                           double error_energy) noexcept;

/// Parameters of a CLIK solver. Defaults are the thesis' (Tables 3.4, 3.5; Sec. 3.1.2).
struct ClikParameters {
  InverseOperator inverse = InverseOperator::SvfSelectiveDamping;
  LimitScheme limits = LimitScheme::ContinuousTaskPriority;
  TaskMode mode = TaskMode::Pose;
  double rotation_weight = 1.0;  ///< Task metric: metres per radian of orientation error (scales the ω rows).
  double pinv_tolerance = 1e-9;  ///< JP: singular values below this count as zero.
  double lambda = 0.005;         ///< JD damping λ (Table 3.4).
  double filter_epsilon = 0.05;  ///< JF: width ε of the singular region (in singular values).
  double lambda_max = 0.02;      ///< JF: maximum damping λ_max = 4λ (Table 3.4).
  double ied_omega = 0.01;       ///< IED: ω (Ω = ω I_m, Table 3.4).
  double sigma0 = 0.01;          ///< SVF: minimum singular value σ0 (Table 3.4).
  double nu = 10.0;              ///< SVF: shape factor ν (σ0 < ν < 2/σ0).
  double gamma_max = 0.5;        ///< SD: maximum joint change per step γ_max [rad] (Table 3.4).
  double gp_gain = 0.2;          ///< GP: μ (Table 3.5).
  /// Activation buffer β [rad]: h_β rises from 0 to 1 over the last β before a limit. The thesis leaves β open;
  /// goals inside the buffer compete with the push to the centre, so smaller is better down to ~0.05 (CTP+SD+SVF on
  /// 300 Table 3.5 problems: 94.0 % at β = 0.1, 97.7 % at 0.05, 98.0 % at 0.02).
  double beta = 0.05;
  /// solve(): β schedule. When the residual has not dropped by 10 % over `stall_window` iterations, β is
  /// multiplied by `beta_decay` (1 disables). A goal a few millimetres from a limit lies deep in the buffer, where
  /// h_β ≈ 1 all but removes the joint and the push to the centre balances the task: shrinking β releases it.
  /// Measured on Table 3.5 (1000 problems, seed 1), CTP+SD+SVF: 98.1 % within limits without, 99.6 % with 10 / 0.5.
  int stall_window = 10;
  double beta_decay = 0.5;
  double lambda_jl = 0.1;    ///< Push-to-centre gain λ_JL (thesis: 0.1–0.5).
  int max_iterations = 500;  ///< solve(): iteration cap.
  double tolerance = 1e-5;   ///< solve(): converged when every error component ≤ tolerance [m, rad].
  double timeout = 0.0;      ///< solve(): time budget [s]; 0 = none.
  /// solve(): clamp q into the joint limits after every step (the rule of KDL's NR_JL); off in the thesis' methods.
  bool clamp_to_limits = false;

  /// Throws std::invalid_argument naming the first parameter that is out of range.
  void validate() const;
};

/// Outcome of a CLIK step or solve. A step() that computed Δq returns StepComputed; only solve() (and the global
/// solver) say Converged.
enum class IkStatus { Converged, StepComputed, MaxIterations, Timeout, InvalidInput, NumericalFailure };
const char* toString(IkStatus status) noexcept;

/// Result of solve(): status, iterations used and the final residual max_i |e_i| (unweighted, m and rad).
struct IkResult {
  IkStatus status = IkStatus::InvalidInput;
  int iterations = 0;
  double residual = 0.0;
};

/// Joint-limit activation h_β(q) ∈ [0, 1] (3.24): 0 farther than β from both limits, 1 at or beyond a limit,
/// C∞ in between (h = ½ (1 + tanh(1/x − 1/(1 − x))), x = distance / β).
double limitActivation(double q, double lower, double upper, double beta) noexcept;

/// Most joints a CLIK chain may have: the continuous pseudoinverse (3.22) enumerates the subsets of the joints in
/// transition with a bit mask, and the joint index lists have this fixed capacity.
inline constexpr int kClikMaxJoints = 30;

/// A list of joint indices of fixed capacity kClikMaxJoints: growing it never allocates.
class JointIndexList {
 public:
  void clear() noexcept { size_ = 0; }
  /// Appends a joint; ignored when full (ClikData rejects chains longer than the capacity).
  void push(int joint) noexcept {
    if (size_ < kClikMaxJoints) indices_[static_cast<std::size_t>(size_++)] = joint;
  }
  int size() const noexcept { return size_; }
  bool empty() const noexcept { return size_ == 0; }
  int operator[](int i) const noexcept { return indices_[static_cast<std::size_t>(i)]; }
  const int* begin() const noexcept { return indices_.data(); }
  const int* end() const noexcept { return indices_.data() + size_; }

 private:
  std::array<int, kClikMaxJoints> indices_{};
  int size_ = 0;
};

/// Scratch buffers of a CLIK solver for one chain and one parameter set, sized once. n joints, m task rows.
struct ClikData {
  /// \throws std::invalid_argument for invalid parameters or a chain of more than kClikMaxJoints joints.
  ClikData(const ChainModel& model, const ClikParameters& parameters);

  ChainData kinematics;
  Eigen::VectorXd error;     ///< Unweighted task error (m rows).
  Eigen::VectorXd task;      ///< Weighted task error e.
  Eigen::MatrixXd jacobian;  ///< Weighted task Jacobian J (m × n).
  Eigen::VectorXd dq;        ///< Last step.

  // Decompositions.
  std::vector<ThinSvd> svd_by_columns;   ///< SVD of m × c sub-Jacobians, c = 1..n (index c − 1).
  ThinSvd svd_augmented;                 ///< (m + n) × n, task augmentation.
  ThinSvd svd_inverse;                   ///< n × m, SVD of a continuous pseudoinverse (CTP+SD).
  Eigen::MatrixXd gram;                  ///< J Jᵀ + c I (m × m), damped operators.
  Eigen::LLT<Eigen::MatrixXd> gram_llt;  ///< Its Cholesky factorisation.

  // Joint space (n).
  Eigen::VectorXd activation;         ///< h_β(q_i) (3.24).
  Eigen::VectorXd centre;             ///< Joint range centres q_c (0 for unlimited joints).
  Eigen::VectorXd scale;              ///< Column scaling of J: W^{-1/2} (JW), 1 − h (JC, CTP), P1's diagonal (TP).
  Eigen::VectorXd previous_gradient;  ///< JW: |∂H/∂q| at the previous step.
  Eigen::VectorXd column_norms;       ///< ‖J^j‖ for selective damping.
  Eigen::VectorXd limit_step;         ///< Δq1 of TP and CTP: the joint-limit task's step.
  Eigen::VectorXd task_step;          ///< The pose task's step through the (scaled) inverse.
  Eigen::VectorXd centring_gradient;  ///< GP: ∇H (3.19).
  Eigen::VectorXd null_space_part;    ///< GP: J† J ∇H.
  Eigen::VectorXd component;          ///< Selective damping: one component w_s.

  // Task space (m) and operators.
  Eigen::VectorXd task_residual;   ///< e − J Δq1 (TP, CTP).
  Eigen::VectorXd task_image;      ///< J x of a joint vector x (GP: J ∇H; CTP+SD: J Δq1).
  Eigen::VectorXd gains;           ///< Operator gains g(σ_i) (m + n).
  Eigen::VectorXd task_scratch;    ///< J Jᵀ e (JT) or (J Jᵀ + c I)⁻¹ e (damped operators) (m + n).
  Eigen::MatrixXd columns;         ///< m × n, sub-Jacobian of selected or scaled columns (left block used).
  Eigen::MatrixXd augmented;       ///< (m + n) × n, TA's extended Jacobian.
  Eigen::VectorXd augmented_task;  ///< m + n, TA's extended error.
  Eigen::MatrixXd inverse;         ///< n × m, an inverse operator as a matrix.
  Eigen::MatrixXd scattered;       ///< n × m: right singular vectors of J_Q scattered to their joints (CTP+SD).
  JointIndexList always, transitional, selected;  ///< Joints with h = 1, with 0 < h < 1, and of the subset Q.
};

/// One CLIK step Δq at configuration q towards `target` (pose of the chain tip in the base frame), into data.dq:
/// StepComputed, InvalidInput for a wrong size or non-finite q or target, NumericalFailure for a non-finite step.
/// Real-time safe: no allocation, no exceptions.
[[nodiscard]] IkStatus step(const ChainModel& model, const ClikParameters& parameters, ClikData& data,
                            const Eigen::Ref<const Eigen::VectorXd>& q, const Eigen::Isometry3d& target) noexcept;

/// Iterates q ← q + Δq from the given q until every error component is within tolerance, the iteration cap or
/// the time budget. q is updated in place (the last iterate on failure). JW's step memory is reset at the start.
/// Real-time safe: no allocation, no exceptions.
[[nodiscard]] IkResult solve(const ChainModel& model, const ClikParameters& parameters, ClikData& data,
                             Eigen::Ref<Eigen::VectorXd> q, const Eigen::Isometry3d& target) noexcept;

/// Continuous pseudoinverse with joint activations a_i ∈ [0, 1] (thesis eq. 3.22):
/// J^{A⊕} = Σ_{Q ⊆ {1..n}} (∏_{i∈Q} a_i)(∏_{i∉Q} (1 − a_i)) J_Q^*, J_Q the columns in Q (others zero), * the inner
/// operator (Pseudoinverse or SingularValueFilter gains). Only joints with 0 < a_i < 1 branch: the cost is 2^k
/// decompositions for k such joints (1 when none is in transition). `inner` gives the gains g(σ) of J_Q^* (the
/// selective-damping operators use their undamped inverse: 1/σ or 1/h(σ)); `error_energy` is E for ED/IED.
/// J must be m × n (the task size of `data`); writes n × m into `out`.
/// Real-time safe: no allocation, no exceptions.
void continuousPseudoinverse(const ClikParameters& parameters, ClikData& data,
                             const Eigen::Ref<const Eigen::MatrixXd>& J,
                             const Eigen::Ref<const Eigen::VectorXd>& activation, InverseOperator inner,
                             double error_energy, Eigen::Ref<Eigen::MatrixXd> out) noexcept;

}  // namespace bimanual_skills::kinematics

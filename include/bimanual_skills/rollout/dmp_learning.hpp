/// \file
/// Policy search over a (coordinated) DMP fitted to a task's demonstration, for any RolloutTask whose parameters are
/// a coordinated policy (coordinated_parameters.hpp): the DR-DMP variants of the thesis' Ch. 7 with REPS and the
/// CMU/IDR coordination updates, PI2-CMA (optionally on a second layer of Gaussians over the DMP's kernels, its
/// covariance filtered to the diagonal: the thesis' scarf experiment, Sec. 4.3.1) and CMA-ES. The task's results are
/// recorded with its own term names.
///
/// Protocol of one run of one algorithm: the DR-DMP is fitted to the demonstration (PCA coordination, 7.26–7.27); the
/// search starts at the fit with an isotropic covariance; each epoch e = 0 … updates runs the noise-free mean policy
/// (what a user of the learning gets at that point; not used by the update) and `rollouts` samples, then (e <
/// updates) updates the policy from the samples' rewards.
///
/// Nothing is lost: every finished rollout is appended at once to DIR/rollouts.csv (outcome, reward, the task's terms,
/// reason) and DIR/rollout_parameters.csv (its latent weights); DIR/epochs.csv is rewritten after every epoch. A
/// learning is deterministic for its seed, so a restarted run regenerates the same rollouts and takes those on disk
/// (checking that their parameters are the same to the last bit) instead of running them again. Results do not
/// depend on the number of threads or workers. Rollouts whose outcome is "RobotFailed" stay out of the learning:
/// they run again with the same parameters and seed (robot_retries), and the learning stops after robot_fault_limit
/// of them in a row. Target bimanual_skills_rollout. Offline: allocates and throws std::invalid_argument.
#pragma once

#include "bimanual_skills/learning/coordinated_reps.hpp"
#include "bimanual_skills/primitives/dr_dmp.hpp"
#include "bimanual_skills/rollout/parallel_evaluator.hpp"

#include <Eigen/Core>

#include <cstdint>
#include <functional>
#include <memory>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace bimanual_skills::rollout {

/// How the policy follows the rollouts.
enum class PolicySearch {
  Reps,    ///< REPS on the latent weights (reusing earlier rollouts), then the variant's coordination rule.
  Pi2Cma,  ///< PI2-CMA (learning/pi2.hpp, h = 10) on the weights, the reward as a terminal cost, the covariance
           ///< memory λ as REPS'; no reuse.
  CmaEs,   ///< CMA-ES (Hansen 2006): the best half by log-rank weights, CovarianceAdaptation; no reuse.
  /// "REPS": learning::DualReps without clusters (the REPS update of the thesis' Ch. 6 comparisons and ps_benchmark,
  /// learning::thesisReps) on the weights, reusing earlier rollouts; the covariance memory λ as above.
  StandardReps,
  /// "DREPS": Dual REPS (thesis Ch. 6, Alg. 6.2) with the thesis' settings (learning::thesisDreps) on the weights.
  Dreps,
};

/// A DR-DMP variant of Tables 7.1–7.2, by the thesis' name, or a peer on the standard DMP.
struct DrDmpVariant {
  std::string name;
  int matrices = 1;     ///< N_s
  int latent_dims = 1;  ///< Initial r.
  learning::CoordinationRule rule = learning::CoordinationRule::Fixed;
  double eta = 0.0;  ///< η of the CMU (infinity: r fixed).
  PolicySearch search = PolicySearch::Reps;
};

/// "DR-DMP0(r)" (fixed PCA coordination; r = d is the standard DMP), "DR-DMP_CMU(r)", "DR-DMP_MCMU(Ns,r)",
/// "IDR-DMP_CMU" and "IDR-DMP_MCMU(Ns)" (r = d, reduced by η) for `dofs` DoF; and the peers "PI2-CMA" and "CMA-ES"
/// on the standard DMP's weights (r = d, fixed coordination), and "REPS" and "DREPS" there (PolicySearch).
/// \throws std::invalid_argument for another name or r outside [1, dofs], N_s < 1.
DrDmpVariant parseDrDmpVariant(const std::string& name, int dofs, double eta);

/// What a rollout was.
enum class RolloutKind {
  Sample,      ///< Drawn from the policy (exploration).
  Policy,      ///< The mean policy without exploration (one per epoch, before its update).
  Repetition,  ///< The initial mean policy again, another sensor-noise seed (the reward's variance).
};
const char* toString(RolloutKind kind) noexcept;

/// The learning stopped because the robot kept failing (robot_retries, robot_fault_limit of its configuration).
class RobotFaults : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// One PI2-CMA update of `policy` (its mean and covariance) from the samples' rewards, the reward a terminal cost
/// (rollouts scored once, at the end: every step weighs them alike); `basis` the DMP's basis per step (time steps ×
/// weights per DoF). The new covariance keeps `memory` of the one sampled from (as REPS' λ: a dozen rollouts span a
/// dozen directions of many, and PI2-CMA's own covariance would stop exploring in all the others), and only its
/// diagonal with `diagonal`.
learning::CoordinatedPolicy pi2CmaStep(learning::CoordinatedPolicy policy, const Eigen::MatrixXd& samples,
                                       const Eigen::VectorXd& rewards, const Eigen::MatrixXd& basis, double memory,
                                       double h = 10.0, bool diagonal = false);

/// The inverse of toString(RolloutKind). \throws std::invalid_argument naming `where`.
RolloutKind rolloutKindFromString(const std::string& text, const std::string& where);

/// What the learning needs of its task besides its rollouts.
struct DmpTaskModel {
  int dofs = 0;
  /// The task's DR-DMP parameters with `matrices` coordination matrices (kernels, transformation system).
  std::function<primitives::DrDmpParameters(int matrices)> forcing;
  Eigen::MatrixXd demonstration;  ///< samples × dofs, every `step` seconds.
  double step = 0.0;
  std::vector<std::string> terms;  ///< The names of the task's RolloutResult::terms.
  /// A term that is 1 for a success and 0 otherwise (counted per epoch); "" for none.
  std::string success;
  /// Files DIR/name → text that a run directory must hold before its rollouts are reused (the task's
  /// configuration, its world): written while it holds none, compared once it does.
  std::vector<std::pair<std::string, std::string>> locks;
};

struct DmpLearningConfig {
  std::vector<std::string> algorithms = {"PI2-CMA"};  ///< parseDrDmpVariant() names.
  int runs = 1;
  int updates = 20;
  int rollouts = 12;  ///< Per epoch.
  int reuse = 12;     ///< Rollouts of the previous epochs reused by REPS.
  double epsilon = 0.5;
  double eta = 50.0;
  double initial_stddev = 10.0;    ///< Of each searched weight at the start (latent, or second-layer).
  double covariance_memory = 0.0;  ///< λ in [0, 1): REPS' and PI2-CMA's new covariance keeps λ of the old one.
  /// PI2-CMA on a second layer of Gaussians (the thesis' ref. [25]): this many weights θ per DoF move the fitted
  /// kernel weights by normalised Gaussians of them (ω = ω_fit + Φ θ, dualLayer()); the search starts at θ = 0, the
  /// demonstration. 0: PI2-CMA on the kernel weights themselves.
  int dual_kernels = 0;
  /// PI2-CMA's covariance update keeps only its diagonal (the thesis' "filtered version of CMA").
  bool diagonal_covariance = false;
  double h = 10.0;  ///< PI2's 1/λ (exp(−h normalised cost)).
  int robot_retries = 3;
  int robot_fault_limit = 5;
  std::uint32_t seed = 1;
  int jobs = 0;  ///< Rollouts evaluated in parallel on threads (0: the hardware's).

  /// \throws std::invalid_argument naming the entry out of range or the unknown algorithm (for `dofs` DoF).
  void validate(int dofs) const;
};

/// One finished rollout, as written to DIR/rollouts.csv.
struct DmpRolloutRecord {
  std::string algorithm;
  int run = 0, epoch = 0, index = 0;
  RolloutKind kind = RolloutKind::Sample;
  std::uint32_t seed = 0;
  RolloutResult result;  ///< reward, terms, outcome, reason, wall seconds (trajectory not recorded).
  bool resumed = false;  ///< Read from the run directory rather than run.
  std::vector<Eigen::MatrixXd> coordination;
  Eigen::VectorXd weights;  ///< Latent weights ω.
};

struct DmpEpochStats {
  std::string algorithm;
  int run = 0, epoch = 0;
  int latent_dims = 0;
  int failures = 0, successes = 0;  ///< Of the epoch's samples.
  double mean_reward = 0.0, std_reward = 0.0;
  Eigen::VectorXd term_means;  ///< Over the epoch's samples, failed ones included.
  /// The noise-free mean policy of the epoch: its reward, whether it failed, and whether it succeeded.
  double policy_reward = 0.0;
  bool policy_failed = false, policy_success = false;
};

struct DmpRunResult {
  std::string algorithm;
  int run = 0;
  std::vector<DmpEpochStats> epochs;
  DmpRolloutRecord initial_policy, final_policy, best;
  double seconds = 0.0;
};

struct DmpLearningResult {
  std::vector<DmpRunResult> runs;
  int ran = 0, resumed = 0, robot_faults = 0;
  double seconds = 0.0;
};

/// Hooks for a user interface, called from one thread at a time, in completion order.
struct DmpLearningObserver {
  /// A rollout finished; `task` is the task object that ran it when it ran in this process (still holding its
  /// state), null when it ran elsewhere or was read from disk.
  std::function<void(const DmpRolloutRecord&, RolloutTask* task)> rollout;
  std::function<void(const DmpEpochStats&)> epoch;
  std::function<void(const DmpRolloutRecord&, int attempt, const std::string& reason, bool retry)> robot_fault;
  /// Polled between rollouts: true stops the learning (learn() throws std::runtime_error("stopped")).
  std::function<bool()> stop;
};

/// The weights of the second layer: `kernels` DMP kernel weights as normalised Gaussians (equally spaced over the
/// kernels' indices, each as wide as their spacing) of `layer` weights; kernels × layer, rows summing to 1.
/// \throws std::invalid_argument for layer < 1 or layer > kernels.
Eigen::MatrixXd dualLayer(int kernels, int layer);

class DmpLearner {
 public:
  /// Opens `out_dir` (created if missing), reading the rollouts already there, and locks the model's files there.
  /// \throws std::invalid_argument for a bad configuration, an unwritable directory or one that holds rollouts of
  /// another configuration.
  DmpLearner(DmpTaskModel model, const DmpLearningConfig& config, const std::string& out_dir,
             std::unique_ptr<Evaluator> evaluator, DmpLearningObserver observer = {});
  ~DmpLearner();
  DmpLearner(const DmpLearner&) = delete;
  DmpLearner& operator=(const DmpLearner&) = delete;

  /// Runs every algorithm and run. \throws std::invalid_argument when the directory holds rollouts of another
  /// configuration or seed; RobotFaults when the robot keeps failing (what finished is on disk).
  DmpLearningResult learn();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace bimanual_skills::rollout

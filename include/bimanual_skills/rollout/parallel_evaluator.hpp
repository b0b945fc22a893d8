/// \file
/// The rollout interface of the policy-search programs and an evaluator that runs batches of rollouts over a pool
/// of threads. A task turns a policy parameter vector and a rollout seed into a result, deterministically for the
/// seed; the evaluator owns one task per thread (one simulator each), so a batch's results do not depend on the
/// number of threads. Target bimanual_skills_rollout. Offline: allocates; errors are exceptions.
#pragma once

#include <Eigen/Core>

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace bimanual_skills::rollout {

/// What one rollout returned.
struct RolloutResult {
  double reward = 0.0;
  Eigen::VectorXd terms;  ///< The reward's terms, named by RolloutTask::termNames().
  bool ok = true;         ///< False when the rollout failed (the reward is then the task's failure reward).
  std::string outcome;    ///< The task's name for how it ended ("Ok", "IkFailed", ...).
  std::string reason;     ///< Why it failed; empty when ok.
  double wall_seconds = 0.0;
  /// An optional summary of the rollout's trajectory, one column per sample (empty when the task gives none): the
  /// fold's two tool paths (FoldRolloutTask::toolPaths), which a learner shows of rollouts that ran elsewhere.
  Eigen::MatrixXd trajectory;
};

/// An episodic task. run() must give the same result for the same parameters and seed, whatever ran before it on
/// the same object. One object per thread.
class RolloutTask {
 public:
  virtual ~RolloutTask() = default;
  virtual std::vector<std::string> termNames() const = 0;
  /// The task's starting policy (e.g. its demonstration), a valid parameter vector.
  virtual Eigen::VectorXd initialParameters() const = 0;
  /// A failed rollout (wrong size, non-finite values, a simulation that diverged, ...) is a result with ok = false
  /// and a reason, not an exception; exceptions are for faults of the program.
  virtual RolloutResult run(const Eigen::VectorXd& parameters, std::uint32_t seed) = 0;
};

struct RolloutRequest {
  Eigen::VectorXd parameters;
  std::uint32_t seed = 0;
};

/// Evaluates batches of rollouts: on threads of this process (ParallelEvaluator) or on rollout workers elsewhere
/// (Dispatcher). Whatever evaluates it, a request gives the same result.
class Evaluator {
 public:
  /// Called as each rollout finishes (completion order), one call at a time: the request's index, its result, and
  /// the task that ran it when it ran in this process (still holding that rollout's state, e.g. its images), null
  /// when it ran elsewhere.
  using Done = std::function<void(std::size_t index, const RolloutResult& result, RolloutTask* task)>;

  virtual ~Evaluator() = default;
  /// Runs every request and returns the results in request order. `done` is called once per request; `stop` is
  /// polled between rollouts: when it returns true no new rollout starts, the running ones finish (and are
  /// reported) and evaluate() throws std::runtime_error("stopped").
  virtual std::vector<RolloutResult> evaluate(const std::vector<RolloutRequest>& batch, const Done& done = {},
                                              const std::function<bool()>& stop = {}) = 0;
};

/// Runs batches of rollouts on a pool of threads, each with its own task.
class ParallelEvaluator : public Evaluator {
 public:
  using Factory = std::function<std::unique_ptr<RolloutTask>()>;

  /// Builds `threads` tasks with `factory` (0: one per hardware thread). \throws what the factory throws, or
  /// std::invalid_argument for threads < 0 or a factory that returns no task.
  ParallelEvaluator(const Factory& factory, int threads);
  ~ParallelEvaluator();
  ParallelEvaluator(const ParallelEvaluator&) = delete;
  ParallelEvaluator& operator=(const ParallelEvaluator&) = delete;

  int threads() const noexcept { return static_cast<int>(tasks_.size()); }
  /// The task of thread `i` (e.g. for a rollout outside a batch on the caller's thread).
  RolloutTask& task(int i) { return *tasks_.at(static_cast<std::size_t>(i)); }

  /// As Evaluator::evaluate, `done` called under the evaluator's lock. The first exception of a task is rethrown
  /// after every thread has stopped.
  std::vector<RolloutResult> evaluate(const std::vector<RolloutRequest>& batch, const Done& done = {},
                                      const std::function<bool()>& stop = {}) override;

 private:
  std::vector<std::unique_ptr<RolloutTask>> tasks_;
};

}  // namespace bimanual_skills::rollout

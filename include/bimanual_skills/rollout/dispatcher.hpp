/// \file
/// Batches of rollouts on remote rollout workers, surviving their faults. The dispatcher hands each live worker a
/// share of the batch, hands out the next share as a worker finishes (faster workers take more), and gives the
/// rollouts of a worker that dies, stops making progress for longer than a timeout, or answers something that is
/// not a result of its share, to the survivors. Every request is reported exactly once; since a rollout's result
/// depends on its parameters and seed only, the results do not depend on which worker ran what, on the number of
/// workers or on the faults. Workers are looked up again at every batch, so workers can join between batches.
///
/// The transport is behind WorkerLink and WorkerDirectory (ROS topics in ros_layer/workers/topic_workers.hpp;
/// in-process links in the tests). Target bimanual_skills_rollout. Offline: allocates; errors are exceptions.
#pragma once

#include "bimanual_skills/rollout/parallel_evaluator.hpp"

#include <cstddef>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

namespace bimanual_skills::rollout {

/// One worker as the dispatcher sees it: it evaluates one share at a time.
class WorkerLink {
 public:
  enum class State {
    Idle,      ///< No share (before start() or after its results were taken).
    Running,   ///< Working on its share.
    Finished,  ///< The share's results are in `results` (their count and contents are checked by the dispatcher).
    Refused,   ///< The worker refused the share (a task or configuration it lacks): it is left out, warned.
    Lost,      ///< The worker is gone or failed in a way that says nothing about the request.
  };
  struct Status {
    State state = State::Idle;
    std::size_t done = 0;  ///< Rollouts of the share finished so far (progress).
    std::vector<RolloutResult> results;
    std::string reason;  ///< Why Refused or Lost.
  };

  virtual ~WorkerLink() = default;
  /// A name that identifies the worker among those of its directory.
  virtual const std::string& name() const = 0;
  /// Sends a share; false when it could not be sent (the worker counts as lost).
  virtual bool start(const std::vector<RolloutRequest>& share) = 0;
  /// Without blocking: the share's state.
  virtual Status poll() = 0;
  /// Abandons the share (best effort; a late answer is ignored).
  virtual void cancel() = 0;
};

/// Finds the workers that are alive now.
class WorkerDirectory {
 public:
  virtual ~WorkerDirectory() = default;
  /// The names of the workers alive now.
  virtual std::vector<std::string> alive() = 0;
  /// A link to the worker `name`; null when it cannot be reached.
  virtual std::unique_ptr<WorkerLink> connect(const std::string& name) = 0;
  /// Where it looks for workers and how to start them, for messages.
  virtual std::string where() const = 0;
};

/// What a batch took.
struct DispatchStats {
  std::size_t rollouts = 0;
  std::size_t shares = 0;         ///< Shares sent (including re-dispatched ones).
  std::size_t redispatched = 0;   ///< Rollouts sent again because their worker failed.
  std::size_t workers = 0;        ///< Workers that took part.
  std::size_t alive = 0;          ///< Workers still alive at the end.
  std::vector<std::string> lost;  ///< "name: reason" of each worker lost during the batch.
  double seconds = 0.0;
};

struct DispatchConfig {
  /// A worker that finishes no rollout for this long [s] while it holds a share counts as hung: its share goes to
  /// the others and it is left out until the next batch. Must exceed the longest rollout.
  double timeout = 60.0;
  /// Rollouts per share: 0 hands each idle worker ⌈remaining / (2 · workers)⌉ (large shares first, small ones at
  /// the end), or ⌈remaining / workers⌉ when the rollouts so far took so little (that share under 50 ms) that
  /// another round trip would cost more than it balances; k > 0 hands out k at a time.
  std::size_t share = 0;
  /// How long [s] a batch waits for a first worker (or for one after all were lost) before it throws.
  double wait_for_workers = 30.0;
  /// A rollout given to this many workers that all failed it is a fault of the rollout: evaluate() throws.
  int max_attempts = 3;
  double poll_period = 0.002;  ///< [s] between polls of the workers.
  /// [s] between look-ups, during a batch, for workers that joined since it began. Those lost in the batch, or that
  /// could not be reached, stay out until the next one (unless no worker is left).
  double join_period = 1.0;
  /// Events worth a line in a log: a worker joined (fault = false), a worker was lost or hung and its rollouts go
  /// to the others (fault = true).
  std::function<void(const std::string& line, bool fault)> log;
  /// Called at the end of each batch with what it took (see DispatchStats).
  std::function<void(const DispatchStats&)> batch;

  /// \throws std::invalid_argument for a timeout or wait ≤ 0, max_attempts < 1 or a poll or join period ≤ 0.
  void validate() const;
};

class Dispatcher : public Evaluator {
 public:
  /// `terms` is the number of reward terms of the task (a result with another number is garbage).
  /// \throws std::invalid_argument for a null directory or a bad configuration.
  Dispatcher(std::unique_ptr<WorkerDirectory> directory, std::size_t terms, DispatchConfig config);
  ~Dispatcher() override;

  /// Evaluator::evaluate on the workers; `done` gets no task. A worker that refuses a share (another configuration
  /// file on its host, a task it lacks) is left out of this learning, warned, and its rollouts go to the others.
  /// \throws std::runtime_error when no worker is alive for config.wait_for_workers (naming those left out and
  /// why), when a rollout failed on config.max_attempts workers (a request every worker refuses), or "stopped".
  std::vector<RolloutResult> evaluate(const std::vector<RolloutRequest>& batch, const Done& done = {},
                                      const std::function<bool()>& stop = {}) override;

  /// Looks the workers up now, as each batch does first: drops the links of workers no longer listed and connects
  /// the new ones (config.log hears of each that joins). Returns how many are connected; no rollout is sent. For
  /// waiting until workers are up before a batch.
  std::size_t discover();

  const DispatchStats& lastBatch() const noexcept { return last_; }

 private:
  struct Worker;
  /// discover() with `left_out` (see join()).
  std::size_t lookUp(std::vector<std::string>& left_out);
  /// Connects the workers alive now that are not connected yet, except those named in `left_out`, and adds those
  /// that could not be reached to it.
  void join(const std::vector<std::string>& alive, std::vector<std::string>& left_out);

  std::unique_ptr<WorkerDirectory> directory_;
  std::size_t terms_;
  DispatchConfig config_;
  DispatchStats last_;
  std::vector<std::unique_ptr<Worker>> workers_;
  double rollout_seconds_ = 0.0;  ///< Mean wall time of a rollout on the workers, over every result so far.
  std::size_t timed_ = 0;         ///< Results behind that mean.
  std::map<std::string, std::string> refused_;  ///< Workers that refused a share, and why: never joined again.
};

}  // namespace bimanual_skills::rollout

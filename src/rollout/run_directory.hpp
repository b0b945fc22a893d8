/// \file
/// A learning's run directory (module-private to rollout): the rollouts of earlier runs read back, files that lock
/// the directory to one configuration, every finished rollout appended at once (DIR/rollouts.csv with the task's
/// terms, DIR/rollout_parameters.csv with its latent weights), robot faults logged (DIR/robot_faults.csv), and
/// batches evaluated with what the directory holds taken from it and the robot's faults run again.
#pragma once

#include "bimanual_skills/rollout/dmp_learning.hpp"
#include "io/csv_records.hpp"

#include <functional>
#include <map>
#include <string>
#include <vector>

namespace bimanual_skills::rollout {

class RunDirectory {
 public:
  /// What a batch's evaluation tells its learner, one call at a time.
  struct Hooks {
    /// A rollout ran now (written already); `task` as Evaluator::Done gives it.
    std::function<void(const DmpRolloutRecord&, RolloutTask* task)> ran;
    /// A rollout was taken from the directory.
    std::function<void(const DmpRolloutRecord&)> resumed;
    std::function<void(const DmpRolloutRecord&, int attempt, const std::string& reason, bool retry)> robot_fault;
    std::function<bool()> stop;
  };

  /// Creates `dir` if missing and reads its rollouts (a partial last record of a killed run dropped). `what` names
  /// the learning in errors ("fold learning"). \throws std::invalid_argument for a directory that cannot be made or
  /// that holds files of another task.
  RunDirectory(std::string dir, std::vector<std::string> terms, std::string what, int robot_retries,
               int robot_fault_limit);

  /// Writes `text` to DIR/name, or, when the directory holds rollouts already, checks that it says the same
  /// (`otherwise`: what its rollouts would then be, "scored with another reward").
  void lock(const std::string& name, const std::string& text, const std::string& otherwise);
  /// Opens the files for appending (after the locks).
  void open();

  /// Evaluates a batch (records with coordination, weights and seed set): those the directory holds (with the same
  /// parameters to the bit, else std::invalid_argument) from it, the others by `evaluator`; a result whose outcome is
  /// "RobotFailed" runs again up to robot_retries times and is never written. \throws RobotFaults when the robot
  /// keeps failing, std::runtime_error("stopped") when hooks.stop said so.
  void evaluate(std::vector<DmpRolloutRecord>& batch, Evaluator& evaluator, const Hooks& hooks);

  const std::string& path() const noexcept { return dir_; }
  int ran() const noexcept { return ran_; }
  int resumed() const noexcept { return resumed_; }
  int robotFaults() const noexcept { return robot_faults_; }
  bool holdsRollouts() const noexcept { return !stored_.empty(); }

 private:
  std::string columns() const;
  std::string prefix(const DmpRolloutRecord& rec) const;
  void read();
  void write(const DmpRolloutRecord& rec);
  std::vector<std::size_t> attempt(std::vector<DmpRolloutRecord>& batch, const std::vector<std::size_t>& pending,
                                   int attempt, Evaluator& evaluator, const Hooks& hooks);
  void onRobotFault(const DmpRolloutRecord& rec, int attempt, std::string& fault, const Hooks& hooks);

  std::string dir_, what_;
  std::vector<std::string> terms_;
  int robot_retries_, robot_fault_limit_;
  std::map<std::string, DmpRolloutRecord> stored_;
  io::CsvAppender rollouts_csv_, parameters_csv_, faults_csv_;
  int ran_ = 0, resumed_ = 0, robot_faults_ = 0, faults_in_a_row_ = 0;
};

/// The key of a rollout in its learning: algorithm|run|epoch|kind|index.
std::string rolloutKey(const std::string& algorithm, int run, int epoch, RolloutKind kind, int index);

}  // namespace bimanual_skills::rollout

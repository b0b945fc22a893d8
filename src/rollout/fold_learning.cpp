#include "bimanual_skills/rollout/fold_learning.hpp"

#include "bimanual_skills/learning/gaussian.hpp"
#include "bimanual_skills/primitives/dr_dmp.hpp"
#include "bimanual_skills/realtime/clock.hpp"
#include "bimanual_skills/rollout/fold_rollout_task.hpp"
#include "bimanual_skills/sim/sim_config.hpp"
#include "dmp_search.hpp"
#include "io/csv_records.hpp"
#include "io/yaml_io.hpp"
#include "learning_section.hpp"
#include "run_directory.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <vector>

namespace bimanual_skills::rollout {

namespace {

using realtime::Clock;
using realtime::secondsSince;
constexpr double kInfinity = std::numeric_limits<double>::infinity();

/// Per goal weight the forcing α_z β_z goal_stddev that moves the goal by goal_stddev.
double goalWeightStddev(const FoldLearningConfig& config, const primitives::DmpParameters& dmp) {
  return dmp.alpha_z * dmp.beta_z * config.goal_stddev;
}

}  // namespace

Eigen::VectorXd latentWeightStddev(const FoldLearningConfig& config, const tasks::ClothFoldTask& task) {
  const int basis = task.policyBasisSize();
  const bool goals = task.config().policy == tasks::FoldPolicy::WeightsAndGoals;
  Eigen::VectorXd out = Eigen::VectorXd::Constant(tasks::ClothFoldTask::kDofs * basis, config.initial_stddev);
  if (goals) {
    for (int dof = 0; dof < tasks::ClothFoldTask::kDofs; ++dof) {
      out[dof * basis + basis - 1] = goalWeightStddev(config, task.dmpParameters());
    }
  }
  return out;
}

FoldLearningConfig withSimulationRenderer(FoldLearningConfig config) {
  const vision::RenderNoise noise = config.reward.renderer.noise;
  config.reward.renderer = tasks::rendererFor(sim::SimConfig::fromYamlFile(config.task.sim_config, config.task.robot));
  config.reward.renderer.noise = noise;
  return config;
}

void FoldLearningConfig::validate() const {
  if (algorithms.empty()) throw std::invalid_argument("fold learning: no algorithm");
  for (const std::string& a : algorithms) parseDrDmpVariant(a, tasks::ClothFoldTask::kDofs, eta);
  if (runs < 1 || updates < 0 || rollouts < 2 || reuse < 0 || repetitions < 0 || jobs < 0) {
    throw std::invalid_argument("fold learning: runs >= 1, updates >= 0, rollouts >= 2, reuse, repetitions, jobs >= 0");
  }
  if (!(epsilon > 0.0) || !(eta > 1.0) || !(initial_stddev > 0.0) || !std::isfinite(initial_stddev)) {
    throw std::invalid_argument("fold learning: epsilon > 0, eta > 1 and a finite initial_stddev > 0");
  }
  if (!(goal_stddev > 0.0 && goal_stddev <= 1.0)) throw std::invalid_argument("fold learning: goal_stddev in (0, 1] m");
  if (!(covariance_memory >= 0.0 && covariance_memory < 1.0)) {
    throw std::invalid_argument("fold learning: covariance_memory in [0, 1)");
  }
  if (robot_retries < 0 || robot_retries > 100 || robot_fault_limit < 1 || robot_fault_limit > 1000) {
    throw std::invalid_argument("fold learning: robot_retries in [0, 100] and robot_fault_limit in [1, 1000]");
  }
  reward.validate("fold learning reward");
}

FoldLearningConfig FoldLearningConfig::fromYamlFile(const std::string& path) {
  const std::string where = "fold learning file '" + path + "'";
  const YAML::Node root = io::loadYamlFile(path, where);
  if (!root.IsMap()) io::fail(where + ": must be a map");
  io::checkKeys(root, where, {"sim", "robot", "friction", "task", "reward", "learning"});
  FoldLearningConfig c;
  c.task.sim_config = io::resolvePath(path, io::readString(root, "sim", where));
  if (root["robot"]) c.task.robot = io::resolvePath(path, io::readString(root, "robot", where));
  if (const YAML::Node friction = root["friction"]) {
    if (!friction.IsSequence()) io::fail(where + ": 'friction' must be a list of files, one per arm");
    for (const YAML::Node& file : friction)
      c.task.friction_files.push_back(io::resolvePath(path, file.as<std::string>()));
  }
  if (const YAML::Node task = root["task"]) {
    const std::string at = where + " task";
    io::checkKeys(task, at,
                  {"kernels", "duration", "ik_method", "max_ik_error", "max_tracking_error", "demo_reach", "demo_lift",
                   "demo_drop", "demo_lag", "demonstration", "policy", "velocity_limit", "image_delay", "noise",
                   "cloth_position_noise", "cloth_yaw_noise", "release_noise"});
    if (task["kernels"]) c.task.kernels = io::readInt(task, "kernels", at);
    c.task.duration = io::readDouble(task, "duration", at, c.task.duration);
    if (task["ik_method"]) c.task.ik_method = io::readString(task, "ik_method", at);
    c.task.max_ik_error = io::readDouble(task, "max_ik_error", at, c.task.max_ik_error);
    c.task.max_tracking_error = io::readDouble(task, "max_tracking_error", at, c.task.max_tracking_error);
    if (task["velocity_limit"]) {
      const double limit = io::readDouble(task, "velocity_limit", at, 0.0);
      if (!(limit > 0.0) || !std::isfinite(limit))
        io::fail(at + ": 'velocity_limit' must be a finite speed > 0 [rad/s]");
      c.task.velocity_limit = Eigen::VectorXd::Constant(1, limit);
    }
    c.task.demo_reach = io::readDouble(task, "demo_reach", at, c.task.demo_reach);
    c.task.demo_lift = io::readDouble(task, "demo_lift", at, c.task.demo_lift);
    c.task.demo_drop = io::readDouble(task, "demo_drop", at, c.task.demo_drop);
    c.task.demo_lag = io::readDouble(task, "demo_lag", at, c.task.demo_lag);
    c.task.image_delay = io::readDouble(task, "image_delay", at, c.task.image_delay);
    if (!(c.task.image_delay >= 0.0 && c.task.image_delay <= 60.0))
      io::fail(at + ": 'image_delay' must be in [0, 60] s");
    if (!(c.task.demo_lag >= 0.0 && c.task.demo_lag < 0.9)) io::fail(at + ": 'demo_lag' must be in [0, 0.9)");
    if (task["policy"]) c.task.policy = tasks::foldPolicyFromString(io::readString(task, "policy", at), at);
    if (task["noise"]) c.task.noise = tasks::foldNoiseSetting(io::readString(task, "noise", at), at);
    const tasks::FoldNoise named = c.task.noise;
    c.task.noise.cloth_position = io::readDouble(task, "cloth_position_noise", at, named.cloth_position);
    c.task.noise.cloth_yaw = io::readDouble(task, "cloth_yaw_noise", at, named.cloth_yaw);
    c.task.noise.release_time = io::readDouble(task, "release_noise", at, named.release_time);
    if (task["cloth_position_noise"] || task["cloth_yaw_noise"] || task["release_noise"])
      c.task.noise.setting = "custom";
    c.task.noise.validate(at);
    if (const YAML::Node files = task["demonstration"]) {
      if (!files.IsSequence() || files.size() != 2)
        io::fail(at + ": 'demonstration' must list two DMP files (left, right)");
      for (const YAML::Node& file : files)
        c.task.demonstration_files.push_back(io::resolvePath(path, file.as<std::string>()));
    }
  }
  if (const YAML::Node reward = root["reward"]) {
    const std::string at = where + " reward";
    io::checkKeys(
        reward, at,
        {"setting", "acceleration_weight", "colour_weight", "depth_weight", "goal_weight", "goal_missing_height",
         "goal_excess_height", "fold_weight", "fold_heap_weight", "failure_reward", "depth_noise", "colour_noise"});
    if (reward["setting"]) c.reward = tasks::rewardSetting(c.reward, io::readString(reward, "setting", at), at);
    c.reward.acceleration_weight = io::readDouble(reward, "acceleration_weight", at, c.reward.acceleration_weight);
    c.reward.image.colour_weight = io::readDouble(reward, "colour_weight", at, c.reward.image.colour_weight);
    c.reward.image.depth_weight = io::readDouble(reward, "depth_weight", at, c.reward.image.depth_weight);
    c.reward.image.goal_weight = io::readDouble(reward, "goal_weight", at, c.reward.image.goal_weight);
    c.reward.image.fold_weight = io::readDouble(reward, "fold_weight", at, c.reward.image.fold_weight);
    c.reward.image.fold_heap_weight = io::readDouble(reward, "fold_heap_weight", at, c.reward.image.fold_heap_weight);
    c.reward.image.goal_missing_height =
        io::readDouble(reward, "goal_missing_height", at, c.reward.image.goal_missing_height);
    c.reward.image.goal_excess_height =
        io::readDouble(reward, "goal_excess_height", at, c.reward.image.goal_excess_height);
    c.reward.failure_reward = io::readDouble(reward, "failure_reward", at, c.reward.failure_reward);
    c.reward.renderer.noise.depth_stddev =
        io::readDouble(reward, "depth_noise", at, c.reward.renderer.noise.depth_stddev);
    c.reward.renderer.noise.colour_stddev =
        io::readDouble(reward, "colour_noise", at, c.reward.renderer.noise.colour_stddev);
  }
  if (const YAML::Node learning = root["learning"]) {
    const std::string at = where + " learning";
    readSharedLearning(learning, at, c, {"goal_stddev", "repetitions"});
    c.goal_stddev = io::readDouble(learning, "goal_stddev", at, c.goal_stddev);
    if (learning["repetitions"]) c.repetitions = io::readInt(learning, "repetitions", at);
  }
  io::withContext(where, [&] { c.validate(); });
  return c;
}

struct FoldLearner::Impl {
  FoldLearningConfig config;
  std::string dir;
  FoldLearningObserver observer;
  std::unique_ptr<Evaluator> evaluator;
  ParallelEvaluator* threads = nullptr;     ///< The evaluator when the rollouts run on threads here.
  std::unique_ptr<FoldRolloutTask> helper;  ///< For the demonstration and the images when they run elsewhere.
  std::unique_ptr<RunDirectory> directory;

  /// The reward the directory's rollouts were scored with, DIR/reward.txt: written while the directory holds no
  /// rollout, compared once it does (rollouts scored otherwise must not be reused).
  void lockRewardAndWorld() {
    const tasks::FoldRewardConfig& r = config.reward;
    std::ostringstream text;
    text << "setting " << r.setting << "\nacceleration_weight " << io::exactNumber(r.acceleration_weight)
         << "\ncolour_weight " << io::exactNumber(r.image.colour_weight) << "\ndepth_weight "
         << io::exactNumber(r.image.depth_weight) << "\ngoal_weight " << io::exactNumber(r.image.goal_weight)
         << "\ngoal_missing_height " << io::exactNumber(r.image.goal_missing_height) << "\ngoal_excess_height "
         << io::exactNumber(r.image.goal_excess_height) << "\nfold_weight " << io::exactNumber(r.image.fold_weight)
         << "\nfold_heap_weight " << io::exactNumber(r.image.fold_heap_weight) << "\nfailure_reward "
         << io::exactNumber(r.failure_reward) << "\ndepth_noise " << io::exactNumber(r.renderer.noise.depth_stddev)
         << "\ncolour_noise " << io::exactNumber(r.renderer.noise.colour_stddev) << '\n';
    directory->lock("reward.txt", text.str(), "scored with another reward");
    // The world the rollouts ran in: the simulation file with its URDF and plant (on a robot through ROS the
    // simulator's is checked against it, FoldOnRobotTask).
    // With the robot's noise, its σ too (a world without it writes what it always did).
    std::string world = "sim_config " + sim::SimConfig::worldDigest(config.task.sim_config, config.task.robot) + "\n";
    const tasks::FoldNoise& noise = config.task.noise;
    if (noise.any()) {
      world += "noise cloth_position " + io::exactNumber(noise.cloth_position) + " cloth_yaw " +
               io::exactNumber(noise.cloth_yaw) + " release_time " + io::exactNumber(noise.release_time) + "\n";
    }
    directory->lock("world.txt", world, "run in another world (simulation, URDF or plant file, or the robot's noise)");
  }

  /// Evaluates a batch (records with coordination, weights and seed set): stored ones from the directory, the others
  /// on the evaluator (RunDirectory::evaluate).
  void evaluate(std::vector<FoldRolloutRecord>& batch) {
    std::vector<DmpRolloutRecord> records(batch.size());
    for (std::size_t i = 0; i < batch.size(); ++i) {
      const FoldRolloutRecord& rec = batch[i];
      DmpRolloutRecord& r = records[i];
      r.algorithm = rec.algorithm;
      r.run = rec.run;
      r.epoch = rec.epoch;
      r.index = rec.index;
      r.kind = rec.kind;
      r.seed = rec.seed;
      r.coordination = rec.coordination;
      r.weights = rec.weights;
    }
    const auto take = [&](const DmpRolloutRecord& r) -> FoldRolloutRecord& {
      FoldRolloutRecord& rec = batch[static_cast<std::size_t>(&r - records.data())];
      rec.terms = FoldRolloutTask::termsOf(r.result);
      rec.reason = r.result.reason;
      rec.wall_seconds = r.result.wall_seconds;
      rec.resumed = r.resumed;
      return rec;
    };
    RunDirectory::Hooks hooks;
    hooks.resumed = [&](const DmpRolloutRecord& r) {
      FoldRolloutRecord& rec = take(r);
      if (observer.rollout) observer.rollout(rec, tasks::FoldRollout{}, firstTask().reward());
    };
    hooks.ran = [&](const DmpRolloutRecord& r, RolloutTask* task) { show(take(r), task, r.result); };
    hooks.robot_fault = [&](const DmpRolloutRecord& r, int attempt, const std::string& reason, bool retry) {
      if (observer.robot_fault) observer.robot_fault(take(r), attempt, reason, retry);
    };
    hooks.stop = observer.stop;
    directory->evaluate(records, *evaluator, hooks);
  }

  /// Under the evaluator's lock: a rollout the robot ran, shown.
  void show(const FoldRolloutRecord& rec, RolloutTask* task, const RolloutResult& result) {
    if (!observer.rollout) return;
    if (auto* fold = dynamic_cast<FoldRolloutTask*>(task)) {
      observer.rollout(rec, fold->lastRollout(), fold->reward());
    } else if (const auto* recorded = dynamic_cast<const RecordedFoldTask*>(task)) {
      observer.rollout(rec, recorded->lastRecording(), firstTask().reward());
    } else {
      tasks::FoldRollout paths;
      paths.actual_path = FoldRolloutTask::toolPaths(result);
      observer.rollout(rec, paths, firstTask().reward());
    }
  }

  FoldRolloutTask& firstTask() { return helper ? *helper : static_cast<FoldRolloutTask&>(threads->task(0)); }

  FoldEpochStats epochStats(const std::string& algorithm, int run, int epoch, int latent_dims,
                            const std::vector<FoldRolloutRecord>& batch) const {
    FoldEpochStats s;
    s.algorithm = algorithm;
    s.run = run;
    s.epoch = epoch;
    s.latent_dims = latent_dims;
    double sum = 0.0, squares = 0.0;
    int samples = 0;
    for (const FoldRolloutRecord& rec : batch) {
      if (rec.kind != RolloutKind::Sample) continue;
      ++samples;
      sum += rec.terms.reward;
      squares += rec.terms.reward * rec.terms.reward;
      if (rec.terms.outcome != tasks::FoldOutcome::Ok) ++s.failures;
    }
    s.mean_reward = sum / samples;
    s.std_reward = samples > 1
                       ? std::sqrt(std::max(0.0, (squares - samples * s.mean_reward * s.mean_reward) / (samples - 1)))
                       : 0.0;
    for (const FoldRolloutRecord& rec : batch) {
      if (rec.kind != RolloutKind::Policy) continue;
      s.policy_reward = rec.terms.reward;
      s.policy_fold_quality = rec.terms.fold_quality;
      s.policy_failed = rec.terms.outcome != tasks::FoldOutcome::Ok;
    }
    // Every sample counts, failures included with the terms measured on the cloth they left (a rollout stopped
    // before the fold left it flat: q = 0).
    for (const FoldRolloutRecord& rec : batch) {
      if (rec.kind != RolloutKind::Sample) continue;
      s.r_acceleration += rec.terms.r_acceleration;
      s.r_color += rec.terms.r_color;
      s.r_depth += rec.terms.r_depth;
      s.fill_ratio += rec.terms.fill_ratio;
      s.mean_gradient += rec.terms.mean_gradient;
      s.area_ratio += rec.terms.area_ratio;
      s.r_goal += rec.terms.r_goal;
      s.goal_mismatch += rec.terms.goal_mismatch;
      s.r_fold += rec.terms.r_fold;
      s.fold_mismatch += rec.terms.fold_mismatch;
      s.fold_quality += rec.terms.fold_quality;
      s.fold_quality_std += rec.terms.fold_quality * rec.terms.fold_quality;
    }
    for (double* v : {&s.r_acceleration, &s.r_color, &s.r_depth, &s.fill_ratio, &s.mean_gradient, &s.area_ratio,
                      &s.r_goal, &s.goal_mismatch, &s.r_fold, &s.fold_mismatch, &s.fold_quality, &s.fold_quality_std}) {
      *v /= samples;
    }
    // Sample standard deviation of q (the second moment is in fold_quality_std so far).
    s.fold_quality_std = samples > 1 ? std::sqrt(std::max(0.0, (s.fold_quality_std - s.fold_quality * s.fold_quality) *
                                                                   samples / (samples - 1.0)))
                                     : 0.0;
    return s;
  }

  /// Rewrites epochs.csv: the finished runs, then the epochs so far of the current one.
  void writeEpochs(const std::vector<FoldRunResult>& finished, const FoldRunResult& current) const {
    std::ofstream csv(dir + "/epochs.csv");
    csv << "algorithm,run,epoch,latent_dims,failures,mean_reward,std_reward,r_acceleration,r_color,r_depth,"
           "fill_ratio,mean_gradient,area_ratio,r_goal,goal_mismatch,r_fold,fold_mismatch,fold_quality,fold_quality_"
           "std,"
           "policy_reward,policy_fold_quality,policy_failed\n";
    std::vector<const FoldRunResult*> runs;
    for (const FoldRunResult& run : finished) runs.push_back(&run);
    runs.push_back(&current);
    for (const FoldRunResult* run : runs) {
      for (const FoldEpochStats& s : run->epochs) {
        csv << io::quotedField(s.algorithm) << ',' << s.run << ',' << s.epoch << ',' << s.latent_dims << ','
            << s.failures << ',' << io::exactNumber(s.mean_reward) << ',' << io::exactNumber(s.std_reward) << ','
            << io::exactNumber(s.r_acceleration) << ',' << io::exactNumber(s.r_color) << ','
            << io::exactNumber(s.r_depth) << ',' << io::exactNumber(s.fill_ratio) << ','
            << io::exactNumber(s.mean_gradient) << ',' << io::exactNumber(s.area_ratio) << ','
            << io::exactNumber(s.r_goal) << ',' << io::exactNumber(s.goal_mismatch) << ',' << io::exactNumber(s.r_fold)
            << ',' << io::exactNumber(s.fold_mismatch) << ',' << io::exactNumber(s.fold_quality) << ','
            << io::exactNumber(s.fold_quality_std) << ',' << io::exactNumber(s.policy_reward) << ','
            << io::exactNumber(s.policy_fold_quality) << ',' << (s.policy_failed ? 1 : 0) << '\n';
      }
    }
  }

  /// coordination.csv: every run's final coordination matrices; initial_coordination.csv: its first policy's (the
  /// demonstration's PCA for the IDR learners), so that what learning changed in them can be told from what the
  /// demonstration put there.
  void writeCoordination(const std::vector<FoldRunResult>& runs) const {
    const auto write = [&](const std::string& name, const auto& matrices_of) {
      std::ofstream csv(dir + "/" + name);
      csv << "algorithm,run,matrix,row,values...\n";
      for (const FoldRunResult& run : runs) {
        const std::vector<Eigen::MatrixXd>& matrices = matrices_of(run);
        for (std::size_t s = 0; s < matrices.size(); ++s) {
          const Eigen::MatrixXd& omega = matrices[s];
          for (Eigen::Index i = 0; i < omega.rows(); ++i) {
            csv << io::quotedField(run.algorithm) << ',' << run.run << ',' << s << ',' << i;
            for (Eigen::Index j = 0; j < omega.cols(); ++j) csv << ',' << io::exactNumber(omega(i, j));
            csv << '\n';
          }
        }
      }
    };
    write("coordination.csv",
          [](const FoldRunResult& run) -> const std::vector<Eigen::MatrixXd>& { return run.final.coordination; });
    write("initial_coordination.csv", [](const FoldRunResult& run) -> const std::vector<Eigen::MatrixXd>& {
      return run.initial_policy.coordination;
    });
  }

  FoldRunResult learnRun(const std::string& algorithm, int algorithm_index, int run,
                         const std::vector<FoldRunResult>& done) {
    const auto start = Clock::now();
    const DrDmpVariant variant = parseDrDmpVariant(algorithm, tasks::ClothFoldTask::kDofs, config.eta);
    const tasks::ClothFoldTask& task = firstTask().task();
    const primitives::DrDmpParameters parameters = task.forcingParameters(variant.matrices);
    DmpSearch::Settings settings;
    settings.epsilon = config.epsilon;
    settings.reuse = config.reuse;
    settings.covariance_memory = config.covariance_memory;
    settings.initial_stddev = config.initial_stddev;
    settings.goal_stddev = goalWeightStddev(config, parameters.dmp);
    DmpSearch search(variant, parameters, task.demonstrationTrajectory(), task.demonstrationStep(), settings);
    FoldRunResult result;
    result.best.terms.reward = -kInfinity;
    searchRun<FoldRolloutRecord>(
        search, algorithm, algorithm_index, run, config.seed, config.updates, config.rollouts, result,
        [this](std::vector<FoldRolloutRecord>& batch) { evaluate(batch); },
        [](const FoldRolloutRecord& rec) { return rec.terms.reward; },
        [](const FoldRolloutRecord& rec) { return rec.terms.outcome == tasks::FoldOutcome::Ok; },
        [&](int epoch, int latent_dims, const std::vector<FoldRolloutRecord>& batch) {
          result.epochs.push_back(epochStats(algorithm, run, epoch, latent_dims, batch));
          if (observer.epoch) observer.epoch(result.epochs.back());
          writeEpochs(done, result);
        });
    result.final = search.policy();
    result.seconds = secondsSince(start);
    return result;
  }
};

FoldLearner::FoldLearner(const FoldLearningConfig& config, const std::string& out_dir, FoldLearningObserver observer,
                         std::unique_ptr<Evaluator> evaluator)
    : impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  config.validate();
  m.dir = out_dir;
  m.observer = std::move(observer);
  m.directory = std::make_unique<RunDirectory>(out_dir, FoldRolloutTask::names(), "fold learning", config.robot_retries,
                                               config.robot_fault_limit);
  m.config = withSimulationRenderer(config);
  if (evaluator) {
    m.evaluator = std::move(evaluator);
    m.helper = std::make_unique<FoldRolloutTask>(m.config.task, m.config.reward);
  } else {
    auto threads = std::make_unique<ParallelEvaluator>(
        [&m] { return std::make_unique<FoldRolloutTask>(m.config.task, m.config.reward); }, config.jobs);
    m.threads = threads.get();
    m.config.jobs = threads->threads();
    m.evaluator = std::move(threads);
  }
  m.lockRewardAndWorld();
  m.directory->open();
  m.firstTask().task().saveDemonstration(out_dir + "/demonstration_");
}

FoldLearner::~FoldLearner() = default;

const FoldLearningConfig& FoldLearner::config() const noexcept {
  return impl_->config;
}

FoldLearningResult FoldLearner::learn() {
  Impl& m = *impl_;
  const auto start = Clock::now();
  FoldLearningResult result;
  if (m.config.repetitions > 0) {
    const tasks::ClothFoldTask& task = m.firstTask().task();
    std::seed_seq sequence{m.config.seed, 0xde70u};
    std::mt19937 rng(sequence);
    std::vector<FoldRolloutRecord> batch;
    for (int k = 0; k < m.config.repetitions; ++k) {
      FoldRolloutRecord rec;
      rec.algorithm = "demonstration";
      rec.kind = RolloutKind::Repetition;
      rec.index = k;
      rec.coordination = {Eigen::MatrixXd::Identity(tasks::ClothFoldTask::kDofs, tasks::ClothFoldTask::kDofs)};
      rec.weights = task.demonstrationParameters();  // the latent weights of Ω = I
      rec.seed = static_cast<std::uint32_t>(rng());
      batch.push_back(rec);
    }
    m.evaluate(batch);
    result.repetitions = batch;
  }
  for (std::size_t a = 0; a < m.config.algorithms.size(); ++a) {
    for (int run = 0; run < m.config.runs; ++run) {
      result.runs.push_back(m.learnRun(m.config.algorithms[a], static_cast<int>(a), run, result.runs));
      m.writeCoordination(result.runs);
    }
  }
  result.simulated = m.directory->ran();
  result.resumed = m.directory->resumed();
  result.robot_faults = m.directory->robotFaults();
  result.seconds = secondsSince(start);
  return result;
}

tasks::FoldRollout FoldLearner::replay(const FoldRolloutRecord& record, double cloth_rate) {
  tasks::ClothFoldConfig task = impl_->config.task;
  task.cloth_rate = cloth_rate;
  tasks::ClothFoldTask replay(task);
  return replay.run(record.coordination, record.weights, record.seed);
}

tasks::FoldRewardTerms FoldLearner::score(const tasks::FoldRollout& rollout, std::uint32_t seed, cv::Mat& bgr,
                                          cv::Mat& depth) {
  FoldRolloutTask& task = impl_->firstTask();
  const tasks::FoldRewardTerms terms = task.score(rollout, seed);
  task.reward().bgr().copyTo(bgr);
  task.reward().depth().copyTo(depth);
  return terms;
}

}  // namespace bimanual_skills::rollout

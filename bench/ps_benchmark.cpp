// The thesis' policy-search experiments (Ch. 6: Figs. 6.5–6.7, 6.10–6.12, 6.14) and the classic PI2 via-point task,
// as one seeded program.
//
//   ps_benchmark --experiment multimodal2d|multimodal_scale|bottles|wam_bottles|wam_bottles617|wam_guided|circle|
//                             pi2viapoint|all
//                --runs R --seed S --out DIR [--quick] [--jobs N] [--worker-namespace NS | --workers A,B,...]
//                [--worker-timeout S]
//
// Writes DIR/<experiment>.csv (one row per run and update, appended as each run ends), DIR/summary.json, then runs
// scripts/plot_ps_benchmark.py for the learning-curve PNGs (mean ± 2 std over runs) and DIR/tables.md.
//
// With --worker-namespace or --workers, each update's rollouts run on rollout_worker nodes (nodes/rollout_worker.cpp,
// over the ROS master at ROS_MASTER_URI) as the registry's task of the experiment (rollout/task_registry.hpp), which
// computes the same rewards bit for bit: the CSVs are those of the run in this process.
#include "bimanual_skills/learning/dual_reps.hpp"
#include "bimanual_skills/learning/gaussian.hpp"
#include "bimanual_skills/learning/pi2.hpp"
#include "bimanual_skills/parallel/parallel_for.hpp"
#include "bimanual_skills/realtime/clock.hpp"
#include "bimanual_skills/rollout/dispatcher.hpp"
#include "bimanual_skills/rollout/task_registry.hpp"
#include "bimanual_skills/ros_layer/workers/topic_workers.hpp"
#include "bimanual_skills/tasks/human_guidance.hpp"
#include "bimanual_skills/tasks/policy_search_tasks.hpp"
#include "bimanual_skills/tasks/wam_bottles.hpp"
#include "cli/package_share.hpp"
#include "cli/pinned_numerics.hpp"
#include "experiment_cli.hpp"
#include "parallel_runs.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <memory>
#include <mutex>
#include <numeric>
#include <optional>
#include <random>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace bk = bimanual_skills::kinematics;
namespace bl = bimanual_skills::learning;
namespace br = bimanual_skills::rollout;
namespace bt = bimanual_skills::tasks;

namespace {

using Options = bimanual_skills::bench::ExperimentOptions;

/// An episodic task: the reward of a parameter vector (higher is better).
using Reward = std::function<double(const Eigen::VectorXd&)>;

/// The rollout workers of --worker-namespace / --workers; none selected: the rollouts run here.
struct WorkerOptions {
  std::string space;
  std::string names;
  double timeout = 60.0;
  bool selected() const { return !space.empty() || !names.empty(); }
};

/// An experiment's rollouts in batches: on rollout workers, as the registry task `task` (configured by the file
/// `config`), or on threads of this process (the same task, one per thread). Each sample's reward and, for PI2, its
/// step costs (the task's terms but the last). A rollout that failed (the WAM's controller stopped it) counts with
/// the task's failure reward.
class BatchRollouts {
 public:
  /// On the workers of `options`.
  BatchRollouts(const WorkerOptions& options, const std::string& task, const std::string& config)
      : where_("workers"), terms_(br::makeRolloutTask(task, config)->termNames().size()) {
    bimanual_skills::ros_layer::WorkerSelection selection;
    selection.task = task;
    selection.config = config;
    if (options.names.empty()) {
      selection.space = options.space;
    } else {
      selection.names = bimanual_skills::ros_layer::splitWorkerNames(options.names);
    }
    br::DispatchConfig dispatch;
    dispatch.timeout = options.timeout;
    dispatch.log = [](const std::string& line, bool) {
      std::printf("  [workers] %s\n", line.c_str());
      std::fflush(stdout);
    };
    dispatch.batch = [this](const br::DispatchStats& s) {
      redispatched_ += s.redispatched;
      workers_ = std::max(workers_, s.workers);
    };
    evaluator_ = std::make_unique<br::Dispatcher>(
        std::make_unique<bimanual_skills::ros_layer::TopicWorkerDirectory>(selection), terms_, dispatch);
  }
  /// On `threads` threads here.
  BatchRollouts(const std::string& task, const std::string& config, int threads)
      : where_("threads"), terms_(br::makeRolloutTask(task, config)->termNames().size()) {
    evaluator_ =
        std::make_unique<br::ParallelEvaluator>([task, config] { return br::makeRolloutTask(task, config); }, threads);
    workers_ = static_cast<std::size_t>(threads);
  }

  /// The rewards of the rows of `samples`, and their step costs when `costs` is given.
  void evaluate(const Eigen::MatrixXd& samples, Eigen::VectorXd& rewards, Eigen::MatrixXd* costs) {
    std::vector<br::RolloutRequest> batch(static_cast<std::size_t>(samples.rows()));
    for (Eigen::Index k = 0; k < samples.rows(); ++k) {
      batch[static_cast<std::size_t>(k)] = {samples.row(k).transpose(), static_cast<std::uint32_t>(k)};
    }
    const auto start = std::chrono::steady_clock::now();
    const std::vector<br::RolloutResult> results = evaluator_->evaluate(batch);
    seconds_ += bimanual_skills::realtime::secondsSince(start);
    ++batches_;
    rollouts_ += results.size();
    if (costs != nullptr) costs->resize(samples.rows(), static_cast<Eigen::Index>(terms_) - 1);
    for (Eigen::Index k = 0; k < samples.rows(); ++k) {
      const br::RolloutResult& r = results[static_cast<std::size_t>(k)];
      if (!r.ok) {
        ++failed_;
        if (failures_.size() < 3) failures_.push_back(r.outcome + ": " + r.reason);
      }
      rewards[k] = r.reward;
      if (costs != nullptr) costs->row(k) = r.terms.head(costs->cols()).transpose();
    }
  }

  std::size_t failed() const { return failed_; }
  std::size_t rollouts() const { return rollouts_; }

  void report(const std::string& experiment) const {
    std::printf("  %s on %s: %zu rollouts in %zu batches on up to %zu %s, %zu re-dispatched, %zu failed, %.2f s\n",
                experiment.c_str(), where_.c_str(), rollouts_, batches_, workers_, where_.c_str(), redispatched_,
                failed_, seconds_);
    for (const std::string& f : failures_) std::printf("    e.g. %s\n", f.c_str());
    std::fflush(stdout);
  }

 private:
  std::string where_;
  std::size_t terms_;
  std::unique_ptr<br::Evaluator> evaluator_;
  std::size_t batches_ = 0, rollouts_ = 0, redispatched_ = 0, workers_ = 0, failed_ = 0;
  std::vector<std::string> failures_;
  double seconds_ = 0.0;
};

/// A learner: REPS, DREPS variants or PI2 variants, updating N(mean, covariance) from rollouts.
struct Algorithm {
  std::string name;
  std::function<void(std::mt19937&)> reset;  ///< New learner state for a run.
  /// New policy from this update's samples and rewards (per-step costs for PI2 come through `costs`).
  std::function<void(Eigen::VectorXd& mean, Eigen::MatrixXd& covariance, const Eigen::MatrixXd& samples,
                     const Eigen::VectorXd& rewards, const Eigen::MatrixXd& costs)>
      update;
};

struct Protocol {
  int runs = 50;
  int updates = 50;
  int rollouts = 50;
  Eigen::VectorXd mean;
  Eigen::MatrixXd covariance;
};

/// The protocol of an experiment: `runs` (or --runs) runs of `updates` updates of `rollouts` rollouts, or the
/// `quick_runs` × `quick_updates` smoke version, from N(mean, σ² I).
Protocol makeProtocol(const Options& options, int runs, int quick_runs, int updates, int quick_updates, int rollouts,
                      const Eigen::VectorXd& mean, double sigma) {
  Protocol protocol;
  protocol.runs = options.runs > 0 ? options.runs : (options.quick ? quick_runs : runs);
  protocol.updates = options.quick ? quick_updates : updates;
  protocol.rollouts = rollouts;
  protocol.mean = mean;
  protocol.covariance = sigma * sigma * Eigen::MatrixXd::Identity(mean.size(), mean.size());
  return protocol;
}

/// One run's learning curve: the reward of the mean policy before the first update and after each one, and the
/// mean reward of each update's rollouts.
struct Curve {
  std::vector<double> policy_reward;
  std::vector<double> rollout_reward;
  std::vector<Eigen::VectorXd> means;
  double final_stddev = 0.0;  ///< √(trace Σ / n) of the last policy: how much it still explores.
  double seconds = 0.0;
};

/// Rollouts of every update of one run, here or on `workers`; per-step costs only when `step_costs` is given (PI2).
Curve learn(const Protocol& protocol, const Algorithm& algorithm, const Reward& reward, std::mt19937& rng,
            BatchRollouts* workers, const std::function<Eigen::VectorXd(const Eigen::VectorXd&)>& step_costs) {
  Curve curve;
  Eigen::VectorXd mean = protocol.mean;
  Eigen::MatrixXd covariance = protocol.covariance;
  bl::GaussianSampler sampler;
  algorithm.reset(rng);
  curve.policy_reward.push_back(reward(mean));
  curve.means.push_back(mean);
  const auto start = std::chrono::steady_clock::now();
  for (int u = 0; u < protocol.updates; ++u) {
    const Eigen::MatrixXd L = bl::choleskyFactor(covariance);
    Eigen::MatrixXd samples(protocol.rollouts, mean.size());
    Eigen::VectorXd rewards(protocol.rollouts);
    Eigen::MatrixXd costs;
    for (int k = 0; k < protocol.rollouts; ++k) samples.row(k) = sampler.draw(mean, L, rng).transpose();
    for (int k = 0; workers == nullptr && k < protocol.rollouts; ++k) {
      if (step_costs) {
        const Eigen::VectorXd c = step_costs(samples.row(k).transpose());
        if (costs.size() == 0) costs.resize(protocol.rollouts, c.size());
        costs.row(k) = c.transpose();
        rewards[k] = -c.sum();
      } else {
        rewards[k] = reward(samples.row(k).transpose());
      }
    }
    if (workers != nullptr) workers->evaluate(samples, rewards, step_costs ? &costs : nullptr);
    algorithm.update(mean, covariance, samples, rewards, costs);
    curve.policy_reward.push_back(reward(mean));
    curve.rollout_reward.push_back(rewards.mean());
    curve.means.push_back(mean);
  }
  curve.seconds = bimanual_skills::realtime::secondsSince(start);
  curve.final_stddev = std::sqrt(covariance.trace() / static_cast<double>(covariance.rows()));
  return curve;
}

Algorithm repsAlgorithm(const std::string& name, const bl::DualRepsParameters& parameters) {
  auto learner = std::make_shared<std::optional<bl::DualReps>>();
  return {name, [learner, parameters](std::mt19937&) { learner->emplace(parameters); },
          [learner](Eigen::VectorXd& mean, Eigen::MatrixXd& covariance, const Eigen::MatrixXd& samples,
                    const Eigen::VectorXd& rewards, const Eigen::MatrixXd&) {
            const bl::DualRepsUpdate update = (*learner)->update(mean, covariance, samples, rewards);
            mean = update.policy.mean;
            covariance = update.policy.covariance;
          }};
}

/// The three algorithms of the thesis' comparisons (Sec. 6.1.3): REPS, nDREPS (3 repulsive clusters, no attractive)
/// and DREPS (1 attractive, up to 4 repulsive chosen by the 2-cluster split), ξ = 5, χ = 2ε.
std::vector<Algorithm> repsFamily(double epsilon, int reuse, bool with_ndreps) {
  const bl::DualRepsParameters dreps = bl::thesisDreps(epsilon, reuse);
  const bl::DualRepsParameters reps = bl::thesisReps(epsilon, reuse);
  std::vector<Algorithm> out = {repsAlgorithm("REPS", reps)};
  if (with_ndreps) {
    bl::DualRepsParameters ndreps = dreps;
    ndreps.clusters = 4;
    ndreps.max_attractive = 0;
    ndreps.max_repulsive = 3;
    ndreps.split_repulsive = false;
    out.push_back(repsAlgorithm("nDREPS", ndreps));
  }
  out.push_back(repsAlgorithm("DREPS", dreps));
  return out;
}

/// Row of summary.json: one algorithm of one experiment.
struct Summary {
  std::string experiment, algorithm;
  int runs = 0, updates = 0, rollouts = 0;
  double final_reward_mean = 0.0, final_reward_std = 0.0, seconds_per_update = 0.0;
  std::vector<std::pair<std::string, double>> extra;  ///< Experiment-specific fields.
};

class Writer {
 public:
  Writer(const Options& options, const std::string& experiment)
      : csv_(options.out + "/" + experiment + ".csv"), experiment_(experiment) {
    csv_ << "experiment,algorithm,run,update,policy_reward,rollout_reward\n";
  }
  void add(const std::string& algorithm, int run, const Curve& curve) {
    for (std::size_t u = 0; u < curve.policy_reward.size(); ++u) {
      csv_ << experiment_ << ',' << algorithm << ',' << run << ',' << u << ',' << curve.policy_reward[u] << ','
           << (u > 0 ? curve.rollout_reward[u - 1] : curve.policy_reward[0]) << '\n';
    }
    csv_.flush();
  }

 private:
  std::ofstream csv_;
  std::string experiment_;
};

Summary summarise(const std::string& experiment, const std::string& algorithm, const Protocol& protocol,
                  const std::vector<Curve>& curves) {
  Summary s;
  s.experiment = experiment;
  s.algorithm = algorithm;
  s.runs = static_cast<int>(curves.size());
  s.updates = protocol.updates;
  s.rollouts = protocol.rollouts;
  double sum = 0.0, squares = 0.0, seconds = 0.0;
  for (const Curve& c : curves) {
    sum += c.policy_reward.back();
    squares += c.policy_reward.back() * c.policy_reward.back();
    seconds += c.seconds;
  }
  const double n = static_cast<double>(curves.size());
  s.final_reward_mean = sum / n;
  s.final_reward_std = std::sqrt(std::max(0.0, squares / n - s.final_reward_mean * s.final_reward_mean));
  s.seconds_per_update = seconds / (n * protocol.updates);
  return s;
}

void progress(const std::string& experiment, const std::string& algorithm, int run, int runs, const Curve& curve) {
  if ((run + 1) % std::max(1, runs / 10) == 0 || run + 1 == runs) {
    std::printf("  %s %s: run %d/%d, final policy reward %.3f (%.2f s)\n", experiment.c_str(), algorithm.c_str(),
                run + 1, runs, curve.policy_reward.back(), curve.seconds);
    std::fflush(stdout);
  }
}

/// Every run of one algorithm (each with its own generator, the same for every algorithm): learns, appends the CSV,
/// prints progress; `each` sees every finished curve.
std::vector<Curve> runAll(const Options& options, const std::string& experiment, const Protocol& protocol,
                          const Algorithm& algorithm, const Reward& reward, Writer& writer,
                          const std::function<void(const Curve&)>& each, BatchRollouts* workers,
                          const std::function<Eigen::VectorXd(const Eigen::VectorXd&)>& step_costs = {}) {
  std::vector<Curve> curves;
  for (int run = 0; run < protocol.runs; ++run) {
    std::mt19937 rng = bimanual_skills::bench::runGenerator(options, experiment, run);
    curves.push_back(learn(protocol, algorithm, reward, rng, workers, step_costs));
    writer.add(algorithm.name, run, curves.back());
    progress(experiment, algorithm.name, run, protocol.runs, curves.back());
    each(curves.back());
  }
  return curves;
}

/// The rollouts of an experiment on the selected workers (the registry's `task`, configured by `config`), or null
/// when none is selected (the rollouts run here).
std::unique_ptr<BatchRollouts> onWorkers(const WorkerOptions& workers, const std::string& task,
                                         const std::string& config = "") {
  return workers.selected() ? std::make_unique<BatchRollouts>(workers, task, config) : nullptr;
}

/// Writes a task configuration for the workers to DIR/worker_tasks/NAME.yaml (an absolute path, which workers on
/// other hosts see when DIR is on a file system they share) and returns its path.
std::string workerTaskConfig(const Options& options, const std::string& name, const std::string& yaml) {
  const std::filesystem::path dir = std::filesystem::absolute(options.out) / "worker_tasks";
  std::filesystem::create_directories(dir);
  const std::string path = (dir / (name + ".yaml")).string();
  std::ofstream file(path);
  file << yaml;
  if (!file.flush()) throw std::runtime_error("cannot write " + path);
  return path;
}

// ---- multimodal2d: the 3-optimum reward (6.16) ----

void multimodal2d(const Options& options, const WorkerOptions& worker_options, std::vector<Summary>& out) {
  // Three optima around the initial mean (their centroid is the origin, the worst point).
  const bt::MultimodalReward reward;
  const std::vector<Eigen::VectorXd>& psi = reward.optima;
  double best = -1e300;
  for (const auto& p : psi) best = std::max(best, reward(p));
  const double threshold = best - 0.5;
  const Protocol protocol = makeProtocol(options, 50, 3, 40, 8, 100, Eigen::VectorXd::Zero(2), 1.0);
  const std::unique_ptr<BatchRollouts> workers = onWorkers(worker_options, "multimodal");
  Writer writer(options, "multimodal2d");
  for (const Algorithm& algorithm : repsFamily(0.5, 400, true)) {
    int plateau_runs = 0, reached = 0;
    double updates_to_threshold = 0.0;
    const auto each = [&](const Curve& c) {
      // Plateau: the mean stays >= 3 updates between two optima (> 0.5 from each of its two nearest, whose
      // distances differ by < 50 %) before the reward threshold is reached.
      int between = 0, longest = 0;
      for (std::size_t u = 0; u < c.means.size(); ++u) {
        if (c.policy_reward[u] >= threshold) {
          reached += 1;
          updates_to_threshold += static_cast<double>(u);
          break;
        }
        std::vector<double> d;
        for (const auto& p : psi) d.push_back((c.means[u] - p).norm());
        std::sort(d.begin(), d.end());
        between = (d[0] > 0.5 && d[1] < 1.5 * d[0]) ? between + 1 : 0;
        longest = std::max(longest, between);
      }
      if (longest >= 3) ++plateau_runs;
    };
    const std::vector<Curve> curves =
        runAll(options, "multimodal2d", protocol, algorithm, reward, writer, each, workers.get());
    Summary s = summarise("multimodal2d", algorithm.name, protocol, curves);
    s.extra = {{"plateau_runs", plateau_runs},
               {"runs_reaching_threshold", reached},
               {"reward_threshold", threshold},
               {"mean_updates_to_threshold", reached > 0 ? updates_to_threshold / reached : -1.0}};
    out.push_back(s);
  }
  if (workers) workers->report("multimodal2d");
}

// ---- multimodal_scale: DREPS at scale, (6.16) in 20, 50 and 100 dimensions (Sec. 6.1.3, Appendix B.5) ----

void multimodalScale(const Options& options, const WorkerOptions& worker_options, std::vector<Summary>& out) {
  for (const int d : {20, 50, 100}) {
    const bt::MultimodalReward reward = bt::MultimodalReward::inDimension(d);
    const double best = reward(reward.optima.front()), threshold = best - 0.5;
    // As multimodal2d: from N(0, I), 100 rollouts per update reusing up to 400; longer, the space being larger.
    const Protocol protocol = makeProtocol(options, 20, 3, 100, 8, 100, Eigen::VectorXd::Zero(d), 1.0);
    const std::string experiment = "multimodal" + std::to_string(d);
    const std::unique_ptr<BatchRollouts> workers =
        onWorkers(worker_options, "multimodal",
                  worker_options.selected() ? workerTaskConfig(options, experiment,
                                                               "# ps_benchmark " + experiment +
                                                                   ": reward (6.16)\n"
                                                                   "dimension: " +
                                                                   std::to_string(d) + "\n")
                                            : "");
    Writer writer(options, experiment);
    for (const Algorithm& algorithm : repsFamily(0.5, 400, false)) {
      int reached = 0, at_optimum = 0;
      double updates_to_threshold = 0.0, nearest_sum = 0.0, stddev_sum = 0.0;
      const auto each = [&](const Curve& c) {
        for (std::size_t u = 0; u < c.policy_reward.size(); ++u) {
          if (c.policy_reward[u] >= threshold) {
            reached += 1;
            updates_to_threshold += static_cast<double>(u);
            break;
          }
        }
        // At an optimum: the final mean within 0.5 of one (the optima are 3.6–4 apart).
        double nearest = 1e300;
        for (const Eigen::VectorXd& p : reward.optima) nearest = std::min(nearest, (c.means.back() - p).norm());
        at_optimum += nearest < 0.5 ? 1 : 0;
        nearest_sum += nearest;
        stddev_sum += c.final_stddev;
      };
      const std::vector<Curve> curves =
          runAll(options, experiment, protocol, algorithm, reward, writer, each, workers.get());
      Summary s = summarise(experiment, algorithm.name, protocol, curves);
      s.extra = {{"dimension", d},
                 {"runs_reaching_threshold", reached},
                 {"runs_ending_at_an_optimum", at_optimum},
                 {"mean_final_distance_to_nearest_optimum", nearest_sum / protocol.runs},
                 {"mean_final_stddev", stddev_sum / protocol.runs},
                 {"reward_threshold", threshold},
                 {"mean_updates_to_threshold", reached > 0 ? updates_to_threshold / reached : -1.0}};
      out.push_back(s);
    }
    if (workers) workers->report(experiment);
  }
}

// ---- bottles: the planar bottle-avoidance task (Figs. 6.8–6.12, rewards 6.17 and 6.18) ----

void bottles(const Options& options, const WorkerOptions& worker_options, std::vector<Summary>& out) {
  const bt::DmpRollout task = bt::BottleTask::initialPolicy();
  const Protocol protocol = makeProtocol(options, 50, 3, 100, 10, 50, task.parameters(), 60.0);
  Eigen::MatrixXd y, ydd;
  // First with (6.17) (Fig. 6.10: any path that knocks no bottle down is a solution), then with (6.18).
  for (const bool crossing_term : {false, true}) {
    bt::BottleTask world;
    world.crossing_term = crossing_term;
    const std::string experiment = crossing_term ? "bottles" : "bottles617";
    const std::unique_ptr<BatchRollouts> workers =
        onWorkers(worker_options, "bottles",
                  worker_options.selected() && !crossing_term
                      ? workerTaskConfig(options, "bottles617",
                                         "# ps_benchmark bottles617: reward (6.17)\ncrossing_term: false\n")
                      : "");
    const Reward reward = [&](const Eigen::VectorXd& theta) {
      task.rollout(theta, y, ydd);
      return world.reward(y);
    };
    Writer writer(options, experiment);
    for (const Algorithm& algorithm : repsFamily(0.5, 200, false)) {
      int satisfactory_runs = 0, clear_runs = 0;
      double unsatisfactory_sum = 0.0, updates_to_clear = 0.0;
      const auto each = [&](const Curve& c) {
        // Clear: the mean policy knocks no bottle down (reward > −1 under 6.17); the first update where it is.
        const bool reached = c.policy_reward.back() > -1.0;
        for (std::size_t u = 0; reached && u < c.policy_reward.size(); ++u) {
          if (c.policy_reward[u] > -1.0) {
            updates_to_clear += static_cast<double>(u);
            break;
          }
        }
        clear_runs += reached ? 1 : 0;
        bool satisfactory = false;
        task.rollout(c.means.back(), y, ydd);
        const double final_reward = world.reward(y, &satisfactory);
        if (satisfactory) {
          ++satisfactory_runs;
        } else {
          unsatisfactory_sum += final_reward;
        }
      };
      const std::vector<Curve> curves =
          runAll(options, experiment, protocol, algorithm, reward, writer, each, workers.get());
      Summary s = summarise(experiment, algorithm.name, protocol, curves);
      if (crossing_term) {
        const int unsatisfactory = protocol.runs - satisfactory_runs;
        s.extra = {{"satisfactory_runs", satisfactory_runs},
                   {"mean_unsatisfactory_reward", unsatisfactory > 0 ? unsatisfactory_sum / unsatisfactory : 0.0}};
      } else {
        s.extra = {{"runs_knocking_no_bottle", clear_runs},
                   {"mean_updates_to_knock_no_bottle", clear_runs > 0 ? updates_to_clear / clear_runs : -1.0}};
      }
      out.push_back(s);
    }
    if (workers) workers->report(experiment);
  }
}

// ---- wam_bottles: the bottle task on the simulated WAM (Sec. 6.2, Figs. 6.10–6.12) ----

/// The bottle task of Figs. 6.8–6.12 on the simulated WAM (tasks/wam_bottles.hpp, config/bottles_wam.yaml): the
/// planar experiment's DMP, prior and algorithms (REPS and DREPS, ε = 0.5, reuse 200, Σ₀ = 60² I), each rollout a
/// simulated arm among free bottles, on --jobs threads or the workers. The budget is smaller than the thesis' 50
/// runs × 100 updates (one rollout is ~0.16 s of one core): 20 runs × 20 updates × 50 rollouts with (6.18), 20 × 12
/// × 50 with (6.17). Writes
/// DIR/<experiment>_paths.csv: every run's final mean policy as the arm ran it (the tool along and to the left of the
/// line [m]) for the picture of Fig. 6.11.
void wamBottles(const Options& options, const WorkerOptions& worker_options, bool crossing_term,
                std::vector<Summary>& out) {
  const std::string experiment = crossing_term ? "wam_bottles" : "wam_bottles617";
  bt::WamBottleConfig config =
      bt::WamBottleConfig::fromYamlFile(bimanual_skills::cli::packageFile("config/bottles_wam.yaml"));
  config.sim_config = std::filesystem::absolute(config.sim_config).string();
  config.crossing_term = crossing_term;
  const std::string task_file = workerTaskConfig(options, experiment, config.toYaml());
  bt::WamBottleTask policy_task(bt::WamBottleConfig::fromYamlFile(task_file));
  // (6.17) asks how soon the mean policy knocks no bottle (the planar task: 9–11 updates); (6.18) where it ends.
  Protocol protocol =
      makeProtocol(options, 20, 2, crossing_term ? 20 : 12, 2, 50, policy_task.initialParameters(), 60.0);
  if (options.quick) protocol.rollouts = 10;
  std::unique_ptr<BatchRollouts> rollouts = onWorkers(worker_options, "wam_bottles", task_file);
  if (!rollouts) rollouts = std::make_unique<BatchRollouts>("wam_bottles", task_file, options.jobs);
  std::printf("  %s: %d runs x %d updates x %d rollouts, reward (%s), task file %s\n", experiment.c_str(),
              protocol.runs, protocol.updates, protocol.rollouts, crossing_term ? "6.18" : "6.17", task_file.c_str());
  const Reward reward = [&](const Eigen::VectorXd& theta) { return policy_task.run(theta, 0).reward; };
  Writer writer(options, experiment);
  std::ofstream paths(options.out + "/" + experiment + "_paths.csv");
  paths << "experiment,algorithm,run,outcome,reward,bottles_down,crossed,satisfactory,sample,time,along,left\n";
  const double length = policy_task.lineLength();
  for (const Algorithm& algorithm : repsFamily(0.5, 200, false)) {
    int satisfactory_runs = 0, clear_runs = 0, run = 0;
    double unsatisfactory_sum = 0.0, updates_to_clear = 0.0;
    const std::size_t failed_before = rollouts->failed(), rollouts_before = rollouts->rollouts();
    const auto each = [&](const Curve& c) {
      // Clear: the mean policy knocks no bottle down (reward > −1 under 6.17); the first update where it is.
      const bool clear = !crossing_term && c.policy_reward.back() > -1.0;
      for (std::size_t u = 0; clear && u < c.policy_reward.size(); ++u) {
        if (c.policy_reward[u] > -1.0) {
          updates_to_clear += static_cast<double>(u);
          break;
        }
      }
      clear_runs += clear ? 1 : 0;
      const bt::WamBottleRollout r = policy_task.run(c.means.back(), 0);
      if (r.satisfactory) {
        ++satisfactory_runs;
      } else {
        unsatisfactory_sum += r.reward;
      }
      for (Eigen::Index i = 0; i < r.tool_path.cols(); ++i) {
        const Eigen::Vector2d p = policy_task.toLine(r.tool_path.col(i)) * length;
        paths << experiment << ',' << algorithm.name << ',' << run << ',' << bt::toString(r.outcome) << ',' << r.reward
              << ',' << r.down << ',' << (r.crossed ? 1 : 0) << ',' << (r.satisfactory ? 1 : 0) << ',' << i << ','
              << r.path_times[i] << ',' << p.x() << ',' << p.y() << '\n';
      }
      paths.flush();
      ++run;
    };
    const std::vector<Curve> curves =
        runAll(options, experiment, protocol, algorithm, reward, writer, each, rollouts.get());
    Summary s = summarise(experiment, algorithm.name, protocol, curves);
    const double failed = static_cast<double>(rollouts->failed() - failed_before);
    s.extra = {{"failed_rollout_share", failed / static_cast<double>(rollouts->rollouts() - rollouts_before)}};
    // Where the bottles stand in the paths' frame [m], for the picture.
    for (int b = 0; b < 2; ++b) {
      const Eigen::Vector2d at = policy_task.bottleOnLine(b) * length;
      s.extra.push_back({"bottle_" + std::to_string(b + 1) + "_along", at.x()});
      s.extra.push_back({"bottle_" + std::to_string(b + 1) + "_left", at.y()});
    }
    s.extra.push_back({"bottle_radius", policy_task.bottleRadius()});
    s.extra.push_back({"line_length", length});
    if (crossing_term) {
      const int unsatisfactory = protocol.runs - satisfactory_runs;
      s.extra.push_back({"satisfactory_runs", satisfactory_runs});
      s.extra.push_back({"mean_unsatisfactory_reward", unsatisfactory > 0 ? unsatisfactory_sum / unsatisfactory : 0.0});
    } else {
      s.extra.push_back({"runs_knocking_no_bottle", clear_runs});
      s.extra.push_back({"mean_updates_to_knock_no_bottle", clear_runs > 0 ? updates_to_clear / clear_runs : -1.0});
    }
    out.push_back(s);
  }
  rollouts->report(experiment);
}

// ---- wam_guided: human-guided learning of the bottle task on the simulated WAM (Sec. 6.2, Figs. 6.9, 6.13) ----

/// Sets of guided runs (tasks/human_guidance.hpp): in each, 20 scripted people (seeded) guide the WAM's tool between
/// the bottles; the runs' measured paths are split at the take and the release, time-aligned by gradient descent,
/// averaged with weights exp(10 (R − max R)/(max R − min R)), and the task's DMP fitted to the average is run on the
/// arm: the policy a user gets from 20 guided runs, set against REPS' and DREPS' final policies of wam_bottles
/// (scripts/guided_comparison.py). Sets run on --jobs threads (the same results for any count). Writes
/// DIR/wam_guided_runs.csv (every guided run's measured tool path, its parts), DIR/wam_guided_aligned.csv (the aligned
/// parts and the weighted average), DIR/wam_guided_paths.csv (each set's learned policy as the arm ran it, the
/// columns of wam_bottles_paths.csv).
void wamGuided(const Options& options, std::vector<Summary>& out) {
  const std::string experiment = "wam_guided";
  bt::WamBottleConfig config =
      bt::WamBottleConfig::fromYamlFile(bimanual_skills::cli::packageFile("config/bottles_wam.yaml"));
  config.sim_config = std::filesystem::absolute(config.sim_config).string();
  bt::GuidedLearningConfig guided;
  guided.guidance.line_speed = 1.0 / config.duration;
  if (options.quick) guided.runs = 4;
  const int sets = options.runs > 0 ? options.runs : (options.quick ? 2 : 20);
  const int threads = std::min(bimanual_skills::parallel::threadCount(options.jobs), sets);
  std::printf(
      "  %s: %d sets x %d guided runs, reward (6.18), %d threads; set k's people have seeds %u + %d k + "
      "0..%d\n",
      experiment.c_str(), sets, guided.runs, threads, options.seed * 1000u, guided.runs, guided.runs - 1);
  std::fflush(stdout);
  std::vector<std::unique_ptr<bt::WamBottleTask>> tasks;
  for (int t = 0; t < threads; ++t) tasks.push_back(std::make_unique<bt::WamBottleTask>(config));
  std::vector<bt::GuidedLearning> results(static_cast<std::size_t>(sets));
  std::vector<double> seconds(static_cast<std::size_t>(sets));
  std::mutex progress;
  int done = 0;
  bimanual_skills::parallel::parallelFor(static_cast<std::size_t>(sets), threads, [&](int worker, std::size_t k) {
    const auto start = std::chrono::steady_clock::now();
    const std::uint32_t seed =
        options.seed * 1000u + static_cast<std::uint32_t>(guided.runs) * static_cast<std::uint32_t>(k);
    results[k] = bt::learnFromGuidance(*tasks[static_cast<std::size_t>(worker)], guided, seed);
    seconds[k] = bimanual_skills::realtime::secondsSince(start);
    const std::lock_guard<std::mutex> lock(progress);
    const bt::GuidedLearning& r = results[k];
    std::printf(
        "  %s: set %zu (%d/%d done): %d of %d guided runs ran, %d satisfactory; learned policy reward %.3f%s "
        "(%.1f s)\n",
        experiment.c_str(), k, ++done, sets, r.ok_runs, guided.runs, r.satisfactory_runs, r.policy.reward,
        r.policy.satisfactory ? ", satisfactory" : "", seconds[k]);
    std::fflush(stdout);
  });
  const bt::WamBottleTask& task = *tasks.front();
  const double length = task.lineLength();
  std::ofstream runs_csv(options.out + "/" + experiment + "_runs.csv");
  runs_csv << "set,run,seed,outcome,reward,bottles_down,crossed,satisfactory,part,sample,time,along,left\n";
  std::ofstream aligned_csv(options.out + "/" + experiment + "_aligned.csv");
  aligned_csv << "set,part,run,weight,sample,time,along,left\n";
  std::ofstream paths(options.out + "/" + experiment + "_paths.csv");
  paths << "experiment,algorithm,run,outcome,reward,bottles_down,crossed,satisfactory,sample,time,along,left\n";
  int satisfactory = 0, ok_runs = 0, satisfactory_runs = 0;
  double unsatisfactory_sum = 0.0, guided_reward = 0.0, cost_before = 0.0, cost_after = 0.0;
  Eigen::VectorXd rewards(sets);
  for (int k = 0; k < sets; ++k) {
    const bt::GuidedLearning& r = results[static_cast<std::size_t>(k)];
    int ok_index = 0;
    for (std::size_t j = 0; j < r.runs.size(); ++j) {
      const bt::GuidedRun& g = r.runs[j];
      const bt::WamBottleRollout& o = g.rollout;
      if (o.outcome != bt::FoldOutcome::Ok) {
        runs_csv << k << ',' << j << ',' << g.seed << ',' << bt::toString(o.outcome) << ',' << o.reward
                 << ",0,0,0,-1,0,0,0,0\n";
        continue;
      }
      guided_reward += o.reward;
      double t0 = 0.0;
      for (int p = 0; p < 3; ++p) {
        for (Eigen::Index i = 0; i < g.parts[p].rows(); ++i) {
          runs_csv << k << ',' << j << ',' << g.seed << ",Ok," << o.reward << ',' << o.down << ','
                   << (o.crossed ? 1 : 0) << ',' << (o.satisfactory ? 1 : 0) << ',' << p << ',' << i << ','
                   << t0 + g.seconds[p] * static_cast<double>(i) / static_cast<double>(g.parts[p].rows() - 1) << ','
                   << g.parts[p](i, 0) * length << ',' << g.parts[p](i, 1) * length << '\n';
        }
        t0 += g.seconds[p];
        const Eigen::MatrixXd& a = r.alignment[p].aligned[static_cast<std::size_t>(ok_index)];
        for (Eigen::Index i = 0; i < a.rows(); ++i) {
          aligned_csv << k << ',' << p << ',' << j << ',' << r.weights[ok_index] << ',' << i << ",0,"
                      << a(i, 0) * length << ',' << a(i, 1) * length << '\n';
        }
      }
      ++ok_index;
    }
    for (Eigen::Index i = 0; i < r.average.rows(); ++i) {
      aligned_csv << k << ",-1,-1,1," << i << ',' << r.average_times[i] << ',' << r.average(i, 0) * length << ','
                  << r.average(i, 1) * length << '\n';
    }
    const bt::WamBottleRollout& o = r.policy;
    for (Eigen::Index i = 0; i < o.tool_path.cols(); ++i) {
      const Eigen::Vector2d p = task.toLine(o.tool_path.col(i)) * length;
      paths << experiment << ",Guided," << k << ',' << bt::toString(o.outcome) << ',' << o.reward << ',' << o.down
            << ',' << (o.crossed ? 1 : 0) << ',' << (o.satisfactory ? 1 : 0) << ',' << i << ',' << o.path_times[i]
            << ',' << p.x() << ',' << p.y() << '\n';
    }
    rewards[k] = o.reward;
    satisfactory += o.satisfactory ? 1 : 0;
    if (!o.satisfactory) unsatisfactory_sum += o.reward;
    ok_runs += r.ok_runs;
    satisfactory_runs += r.satisfactory_runs;
    cost_before += r.alignment[1].cost_before / sets;
    cost_after += r.alignment[1].cost_after / sets;
  }
  Summary s;
  s.experiment = experiment;
  s.algorithm = "Guided";
  s.runs = sets;
  s.updates = 0;
  s.rollouts = guided.runs;
  s.final_reward_mean = rewards.mean();
  s.final_reward_std = sets > 1 ? std::sqrt((rewards.array() - rewards.mean()).square().sum() / (sets - 1)) : 0.0;
  s.seconds_per_update = std::accumulate(seconds.begin(), seconds.end(), 0.0) / sets;
  const int unsatisfactory = sets - satisfactory;
  s.extra = {{"satisfactory_runs", satisfactory},
             {"mean_unsatisfactory_reward", unsatisfactory > 0 ? unsatisfactory_sum / unsatisfactory : 0.0},
             {"guided_runs", sets * guided.runs},
             {"guided_runs_ran", ok_runs},
             {"guided_runs_satisfactory", satisfactory_runs},
             {"guided_mean_reward", ok_runs > 0 ? guided_reward / ok_runs : 0.0},
             {"guided_alignment_cost_before", cost_before},
             {"guided_alignment_cost_after", cost_after},
             {"line_length", length},
             {"bottle_radius", task.bottleRadius()}};
  for (int b = 0; b < 2; ++b) {
    const Eigen::Vector2d at = task.bottleOnLine(b) * length;
    s.extra.push_back({"bottle_" + std::to_string(b + 1) + "_along", at.x()});
    s.extra.push_back({"bottle_" + std::to_string(b + 1) + "_left", at.y()});
  }
  std::printf(
      "  %s: learned policies satisfactory in %d of %d sets, reward %.3f +- %.3f (std); guided runs: %d of %d "
      "ran, %d satisfactory\n",
      experiment.c_str(), satisfactory, sets, s.final_reward_mean, s.final_reward_std, ok_runs, sets * guided.runs,
      satisfactory_runs);
  out.push_back(s);
}

// ---- circle: a unimodal 7-DoF task with the WAM's kinematics (Fig. 6.14) ----

void circle(const Options& options, const WorkerOptions& worker_options, std::vector<Summary>& out) {
  bt::CircleTask task(
      bk::ChainModel::fromUrdfFile(bimanual_skills::cli::packageFile("urdf/wam.urdf"), "wam_base", "wam_tool"),
      options.seed);
  const Reward reward = [&](const Eigen::VectorXd& theta) { return task.reward(theta); };
  const Protocol protocol = makeProtocol(options, 20, 2, 50, 5, 50, task.policy().parameters(), 2.0);
  // The workers' task: this circle (its demonstration drawn with --seed), as config/circle_task.yaml describes it.
  const std::unique_ptr<BatchRollouts> workers = onWorkers(
      worker_options, "circle",
      worker_options.selected()
          ? workerTaskConfig(options, "circle",
                             "# ps_benchmark circle, seed " + std::to_string(options.seed) +
                                 "\nurdf: " + bimanual_skills::cli::packageFile("urdf/wam.urdf") +
                                 "\nbase: wam_base\ntip: wam_tool\nseed: " + std::to_string(options.seed) + "\n")
          : "");
  Writer writer(options, "circle");
  for (const Algorithm& algorithm : repsFamily(0.5, 100, false)) {
    const std::vector<Curve> curves = runAll(
        options, "circle", protocol, algorithm, reward, writer, [](const Curve&) {}, workers.get());
    Summary s = summarise("circle", algorithm.name, protocol, curves);
    s.extra = {{"initial_reward", curves.front().policy_reward.front()}, {"circle_radius_m", task.radius()}};
    out.push_back(s);
  }
  if (workers) workers->report("circle");
}

// ---- pi2viapoint: a 1-D DMP through a via-point, PI2 vs PI2-CMA vs REPS ----

void pi2viapoint(const Options& options, const WorkerOptions& worker_options, std::vector<Summary>& out) {
  bt::ViaPointTask task;
  const Eigen::MatrixXd& basis = task.basis();
  const auto step_costs = [&](const Eigen::VectorXd& theta) { return task.stepCosts(theta); };
  const Reward reward = [&](const Eigen::VectorXd& theta) { return -step_costs(theta).sum(); };
  const Protocol protocol = makeProtocol(options, 20, 3, 60, 10, 10, task.policy().parameters(), 30.0);
  std::vector<Algorithm> algorithms;
  for (const bool cma : {false, true}) {
    bl::Pi2Parameters parameters;
    parameters.covariance_adaptation = cma;
    algorithms.push_back(
        {cma ? "PI2-CMA" : "PI2", [](std::mt19937&) {},
         [parameters, &basis](Eigen::VectorXd& mean, Eigen::MatrixXd& covariance, const Eigen::MatrixXd& samples,
                              const Eigen::VectorXd&, const Eigen::MatrixXd& costs) {
           const bl::Pi2Update update = bl::pi2Update(parameters, mean, covariance, samples, costs, basis);
           mean = update.mean;
           covariance = update.covariance;
         }});
  }
  algorithms.push_back(repsFamily(0.5, 40, false).front());
  const std::unique_ptr<BatchRollouts> workers = onWorkers(worker_options, "viapoint");
  Writer writer(options, "pi2viapoint");
  for (const Algorithm& algorithm : algorithms) {
    double via_error = 0.0;
    const auto each = [&](const Curve& c) { via_error += task.viaPointError(c.means.back()); };
    const std::vector<Curve> curves =
        runAll(options, "pi2viapoint", protocol, algorithm, reward, writer, each, workers.get(), step_costs);
    Summary s = summarise("pi2viapoint", algorithm.name, protocol, curves);
    s.extra = {{"initial_reward", curves.front().policy_reward.front()},
               {"mean_final_via_point_error", via_error / protocol.runs}};
    out.push_back(s);
  }
  if (workers) workers->report("pi2viapoint");
}

void writeSummary(const Options& options, const std::vector<Summary>& rows) {
  std::vector<bimanual_skills::bench::JsonRow> json;
  for (const Summary& r : rows) {
    bimanual_skills::bench::JsonRow& row = json.emplace_back();
    row.add("experiment", r.experiment)
        .add("algorithm", r.algorithm)
        .add("runs", r.runs)
        .add("updates", r.updates)
        .add("rollouts_per_update", r.rollouts)
        .add("final_reward_mean", r.final_reward_mean)
        .add("final_reward_std", r.final_reward_std)
        .add("seconds_per_update", r.seconds_per_update);
    for (const auto& [key, value] : r.extra) row.add(key, value);
  }
  bimanual_skills::bench::writeSummaryJson(options, "ps_benchmark", json);
}

}  // namespace

int main(int argc, char** argv) {
  bimanual_skills::cli::pinNumerics(argv);
  bimanual_skills::bench::ExperimentProgram program;
  program.name = "ps_benchmark";
  program.description =
      "The thesis' policy-search experiments (Ch. 6: REPS, nDREPS and DREPS on the multimodal reward (6.16), in 2-D\n"
      "and in 20, 50 and 100 dimensions, the bottle task (6.17, 6.18), planar and on the simulated WAM\n"
      "(wam_bottles617, wam_bottles: not in all; --jobs threads run the rollouts), learnt from 20 human-guided runs\n"
      "(wam_guided: not in all; --runs sets, --jobs threads), and the WAM circle) and\n"
      "PI2/PI2-CMA on the via-point task. Writes DIR/<experiment>.csv as runs end, DIR/summary.json, learning-curve "
      "PNGs and\n"
      "DIR/tables.md.";
  program.experiments = {"multimodal2d", "multimodal_scale", "bottles",     "wam_bottles", "wam_bottles617",
                         "wam_guided",   "circle",           "pi2viapoint", "all"};
  program.with_runs = true;
  program.with_jobs = true;
  WorkerOptions workers;
  program.extra = [&workers](bimanual_skills::cli::CommandLine& line) {
    line.option("--worker-namespace", "NS",
                "run the rollouts on the rollout_worker nodes under NS (roslaunch bimanual_skills "
                "rollout_workers.launch), through the ROS master at ROS_MASTER_URI",
                &workers.space);
    line.option("--workers", "A,B,...", "run the rollouts on these rollout_worker nodes (instead of a namespace)",
                &workers.names);
    line.option("--worker-timeout", "S", "seconds without progress after which a worker counts as hung (default 60)",
                &workers.timeout);
  };
  const Options options = bimanual_skills::bench::parseExperimentOptions(argc, argv, program);
  if (!(workers.timeout > 0.0) || !std::isfinite(workers.timeout) ||
      (!workers.names.empty() && bimanual_skills::ros_layer::splitWorkerNames(workers.names).empty())) {
    std::fprintf(stderr,
                 "ps_benchmark: --worker-timeout must be a positive number of seconds and --workers must "
                 "name workers (see --help)\n");
    return 2;
  }
  try {
    std::filesystem::create_directories(options.out);
    std::printf("ps_benchmark: experiment %s, seed %u%s, output %s\n", options.experiment.c_str(), options.seed,
                options.quick ? " (quick)" : "", options.out.c_str());
    if (workers.selected()) {
      int ros_argc = 1;
      ros::init(ros_argc, argv, "ps_benchmark", ros::init_options::AnonymousName | ros::init_options::NoSigintHandler);
      if (!ros::master::check()) {
        throw std::runtime_error("no ROS master answers at " + ros::master::getURI() +
                                 ": start one with the workers (roslaunch bimanual_skills rollout_workers.launch)");
      }
      std::printf("ps_benchmark: rollouts on the workers %s\n",
                  (workers.names.empty() ? "under " + workers.space : workers.names).c_str());
    }
    std::vector<Summary> rows;
    const auto wants = [&](const char* name) { return options.experiment == "all" || options.experiment == name; };
    if (wants("multimodal2d")) multimodal2d(options, workers, rows);
    if (wants("multimodal_scale")) multimodalScale(options, workers, rows);
    if (wants("bottles")) bottles(options, workers, rows);
    // The simulated robot (seconds per update) is not part of `all`.
    if (options.experiment == "wam_bottles617") wamBottles(options, workers, false, rows);
    if (options.experiment == "wam_bottles") wamBottles(options, workers, true, rows);
    if (options.experiment == "wam_guided") wamGuided(options, rows);
    if (wants("circle")) circle(options, workers, rows);
    if (wants("pi2viapoint")) pi2viapoint(options, workers, rows);
    writeSummary(options, rows);
    if (!bimanual_skills::bench::runPlotScript("ps_benchmark", "plot_ps_benchmark.py", options.out)) {
      return 1;
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "ps_benchmark: %s\n", e.what());
    return 1;
  }
  return 0;
}

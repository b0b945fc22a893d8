#include "bimanual_skills/rollout/fold_learning.hpp"

#include "bimanual_skills/learning/gaussian.hpp"
#include "bimanual_skills/learning/pi2.hpp"
#include "bimanual_skills/primitives/dr_dmp.hpp"
#include "bimanual_skills/realtime/clock.hpp"
#include "bimanual_skills/rollout/fold_rollout_task.hpp"
#include "bimanual_skills/sim/sim_config.hpp"
#include "io/csv_records.hpp"
#include "io/yaml_io.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <map>
#include <regex>
#include <sstream>
#include <stdexcept>
#include <vector>

namespace bimanual_skills::rollout {

namespace {

using realtime::Clock;
using realtime::secondsSince;
constexpr double kInfinity = std::numeric_limits<double>::infinity();

std::string key(const std::string& algorithm, int run, int epoch, RolloutKind kind, int index) {
  return algorithm + '|' + std::to_string(run) + '|' + std::to_string(epoch) + '|' + toString(kind) + '|' +
         std::to_string(index);
}

/// Fields of one CSV line; a field in double quotes may hold commas and doubled quotes.
std::vector<std::string> splitCsv(const std::string& line) {
  std::vector<std::string> out(1);
  bool quoted = false;
  for (std::size_t i = 0; i < line.size(); ++i) {
    const char c = line[i];
    if (quoted) {
      if (c == '"' && i + 1 < line.size() && line[i + 1] == '"') {
        out.back() += '"';
        ++i;
      } else if (c == '"') {
        quoted = false;
      } else {
        out.back() += c;
      }
    } else if (c == '"') {
      quoted = true;
    } else if (c == ',') {
      out.emplace_back();
    } else {
      out.back() += c;
    }
  }
  return out;
}

std::string quoted(const std::string& text) {
  std::string out = "\"";
  for (const char c : text) {
    if (c == '\n') {
      out += ' ';
    } else {
      if (c == '"') out += '"';
      out += c;
    }
  }
  return out + '"';
}

std::string number(double value) {
  char buffer[32];
  std::snprintf(buffer, sizeof buffer, "%.17g", value);
  return buffer;
}

RolloutKind kindFromString(const std::string& text, const std::string& where) {
  for (const RolloutKind kind : {RolloutKind::Sample, RolloutKind::Policy, RolloutKind::Repetition}) {
    if (text == toString(kind)) return kind;
  }
  throw std::invalid_argument(where + ": unknown rollout kind '" + text + "'");
}

const char* const kRolloutColumns =
    "algorithm,run,epoch,kind,index,seed,outcome,reward,r_acceleration,r_color,r_depth,fill_ratio,mean_gradient,"
    "area_ratio,aspect,fold_quality,fold_distance,fold_displacement,r_goal,goal_iou,goal_mismatch,r_fold,fold_mismatch,"
    "fold_edge,fold_single,fold_length,latent_dims,wall_seconds,reason";
constexpr std::size_t kRolloutFields = 29;

double toDouble(const std::string& text, const std::string& where) {
  std::size_t used = 0;
  double value = 0.0;
  try {
    value = std::stod(text, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used != text.size() || text.empty()) throw std::invalid_argument(where + ": '" + text + "' is not a number");
  return value;
}

int toInt(const std::string& text, const std::string& where) {
  const double value = toDouble(text, where);
  if (value != std::floor(value) || std::abs(value) > 2147483647.0) {
    throw std::invalid_argument(where + ": '" + text + "' is not an integer");
  }
  return static_cast<int>(value);
}

}  // namespace

FoldLearningConfig withSimulationRenderer(FoldLearningConfig config) {
  const vision::RenderNoise noise = config.reward.renderer.noise;
  config.reward.renderer = tasks::rendererFor(sim::SimConfig::fromYamlFile(config.task.sim_config, config.task.robot));
  config.reward.renderer.noise = noise;
  return config;
}

const char* toString(RolloutKind kind) noexcept {
  switch (kind) {
    case RolloutKind::Sample:
      return "sample";
    case RolloutKind::Policy:
      return "policy";
    case RolloutKind::Repetition:
      return "repetition";
  }
  return "unknown";
}

namespace {

/// PI2-CMA on the policy's weights: the episode's reward is the cost of its last step (the fold is scored once, at
/// the end), so every step weighs the rollouts alike and the update is PI2's projected, probability-weighted average
/// of the exploration (5.8–5.13) with the covariance adapted from the same probabilities. As REPS' (λ =
/// covariance_memory), the new covariance keeps λ of the one sampled from: 12 rollouts span at most 12 of the 240
/// directions, and PI2-CMA's own covariance would stop exploring in all the others after one update.
learning::CoordinatedPolicy pi2CmaStep(learning::CoordinatedPolicy policy, const Eigen::MatrixXd& samples,
                                       const Eigen::VectorXd& rewards, const Eigen::MatrixXd& basis, double memory) {
  learning::Pi2Parameters parameters;
  parameters.covariance_adaptation = true;
  Eigen::MatrixXd costs = Eigen::MatrixXd::Zero(samples.rows(), basis.rows());
  costs.col(costs.cols() - 1) = -rewards;
  const learning::Pi2Update update =
      learning::pi2Update(parameters, policy.mean, policy.covariance, samples, costs, basis);
  policy.mean = update.mean;
  policy.covariance = (1.0 - memory) * update.covariance + memory * policy.covariance;
  return policy;
}

}  // namespace

DrDmpVariant parseDrDmpVariant(const std::string& name, int dofs, double eta) {
  std::smatch m;
  DrDmpVariant v;
  v.name = name;
  v.eta = kInfinity;
  const auto count = [&](const std::string& text) { return std::stoi(text); };
  if (std::regex_match(name, m, std::regex(R"(DR-DMP0\((\d+)\))"))) {
    v.latent_dims = count(m[1]);
  } else if (std::regex_match(name, m, std::regex(R"(DR-DMP_CMU\((\d+)\))"))) {
    v.latent_dims = count(m[1]);
    v.rule = learning::CoordinationRule::Cmu;
  } else if (std::regex_match(name, m, std::regex(R"(DR-DMP_MCMU\((\d+),(\d+)\))"))) {
    v.matrices = count(m[1]);
    v.latent_dims = count(m[2]);
    v.rule = learning::CoordinationRule::Cmu;
  } else if (name == "IDR-DMP_CMU") {
    v.latent_dims = dofs;
    v.rule = learning::CoordinationRule::Cmu;
    v.eta = eta;
  } else if (std::regex_match(name, m, std::regex(R"(IDR-DMP_MCMU\((\d+)\))"))) {
    v.matrices = count(m[1]);
    v.latent_dims = dofs;
    v.rule = learning::CoordinationRule::Cmu;
    v.eta = eta;
  } else if (name == "PI2-CMA" || name == "CMA-ES") {
    v.latent_dims = dofs;
    v.search = name == "PI2-CMA" ? PolicySearch::Pi2Cma : PolicySearch::CmaEs;
  } else {
    throw std::invalid_argument(
        "unknown algorithm '" + name +
        "' (DR-DMP0(r), DR-DMP_CMU(r), DR-DMP_MCMU(Ns,r), IDR-DMP_CMU, IDR-DMP_MCMU(Ns), PI2-CMA, CMA-ES)");
  }
  if (v.latent_dims < 1 || v.latent_dims > dofs || v.matrices < 1 || v.matrices > 20) {
    throw std::invalid_argument("algorithm '" + name + "': r must be in [1, " + std::to_string(dofs) +
                                "] and Ns in [1, 20]");
  }
  return v;
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
                   "demo_drop", "demo_lag", "demonstration", "policy"});
    if (task["kernels"]) c.task.kernels = io::readInt(task, "kernels", at);
    c.task.duration = io::readDouble(task, "duration", at, c.task.duration);
    if (task["ik_method"]) c.task.ik_method = io::readString(task, "ik_method", at);
    c.task.max_ik_error = io::readDouble(task, "max_ik_error", at, c.task.max_ik_error);
    c.task.max_tracking_error = io::readDouble(task, "max_tracking_error", at, c.task.max_tracking_error);
    c.task.demo_reach = io::readDouble(task, "demo_reach", at, c.task.demo_reach);
    c.task.demo_lift = io::readDouble(task, "demo_lift", at, c.task.demo_lift);
    c.task.demo_drop = io::readDouble(task, "demo_drop", at, c.task.demo_drop);
    c.task.demo_lag = io::readDouble(task, "demo_lag", at, c.task.demo_lag);
    if (!(c.task.demo_lag >= 0.0 && c.task.demo_lag < 0.9)) io::fail(at + ": 'demo_lag' must be in [0, 0.9)");
    if (task["policy"]) c.task.policy = tasks::foldPolicyFromString(io::readString(task, "policy", at), at);
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
         "goal_excess_height", "fold_weight", "failure_reward", "depth_noise", "colour_noise"});
    if (reward["setting"]) c.reward = tasks::rewardSetting(c.reward, io::readString(reward, "setting", at), at);
    c.reward.acceleration_weight = io::readDouble(reward, "acceleration_weight", at, c.reward.acceleration_weight);
    c.reward.image.colour_weight = io::readDouble(reward, "colour_weight", at, c.reward.image.colour_weight);
    c.reward.image.depth_weight = io::readDouble(reward, "depth_weight", at, c.reward.image.depth_weight);
    c.reward.image.goal_weight = io::readDouble(reward, "goal_weight", at, c.reward.image.goal_weight);
    c.reward.image.fold_weight = io::readDouble(reward, "fold_weight", at, c.reward.image.fold_weight);
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
    io::checkKeys(
        learning, at,
        {"algorithms", "runs", "updates", "rollouts", "reuse", "epsilon", "eta", "initial_stddev", "goal_stddev",
         "covariance_memory", "repetitions", "seed", "jobs", "robot_retries", "robot_fault_limit"});
    if (const YAML::Node algorithms = learning["algorithms"]) {
      if (!algorithms.IsSequence()) io::fail(at + ": 'algorithms' must be a list of names");
      c.algorithms.clear();
      for (const YAML::Node& a : algorithms) c.algorithms.push_back(a.as<std::string>());
    }
    if (learning["runs"]) c.runs = io::readInt(learning, "runs", at);
    if (learning["updates"]) c.updates = io::readInt(learning, "updates", at);
    if (learning["rollouts"]) c.rollouts = io::readInt(learning, "rollouts", at);
    if (learning["reuse"]) c.reuse = io::readInt(learning, "reuse", at);
    c.epsilon = io::readDouble(learning, "epsilon", at, c.epsilon);
    c.eta = io::readDouble(learning, "eta", at, c.eta);
    c.initial_stddev = io::readDouble(learning, "initial_stddev", at, c.initial_stddev);
    c.goal_stddev = io::readDouble(learning, "goal_stddev", at, c.goal_stddev);
    c.covariance_memory = io::readDouble(learning, "covariance_memory", at, c.covariance_memory);
    if (learning["repetitions"]) c.repetitions = io::readInt(learning, "repetitions", at);
    if (learning["seed"]) {
      const int seed = io::readInt(learning, "seed", at);
      if (seed < 0) io::fail(at + ": 'seed' must be >= 0");
      c.seed = static_cast<std::uint32_t>(seed);
    }
    if (learning["jobs"]) c.jobs = io::readInt(learning, "jobs", at);
    if (learning["robot_retries"]) c.robot_retries = io::readInt(learning, "robot_retries", at);
    if (learning["robot_fault_limit"]) c.robot_fault_limit = io::readInt(learning, "robot_fault_limit", at);
  }
  io::withContext(where, [&] { c.validate(); });
  return c;
}

struct FoldLearner::Impl {
  FoldLearningConfig config;
  std::string dir;
  FoldLearningObserver observer;
  std::unique_ptr<Evaluator> evaluator;
  ParallelEvaluator* threads = nullptr;             ///< The evaluator when the rollouts run on threads here.
  std::unique_ptr<FoldRolloutTask> helper;          ///< For the demonstration and the images when they run elsewhere.
  std::map<std::string, FoldRolloutRecord> stored;  ///< Rollouts found in the directory.
  io::CsvAppender rollouts_csv, parameters_csv, faults_csv;
  int simulated = 0, resumed = 0;
  int robot_faults = 0, faults_in_a_row = 0;

  /// The reward the directory's rollouts were scored with, DIR/reward.txt: written while the directory holds no
  /// rollout, compared once it does (rollouts scored otherwise must not be reused). After readStored().
  void lockRewardAndWorld() {
    const tasks::FoldRewardConfig& r = config.reward;
    std::ostringstream text;
    text << "setting " << r.setting << "\nacceleration_weight " << number(r.acceleration_weight) << "\ncolour_weight "
         << number(r.image.colour_weight) << "\ndepth_weight " << number(r.image.depth_weight) << "\ngoal_weight "
         << number(r.image.goal_weight) << "\ngoal_missing_height " << number(r.image.goal_missing_height)
         << "\ngoal_excess_height " << number(r.image.goal_excess_height) << "\nfold_weight "
         << number(r.image.fold_weight) << "\nfailure_reward " << number(r.failure_reward) << "\ndepth_noise "
         << number(r.renderer.noise.depth_stddev) << "\ncolour_noise " << number(r.renderer.noise.colour_stddev)
         << '\n';
    lock("reward.txt", text.str(), "scored with another reward");
    // The world the rollouts ran in: the simulation file with its URDF and plant (on a robot through ROS the
    // simulator's is checked against it, FoldOnRobotTask).
    lock("world.txt", "sim_config " + sim::SimConfig::worldDigest(config.task.sim_config, config.task.robot) + "\n",
         "run in another world (simulation, URDF or plant file)");
  }

  /// Writes `text` to DIR/name, or, when the directory holds rollouts already, checks that it says the same.
  void lock(const std::string& name, const std::string& text, const std::string& otherwise) {
    const std::string path = dir + "/" + name;
    std::ifstream in{path};
    if (in && !stored.empty()) {
      const std::string recorded{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
      if (recorded != text) {
        throw std::invalid_argument("fold learning: '" + dir + "' holds rollouts " + otherwise + " (" + path +
                                    "): use another directory");
      }
      return;
    }
    std::ofstream out(path);
    out << text;
    if (!out.flush()) throw std::invalid_argument("fold learning: cannot write '" + path + "'");
  }

  void readStored() {
    const std::string rollouts = dir + "/rollouts.csv", parameters = dir + "/rollout_parameters.csv";
    // A run killed while it wrote a record leaves a partial last line: it is dropped (and its rollout run again).
    io::dropPartialRecord(rollouts);
    io::dropPartialRecord(parameters);
    std::map<std::string, Eigen::VectorXd> weights;
    std::ifstream p(parameters);
    std::string line;
    for (int n = 1; std::getline(p, line); ++n) {
      if (n == 1 || line.empty()) continue;
      const std::string where = parameters + " line " + std::to_string(n);
      const std::vector<std::string> f = splitCsv(line);
      if (f.size() < 6) throw std::invalid_argument(where + ": too few fields");
      const int size = toInt(f[5], where);
      if (size < 0 || f.size() != 6 + static_cast<std::size_t>(size)) {
        throw std::invalid_argument(where + ": not the " + f[5] + " weights it announces");
      }
      Eigen::VectorXd w(size);
      for (int i = 0; i < size; ++i) w[i] = toDouble(f[6 + static_cast<std::size_t>(i)], where);
      weights[key(f[0], toInt(f[1], where), toInt(f[2], where), kindFromString(f[3], where), toInt(f[4], where))] = w;
    }
    std::ifstream r(rollouts);
    for (int n = 1; std::getline(r, line); ++n) {
      if (n == 1 && line != kRolloutColumns) {
        throw std::invalid_argument("fold learning: " + rollouts + " has other columns (" + line +
                                    "), written by another version: use another directory");
      }
      if (n == 1 || line.empty()) continue;
      const std::string where = rollouts + " line " + std::to_string(n);
      const std::vector<std::string> f = splitCsv(line);
      if (f.size() != kRolloutFields) throw std::invalid_argument(where + ": expected " + kRolloutColumns);
      FoldRolloutRecord rec;
      rec.algorithm = f[0];
      rec.run = toInt(f[1], where);
      rec.epoch = toInt(f[2], where);
      rec.kind = kindFromString(f[3], where);
      rec.index = toInt(f[4], where);
      rec.seed = static_cast<std::uint32_t>(toDouble(f[5], where));
      rec.terms.outcome = tasks::foldOutcomeFromString(f[6], where);
      rec.terms.reward = toDouble(f[7], where);
      rec.terms.r_acceleration = toDouble(f[8], where);
      rec.terms.r_color = toDouble(f[9], where);
      rec.terms.r_depth = toDouble(f[10], where);
      rec.terms.fill_ratio = toDouble(f[11], where);
      rec.terms.mean_gradient = toDouble(f[12], where);
      rec.terms.area_ratio = toDouble(f[13], where);
      rec.terms.aspect = toDouble(f[14], where);
      rec.terms.fold_quality = toDouble(f[15], where);
      rec.terms.fold_distance = toDouble(f[16], where);
      rec.terms.fold_displacement = toDouble(f[17], where);
      rec.terms.r_goal = toDouble(f[18], where);
      rec.terms.goal_iou = toDouble(f[19], where);
      rec.terms.goal_mismatch = toDouble(f[20], where);
      rec.terms.r_fold = toDouble(f[21], where);
      rec.terms.fold_mismatch = toDouble(f[22], where);
      rec.terms.fold_edge = toDouble(f[23], where);
      rec.terms.fold_single = toDouble(f[24], where);
      rec.terms.fold_length = toDouble(f[25], where);
      rec.wall_seconds = toDouble(f[27], where);
      rec.reason = f[28];
      rec.resumed = true;
      // A robot's fault says nothing of the policy (written by versions that learned from them): run it again.
      if (rec.terms.outcome == tasks::FoldOutcome::RobotFailed) continue;
      const std::string k = key(rec.algorithm, rec.run, rec.epoch, rec.kind, rec.index);
      const auto w = weights.find(k);
      if (w == weights.end()) continue;  // interrupted between the two files: run it again
      rec.weights = w->second;
      stored[k] = rec;
    }
  }

  void openFiles() {
    try {
      rollouts_csv = io::CsvAppender(dir + "/rollouts.csv", kRolloutColumns);
      parameters_csv =
          io::CsvAppender(dir + "/rollout_parameters.csv", "algorithm,run,epoch,kind,index,size,weights...");
      faults_csv = io::CsvAppender(dir + "/robot_faults.csv",
                                   "algorithm,run,epoch,kind,index,seed,attempt,retried,wall_seconds,reason");
    } catch (const std::runtime_error& e) {
      throw std::invalid_argument(std::string("fold learning: ") + e.what());
    }
  }

  /// Under the lock.
  void write(const FoldRolloutRecord& rec) {
    const tasks::FoldRewardTerms& t = rec.terms;
    std::ostringstream line;
    line << quoted(rec.algorithm) << ',' << rec.run << ',' << rec.epoch << ',' << toString(rec.kind) << ',' << rec.index
         << ',' << rec.seed << ',' << tasks::toString(t.outcome) << ',' << number(t.reward) << ','
         << number(t.r_acceleration) << ',' << number(t.r_color) << ',' << number(t.r_depth) << ','
         << number(t.fill_ratio) << ',' << number(t.mean_gradient) << ',' << number(t.area_ratio) << ','
         << number(t.aspect) << ',' << number(t.fold_quality) << ',' << number(t.fold_distance) << ','
         << number(t.fold_displacement) << ',' << number(t.r_goal) << ',' << number(t.goal_iou) << ','
         << number(t.goal_mismatch) << ',' << number(t.r_fold) << ',' << number(t.fold_mismatch) << ','
         << number(t.fold_edge) << ',' << number(t.fold_single) << ',' << number(t.fold_length) << ','
         << (rec.coordination.empty() ? 0 : rec.coordination.front().cols()) << ',' << number(rec.wall_seconds) << ','
         << quoted(rec.reason);
    rollouts_csv.append(line.str());
    // The parameters last: a rollout counts as stored once both records are whole.
    line.str("");
    line << quoted(rec.algorithm) << ',' << rec.run << ',' << rec.epoch << ',' << toString(rec.kind) << ',' << rec.index
         << ',' << rec.weights.size();
    for (Eigen::Index i = 0; i < rec.weights.size(); ++i) line << ',' << number(rec.weights[i]);
    parameters_csv.append(line.str());
  }

  /// Evaluates a batch (records with coordination, weights and seed set): stored ones from disk, the others on
  /// the evaluator's threads.
  void evaluate(std::vector<FoldRolloutRecord>& batch) {
    std::vector<std::size_t> pending;
    for (std::size_t i = 0; i < batch.size(); ++i) {
      FoldRolloutRecord& rec = batch[i];
      const auto found = stored.find(key(rec.algorithm, rec.run, rec.epoch, rec.kind, rec.index));
      if (found == stored.end()) {
        pending.push_back(i);
        continue;
      }
      if (found->second.weights.size() != rec.weights.size() || found->second.weights != rec.weights ||
          found->second.seed != rec.seed) {
        throw std::invalid_argument("fold learning: '" + dir + "' holds rollout " + found->first +
                                    " with other parameters: it belongs to another configuration or seed (use a "
                                    "new directory)");
      }
      rec.terms = found->second.terms;
      rec.reason = found->second.reason;
      rec.wall_seconds = found->second.wall_seconds;
      rec.resumed = true;
      ++resumed;
      if (observer.rollout) observer.rollout(rec, tasks::FoldRollout{}, firstTask().reward());
    }
    // Robot faults are run again (same parameters, same seed) until the robot runs them or gives up.
    for (int attempt = 1; !pending.empty(); ++attempt) {
      pending = evaluatePending(batch, pending, attempt);
    }
  }

  /// One attempt at the pending rollouts of a batch; returns those the robot failed (to run again).
  std::vector<std::size_t> evaluatePending(std::vector<FoldRolloutRecord>& batch,
                                           const std::vector<std::size_t>& pending, int attempt) {
    std::vector<RolloutRequest> requests;
    for (const std::size_t i : pending) {
      requests.push_back({FoldRolloutTask::encode(batch[i].coordination, batch[i].weights), batch[i].seed});
    }
    std::vector<std::size_t> faulted;
    std::string fault;  // why the learning stops, once it must
    const auto stop = [&] { return !fault.empty() || (observer.stop && observer.stop()); };
    // done() runs under the evaluator's lock: the files, the counters and the observer see one rollout at a time.
    try {
      evaluator->evaluate(
          requests,
          [&](std::size_t n, const RolloutResult& result, RolloutTask* task) {
            // A task of another kind (e.g. one on a robot) gives its terms in the result only.
            auto* fold = dynamic_cast<FoldRolloutTask*>(task);
            FoldRolloutRecord& rec = batch[pending[n]];
            rec.terms = fold ? fold->lastTerms() : FoldRolloutTask::termsOf(result);
            rec.reason = result.reason;
            rec.wall_seconds = result.wall_seconds;
            if (rec.terms.outcome == tasks::FoldOutcome::RobotFailed) {
              onRobotFault(rec, attempt, fault);
              faulted.push_back(pending[n]);
              return;
            }
            faults_in_a_row = 0;
            recordRollout(rec, task, result);
          },
          stop);
    } catch (const std::runtime_error& e) {
      if (!fault.empty() && std::string(e.what()) == "stopped") throw RobotFaults(fault);
      throw;
    }
    if (!fault.empty()) throw RobotFaults(fault);
    std::sort(faulted.begin(), faulted.end());
    return faulted;
  }

  /// Under the evaluator's lock: logs a robot's fault and sets `fault` when the learning must stop.
  void onRobotFault(const FoldRolloutRecord& rec, int attempt, std::string& fault) {
    ++robot_faults;
    ++faults_in_a_row;
    const bool retry = attempt <= config.robot_retries && faults_in_a_row < config.robot_fault_limit;
    std::ostringstream line;
    line << quoted(rec.algorithm) << ',' << rec.run << ',' << rec.epoch << ',' << toString(rec.kind) << ',' << rec.index
         << ',' << rec.seed << ',' << attempt << ',' << (retry ? 1 : 0) << ',' << number(rec.wall_seconds) << ','
         << quoted(rec.reason);
    faults_csv.append(line.str());
    if (observer.robot_fault) observer.robot_fault(rec, attempt, rec.reason, retry);
    if (retry || !fault.empty()) return;
    std::ostringstream why;
    why << "the robot failed ";
    if (faults_in_a_row >= config.robot_fault_limit) {
      why << faults_in_a_row << " times in a row (robot_fault_limit " << config.robot_fault_limit << ")";
    } else {
      why << "rollout " << key(rec.algorithm, rec.run, rec.epoch, rec.kind, rec.index) << ' ' << attempt
          << " times (robot_retries " << config.robot_retries << ")";
    }
    why << "; the last: " << rec.reason << ". Fix the robot and run again: the finished rollouts are kept";
    fault = why.str();
  }

  /// Under the evaluator's lock: a rollout the robot ran, written and shown.
  void recordRollout(FoldRolloutRecord& rec, RolloutTask* task, const RolloutResult& result) {
    write(rec);
    ++simulated;
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
        csv << quoted(s.algorithm) << ',' << s.run << ',' << s.epoch << ',' << s.latent_dims << ',' << s.failures << ','
            << number(s.mean_reward) << ',' << number(s.std_reward) << ',' << number(s.r_acceleration) << ','
            << number(s.r_color) << ',' << number(s.r_depth) << ',' << number(s.fill_ratio) << ','
            << number(s.mean_gradient) << ',' << number(s.area_ratio) << ',' << number(s.r_goal) << ','
            << number(s.goal_mismatch) << ',' << number(s.r_fold) << ',' << number(s.fold_mismatch) << ','
            << number(s.fold_quality) << ',' << number(s.fold_quality_std) << ',' << number(s.policy_reward) << ','
            << number(s.policy_fold_quality) << ',' << (s.policy_failed ? 1 : 0) << '\n';
      }
    }
  }

  void writeCoordination(const std::vector<FoldRunResult>& runs) const {
    std::ofstream csv(dir + "/coordination.csv");
    csv << "algorithm,run,matrix,row,values...\n";
    for (const FoldRunResult& run : runs) {
      for (std::size_t s = 0; s < run.final.coordination.size(); ++s) {
        const Eigen::MatrixXd& omega = run.final.coordination[s];
        for (Eigen::Index i = 0; i < omega.rows(); ++i) {
          csv << quoted(run.algorithm) << ',' << run.run << ',' << s << ',' << i;
          for (Eigen::Index j = 0; j < omega.cols(); ++j) csv << ',' << number(omega(i, j));
          csv << '\n';
        }
      }
    }
  }

  FoldRunResult learnRun(const std::string& algorithm, int algorithm_index, int run,
                         const std::vector<FoldRunResult>& done) {
    const auto start = Clock::now();
    const DrDmpVariant variant = parseDrDmpVariant(algorithm, tasks::ClothFoldTask::kDofs, config.eta);
    const tasks::ClothFoldTask& task = firstTask().task();
    const primitives::DrDmpParameters parameters = task.forcingParameters(variant.matrices);
    const Eigen::MatrixXd demonstration = task.demonstrationTrajectory();
    const primitives::DrDmpFit fit =
        primitives::DrDmp::fit(parameters, {demonstration}, task.demonstrationStep(), variant.latent_dims, 0.0);
    const learning::CoordinationGrid grid =
        fit.dmp.grid(task.demonstrationStep(), static_cast<int>(demonstration.rows()) - 1);
    learning::CoordinatedRepsParameters reps;
    reps.reps.epsilon = config.epsilon;
    reps.reps.reuse = config.reuse;
    reps.covariance_memory = config.covariance_memory;
    reps.rule = variant.rule;
    reps.update.eta = variant.eta;
    const Eigen::VectorXd mean = fit.dmp.weights();
    // σ per kernel weight, and per goal weight the forcing α_z β_z goal_stddev that moves the goal by goal_stddev.
    const int basis = parameters.basisSize(), kernels = parameters.dmp.kernels;
    Eigen::VectorXd variances = Eigen::VectorXd::Constant(mean.size(), config.initial_stddev * config.initial_stddev);
    const double goal_forcing = parameters.dmp.alpha_z * parameters.dmp.beta_z * config.goal_stddev;
    for (Eigen::Index j = 0; basis > kernels && j < mean.size() / basis; ++j) {
      variances[j * basis + kernels] = goal_forcing * goal_forcing;
    }
    learning::CoordinatedPolicy initial{fit.dmp.coordination(), mean, variances.asDiagonal(), {}};
    learning::CoordinatedReps learner(reps, grid, initial, fit.excitation);
    // The peers keep their own policy on the standard DMP's weights (the coordination stays the fitted one).
    learning::CoordinatedPolicy peer = initial;
    learning::CovarianceAdaptation adaptation = learning::CovarianceAdaptation::start(initial.covariance);
    const auto current = [&]() -> const learning::CoordinatedPolicy& {
      return variant.search == PolicySearch::Reps ? learner.policy() : peer;
    };

    std::seed_seq sequence{config.seed, static_cast<std::uint32_t>(algorithm_index), static_cast<std::uint32_t>(run)};
    std::mt19937 rng(sequence);
    learning::GaussianSampler sampler;
    FoldRunResult result;
    result.algorithm = algorithm;
    result.run = run;
    result.best.terms.reward = -kInfinity;
    const auto record = [&](int epoch, RolloutKind kind, int index, const Eigen::VectorXd& w) {
      FoldRolloutRecord rec;
      rec.algorithm = algorithm;
      rec.run = run;
      rec.epoch = epoch;
      rec.kind = kind;
      rec.index = index;
      rec.coordination = current().coordination;
      rec.weights = w;
      rec.seed = static_cast<std::uint32_t>(rng());
      return rec;
    };
    for (int epoch = 0; epoch <= config.updates; ++epoch) {
      const learning::CoordinatedPolicy& policy = current();
      const Eigen::MatrixXd factor = learning::choleskyFactor(policy.covariance);
      std::vector<FoldRolloutRecord> batch;
      Eigen::MatrixXd samples(config.rollouts, policy.mean.size());
      // The noise-free mean policy of every epoch (what a user of the learning gets at that point; not an
      // exploration rollout and not used by the update).
      batch.push_back(record(epoch, RolloutKind::Policy, 0, policy.mean));
      for (int k = 0; k < config.rollouts; ++k) {
        samples.row(k) = sampler.draw(policy.mean, factor, rng).transpose();
        batch.push_back(record(epoch, RolloutKind::Sample, k, samples.row(k).transpose()));
      }
      evaluate(batch);
      Eigen::VectorXd rewards(config.rollouts);
      std::vector<Eigen::MatrixXd> values;
      for (const FoldRolloutRecord& rec : batch) {
        if (rec.terms.outcome == tasks::FoldOutcome::Ok && rec.terms.reward > result.best.terms.reward) {
          result.best = rec;
        }
        if (rec.kind == RolloutKind::Policy && epoch == 0) result.initial_policy = rec;
        if (rec.kind == RolloutKind::Policy && epoch == config.updates) result.final_policy = rec;
        if (rec.kind != RolloutKind::Sample) continue;
        rewards[rec.index] = rec.terms.reward;
        values.push_back(learning::coordinatedValues(grid, policy.coordination, rec.weights));
      }
      result.epochs.push_back(epochStats(algorithm, run, epoch, policy.latentDims(), batch));
      if (observer.epoch) observer.epoch(result.epochs.back());
      writeEpochs(done, result);
      if (epoch < config.updates) {
        if (variant.search == PolicySearch::Reps) {
          learner.update(samples, values, rewards);
        } else if (variant.search == PolicySearch::Pi2Cma) {
          peer = pi2CmaStep(peer, samples, rewards, grid.basis(), config.covariance_memory);
        } else {
          peer.mean = learning::cmaEsStep(peer.mean, adaptation, samples, rewards);
          peer.covariance = adaptation.covariance();
        }
      }
    }
    result.final = current();
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
  std::error_code error;
  std::filesystem::create_directories(out_dir, error);
  if (error || !std::filesystem::is_directory(out_dir)) {
    throw std::invalid_argument("fold learning: cannot create the directory '" + out_dir + "'");
  }
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
  m.readStored();
  m.lockRewardAndWorld();
  m.openFiles();
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
  result.simulated = m.simulated;
  result.resumed = m.resumed;
  result.robot_faults = m.robot_faults;
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

#include "run_directory.hpp"

#include "bimanual_skills/rollout/coordinated_parameters.hpp"

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <sstream>
#include <stdexcept>
#include <utility>

namespace bimanual_skills::rollout {

std::string rolloutKey(const std::string& algorithm, int run, int epoch, RolloutKind kind, int index) {
  return algorithm + '|' + std::to_string(run) + '|' + std::to_string(epoch) + '|' + toString(kind) + '|' +
         std::to_string(index);
}

RunDirectory::RunDirectory(std::string dir, std::vector<std::string> terms, std::string what, int robot_retries,
                           int robot_fault_limit)
    : dir_(std::move(dir)),
      what_(std::move(what)),
      terms_(std::move(terms)),
      robot_retries_(robot_retries),
      robot_fault_limit_(robot_fault_limit) {
  std::error_code error;
  std::filesystem::create_directories(dir_, error);
  if (error || !std::filesystem::is_directory(dir_)) {
    throw std::invalid_argument(what_ + ": cannot create the directory '" + dir_ + "'");
  }
  read();
}

std::string RunDirectory::columns() const {
  std::string columns = "algorithm,run,epoch,kind,index,seed,outcome,reward";
  for (const std::string& t : terms_) columns += ',' + t;
  return columns + ",latent_dims,wall_seconds,reason";
}

void RunDirectory::lock(const std::string& name, const std::string& text, const std::string& otherwise) {
  const std::string path = dir_ + "/" + name;
  std::ifstream in{path};
  if (in && !stored_.empty()) {
    const std::string recorded{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
    if (recorded != text) {
      throw std::invalid_argument(what_ + ": '" + dir_ + "' holds rollouts " + otherwise + " (" + path +
                                  "): use another directory");
    }
    return;
  }
  std::ofstream out(path);
  out << text;
  if (!out.flush()) throw std::invalid_argument(what_ + ": cannot write '" + path + "'");
}

void RunDirectory::read() {
  const std::string rollouts = dir_ + "/rollouts.csv", parameters = dir_ + "/rollout_parameters.csv";
  // A run killed while it wrote a record leaves a partial last line: it is dropped (and its rollout run again).
  io::dropPartialRecord(rollouts);
  io::dropPartialRecord(parameters);
  std::map<std::string, Eigen::VectorXd> weights;
  std::ifstream p(parameters);
  std::string line;
  for (int n = 1; std::getline(p, line); ++n) {
    if (n == 1 || line.empty()) continue;
    const std::string where = parameters + " line " + std::to_string(n);
    const std::vector<std::string> f = io::splitCsv(line);
    if (f.size() < 6) throw std::invalid_argument(where + ": too few fields");
    const int size = io::parseInteger(f[5], where);
    if (size < 0 || f.size() != 6 + static_cast<std::size_t>(size)) {
      throw std::invalid_argument(where + ": not the " + f[5] + " weights it announces");
    }
    Eigen::VectorXd w(size);
    for (int i = 0; i < size; ++i) w[i] = io::parseNumber(f[6 + static_cast<std::size_t>(i)], where);
    weights[rolloutKey(f[0], io::parseInteger(f[1], where), io::parseInteger(f[2], where),
                       rolloutKindFromString(f[3], where), io::parseInteger(f[4], where))] = w;
  }
  std::ifstream r(rollouts);
  const std::size_t terms = terms_.size(), fields = 8 + terms + 3;
  for (int n = 1; std::getline(r, line); ++n) {
    if (n == 1 && line != columns()) {
      throw std::invalid_argument(what_ + ": " + rollouts + " has other columns (" + line +
                                  "), written for another task or by another version: use another directory");
    }
    if (n == 1 || line.empty()) continue;
    const std::string where = rollouts + " line " + std::to_string(n);
    const std::vector<std::string> f = io::splitCsv(line);
    if (f.size() != fields) throw std::invalid_argument(where + ": expected " + columns());
    DmpRolloutRecord rec;
    rec.algorithm = f[0];
    rec.run = io::parseInteger(f[1], where);
    rec.epoch = io::parseInteger(f[2], where);
    rec.kind = rolloutKindFromString(f[3], where);
    rec.index = io::parseInteger(f[4], where);
    rec.seed = static_cast<std::uint32_t>(io::parseNumber(f[5], where));
    rec.result.outcome = f[6];
    rec.result.ok = f[6] == "Ok";
    rec.result.reward = io::parseNumber(f[7], where);
    rec.result.terms.resize(static_cast<Eigen::Index>(terms));
    for (std::size_t t = 0; t < terms; ++t) {
      rec.result.terms[static_cast<Eigen::Index>(t)] = io::parseNumber(f[8 + t], where);
    }
    rec.result.wall_seconds = io::parseNumber(f[9 + terms], where);
    rec.result.reason = f[10 + terms];
    rec.resumed = true;
    // A robot's fault says nothing of the policy (written by versions that learned from them): run it again.
    if (rec.result.outcome == "RobotFailed") continue;
    const std::string k = rolloutKey(rec.algorithm, rec.run, rec.epoch, rec.kind, rec.index);
    const auto w = weights.find(k);
    if (w == weights.end()) continue;  // interrupted between the two files: run it again
    rec.weights = w->second;
    stored_[k] = rec;
  }
}

void RunDirectory::open() {
  try {
    rollouts_csv_ = io::CsvAppender(dir_ + "/rollouts.csv", columns());
    parameters_csv_ =
        io::CsvAppender(dir_ + "/rollout_parameters.csv", "algorithm,run,epoch,kind,index,size,weights...");
    faults_csv_ = io::CsvAppender(dir_ + "/robot_faults.csv",
                                  "algorithm,run,epoch,kind,index,seed,attempt,retried,wall_seconds,reason");
  } catch (const std::runtime_error& e) {
    throw std::invalid_argument(what_ + ": " + e.what());
  }
}

std::string RunDirectory::prefix(const DmpRolloutRecord& rec) const {
  std::ostringstream line;
  line << io::quotedField(rec.algorithm) << ',' << rec.run << ',' << rec.epoch << ',' << toString(rec.kind) << ','
       << rec.index;
  return line.str();
}

void RunDirectory::write(const DmpRolloutRecord& rec) {
  std::ostringstream line;
  line << prefix(rec) << ',' << rec.seed << ',' << rec.result.outcome << ',' << io::exactNumber(rec.result.reward);
  for (Eigen::Index t = 0; t < rec.result.terms.size(); ++t) line << ',' << io::exactNumber(rec.result.terms[t]);
  line << ',' << (rec.coordination.empty() ? 0 : rec.coordination.front().cols()) << ','
       << io::exactNumber(rec.result.wall_seconds) << ',' << io::quotedField(rec.result.reason);
  rollouts_csv_.append(line.str());
  // The parameters last: a rollout counts as stored once both records are whole.
  line.str("");
  line << prefix(rec) << ',' << rec.weights.size();
  for (Eigen::Index i = 0; i < rec.weights.size(); ++i) line << ',' << io::exactNumber(rec.weights[i]);
  parameters_csv_.append(line.str());
}

void RunDirectory::evaluate(std::vector<DmpRolloutRecord>& batch, Evaluator& evaluator, const Hooks& hooks) {
  std::vector<std::size_t> pending;
  for (std::size_t i = 0; i < batch.size(); ++i) {
    DmpRolloutRecord& rec = batch[i];
    const auto found = stored_.find(rolloutKey(rec.algorithm, rec.run, rec.epoch, rec.kind, rec.index));
    if (found == stored_.end()) {
      pending.push_back(i);
      continue;
    }
    if (found->second.weights.size() != rec.weights.size() || found->second.weights != rec.weights ||
        found->second.seed != rec.seed) {
      throw std::invalid_argument(what_ + ": '" + dir_ + "' holds rollout " + found->first +
                                  " with other parameters: it belongs to another configuration or seed (use a new "
                                  "directory)");
    }
    rec.result = found->second.result;
    rec.resumed = true;
    ++resumed_;
    if (hooks.resumed) hooks.resumed(rec);
  }
  // Robot faults are run again (same parameters, same seed) until the robot runs them or gives up.
  for (int k = 1; !pending.empty(); ++k) pending = attempt(batch, pending, k, evaluator, hooks);
}

std::vector<std::size_t> RunDirectory::attempt(std::vector<DmpRolloutRecord>& batch,
                                               const std::vector<std::size_t>& pending, int attempt,
                                               Evaluator& evaluator, const Hooks& hooks) {
  std::vector<RolloutRequest> requests;
  for (const std::size_t i : pending) {
    requests.push_back({encodeCoordinatedPolicy(batch[i].coordination, batch[i].weights), batch[i].seed});
  }
  std::vector<std::size_t> faulted;
  std::string fault;  // why the learning stops, once it must
  const auto stop = [&] { return !fault.empty() || (hooks.stop && hooks.stop()); };
  // done() runs under the evaluator's lock: the files, the counters and the hooks see one rollout at a time.
  try {
    evaluator.evaluate(
        requests,
        [&](std::size_t n, const RolloutResult& result, RolloutTask* task) {
          DmpRolloutRecord& rec = batch[pending[n]];
          rec.result = result;
          if (result.terms.size() != static_cast<Eigen::Index>(terms_.size())) {
            rec.result.ok = false;
            rec.result.outcome = "RobotFailed";
            rec.result.reason = "the rollout returned " + std::to_string(result.terms.size()) + " terms, not " +
                                std::to_string(terms_.size()) + " (" + result.reason + ")";
          }
          if (rec.result.outcome == "RobotFailed") {
            onRobotFault(rec, attempt, fault, hooks);
            faulted.push_back(pending[n]);
            return;
          }
          faults_in_a_row_ = 0;
          write(rec);
          ++ran_;
          if (hooks.ran) hooks.ran(rec, task);
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

void RunDirectory::onRobotFault(const DmpRolloutRecord& rec, int attempt, std::string& fault, const Hooks& hooks) {
  ++robot_faults_;
  ++faults_in_a_row_;
  const bool retry = attempt <= robot_retries_ && faults_in_a_row_ < robot_fault_limit_;
  std::ostringstream line;
  line << prefix(rec) << ',' << rec.seed << ',' << attempt << ',' << (retry ? 1 : 0) << ','
       << io::exactNumber(rec.result.wall_seconds) << ',' << io::quotedField(rec.result.reason);
  faults_csv_.append(line.str());
  if (hooks.robot_fault) hooks.robot_fault(rec, attempt, rec.result.reason, retry);
  if (retry || !fault.empty()) return;
  std::ostringstream why;
  why << "the robot failed ";
  if (faults_in_a_row_ >= robot_fault_limit_) {
    why << faults_in_a_row_ << " times in a row (robot_fault_limit " << robot_fault_limit_ << ")";
  } else {
    why << "rollout " << rolloutKey(rec.algorithm, rec.run, rec.epoch, rec.kind, rec.index) << ' ' << attempt
        << " times (robot_retries " << robot_retries_ << ")";
  }
  why << "; the last: " << rec.result.reason << ". Fix the robot and run again: the finished rollouts are kept";
  fault = why.str();
}

}  // namespace bimanual_skills::rollout

#include "bimanual_skills/rollout/dmp_learning.hpp"

#include "bimanual_skills/learning/covariance_adaptation.hpp"
#include "bimanual_skills/learning/gaussian.hpp"
#include "bimanual_skills/learning/pi2.hpp"
#include "bimanual_skills/realtime/clock.hpp"
#include "bimanual_skills/rollout/coordinated_parameters.hpp"
#include "dmp_search.hpp"
#include "io/csv_records.hpp"
#include "io/whole_file.hpp"
#include "run_directory.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <regex>
#include <sstream>

namespace bimanual_skills::rollout {

namespace {

constexpr double kInfinity = std::numeric_limits<double>::infinity();

}  // namespace

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

RolloutKind rolloutKindFromString(const std::string& text, const std::string& where) {
  for (const RolloutKind kind : {RolloutKind::Sample, RolloutKind::Policy, RolloutKind::Repetition}) {
    if (text == toString(kind)) return kind;
  }
  throw std::invalid_argument(where + ": unknown rollout kind '" + text + "'");
}

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
  } else if (name == "REPS" || name == "DREPS") {
    v.latent_dims = dofs;
    v.search = name == "REPS" ? PolicySearch::StandardReps : PolicySearch::Dreps;
  } else {
    throw std::invalid_argument("unknown algorithm '" + name +
                                "' (DR-DMP0(r), DR-DMP_CMU(r), DR-DMP_MCMU(Ns,r), IDR-DMP_CMU, IDR-DMP_MCMU(Ns), "
                                "PI2-CMA, CMA-ES, REPS, DREPS)");
  }
  if (v.latent_dims < 1 || v.latent_dims > dofs || v.matrices < 1 || v.matrices > 20) {
    throw std::invalid_argument("algorithm '" + name + "': r must be in [1, " + std::to_string(dofs) +
                                "] and Ns in [1, 20]");
  }
  return v;
}

learning::CoordinatedPolicy pi2CmaStep(learning::CoordinatedPolicy policy, const Eigen::MatrixXd& samples,
                                       const Eigen::VectorXd& rewards, const Eigen::MatrixXd& basis, double memory,
                                       double h, bool diagonal) {
  learning::Pi2Parameters parameters;
  parameters.covariance_adaptation = true;
  parameters.h = h;
  Eigen::MatrixXd costs = Eigen::MatrixXd::Zero(samples.rows(), basis.rows());
  costs.col(costs.cols() - 1) = -rewards;
  const learning::Pi2Update update =
      learning::pi2Update(parameters, policy.mean, policy.covariance, samples, costs, basis);
  policy.mean = update.mean;
  const Eigen::MatrixXd adapted =
      diagonal ? Eigen::MatrixXd(update.covariance.diagonal().asDiagonal()) : update.covariance;
  policy.covariance = (1.0 - memory) * adapted + memory * policy.covariance;
  return policy;
}

Eigen::MatrixXd dualLayer(int kernels, int layer) {
  if (layer < 1 || layer > kernels) {
    throw std::invalid_argument("dual layer: between 1 and " + std::to_string(kernels) + " weights per DoF");
  }
  Eigen::MatrixXd phi(kernels, layer);
  const double spacing = layer > 1 ? static_cast<double>(kernels - 1) / (layer - 1) : static_cast<double>(kernels);
  for (int j = 0; j < kernels; ++j) {
    for (int l = 0; l < layer; ++l) {
      const double centre = layer > 1 ? l * spacing : 0.5 * (kernels - 1);
      const double u = (j - centre) / spacing;
      phi(j, l) = std::exp(-0.5 * u * u);
    }
    phi.row(j) /= phi.row(j).sum();
  }
  return phi;
}

void DmpLearningConfig::validate(int dofs) const {
  if (algorithms.empty()) throw std::invalid_argument("DMP learning: no algorithm");
  for (const std::string& a : algorithms) parseDrDmpVariant(a, dofs, eta);
  if (runs < 1 || updates < 0 || rollouts < 2 || reuse < 0 || jobs < 0) {
    throw std::invalid_argument("DMP learning: runs >= 1, updates >= 0, rollouts >= 2, reuse and jobs >= 0");
  }
  if (!(epsilon > 0.0) || !(eta > 1.0) || !(initial_stddev > 0.0) || !std::isfinite(initial_stddev) || !(h > 0.0) ||
      !std::isfinite(h)) {
    throw std::invalid_argument("DMP learning: epsilon > 0, eta > 1, a finite initial_stddev > 0 and h > 0");
  }
  if (!(covariance_memory >= 0.0 && covariance_memory < 1.0)) {
    throw std::invalid_argument("DMP learning: covariance_memory in [0, 1)");
  }
  if (dual_kernels < 0) throw std::invalid_argument("DMP learning: dual_kernels >= 0");
  if (robot_retries < 0 || robot_retries > 100 || robot_fault_limit < 1 || robot_fault_limit > 1000) {
    throw std::invalid_argument("DMP learning: robot_retries in [0, 100] and robot_fault_limit in [1, 1000]");
  }
}

struct DmpLearner::Impl {
  DmpTaskModel model;
  DmpLearningConfig config;
  std::unique_ptr<RunDirectory> dir;
  std::unique_ptr<Evaluator> evaluator;
  DmpLearningObserver observer;
  int success_term = -1;

  void evaluate(std::vector<DmpRolloutRecord>& batch) {
    RunDirectory::Hooks hooks;
    hooks.ran = observer.rollout;
    if (observer.rollout) hooks.resumed = [this](const DmpRolloutRecord& rec) { observer.rollout(rec, nullptr); };
    hooks.robot_fault = observer.robot_fault;
    hooks.stop = observer.stop;
    dir->evaluate(batch, *evaluator, hooks);
  }

  bool succeeded(const DmpRolloutRecord& rec) const {
    return success_term >= 0 && rec.result.ok && rec.result.terms[success_term] > 0.5;
  }

  DmpEpochStats epochStats(const std::string& algorithm, int run, int epoch, int latent_dims,
                           const std::vector<DmpRolloutRecord>& batch) const {
    DmpEpochStats s;
    s.algorithm = algorithm;
    s.run = run;
    s.epoch = epoch;
    s.latent_dims = latent_dims;
    s.term_means = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(model.terms.size()));
    double sum = 0.0, squares = 0.0;
    int samples = 0;
    for (const DmpRolloutRecord& rec : batch) {
      if (rec.kind == RolloutKind::Policy) {
        s.policy_reward = rec.result.reward;
        s.policy_failed = !rec.result.ok;
        s.policy_success = succeeded(rec);
        continue;
      }
      ++samples;
      sum += rec.result.reward;
      squares += rec.result.reward * rec.result.reward;
      s.term_means += rec.result.terms;
      if (!rec.result.ok) ++s.failures;
      if (succeeded(rec)) ++s.successes;
    }
    s.mean_reward = sum / samples;
    s.std_reward = samples > 1 ? std::sqrt(std::max(0.0, (squares - sum * sum / samples) / (samples - 1))) : 0.0;
    s.term_means /= samples;
    return s;
  }

  void writeEpochs(const std::vector<DmpRunResult>& finished, const DmpRunResult& current) const {
    std::ostringstream csv;
    csv << "algorithm,run,epoch,latent_dims,failures,successes,mean_reward,std_reward";
    for (const std::string& t : model.terms) csv << ',' << t;
    csv << ",policy_reward,policy_failed,policy_success\n";
    std::vector<const DmpRunResult*> runs;
    for (const DmpRunResult& run : finished) runs.push_back(&run);
    runs.push_back(&current);
    for (const DmpRunResult* run : runs) {
      for (const DmpEpochStats& s : run->epochs) {
        csv << io::quotedField(s.algorithm) << ',' << s.run << ',' << s.epoch << ',' << s.latent_dims << ','
            << s.failures << ',' << s.successes << ',' << io::exactNumber(s.mean_reward) << ','
            << io::exactNumber(s.std_reward);
        for (Eigen::Index t = 0; t < s.term_means.size(); ++t) csv << ',' << io::exactNumber(s.term_means[t]);
        csv << ',' << io::exactNumber(s.policy_reward) << ',' << (s.policy_failed ? 1 : 0) << ','
            << (s.policy_success ? 1 : 0) << '\n';
      }
    }
    const std::string path = dir->path() + "/epochs.csv";
    if (!io::writeWhole(path, [&csv](std::ostream& out) { out << csv.str(); })) {
      throw std::runtime_error("DMP learning: cannot write '" + path + "'");
    }
  }

  DmpRunResult learnRun(const std::string& algorithm, int algorithm_index, int run,
                        const std::vector<DmpRunResult>& done) {
    const auto start = realtime::Clock::now();
    const DrDmpVariant variant = parseDrDmpVariant(algorithm, model.dofs, config.eta);
    DmpSearch::Settings settings;
    settings.epsilon = config.epsilon;
    settings.reuse = config.reuse;
    settings.covariance_memory = config.covariance_memory;
    settings.h = config.h;
    settings.initial_stddev = config.initial_stddev;
    settings.dual_kernels = config.dual_kernels;
    settings.diagonal_covariance = config.diagonal_covariance;
    DmpSearch search(variant, model.forcing(variant.matrices), model.demonstration, model.step, settings);
    DmpRunResult result;
    result.best.result.reward = -kInfinity;
    searchRun<DmpRolloutRecord>(
        search, algorithm, algorithm_index, run, config.seed, config.updates, config.rollouts, result,
        [this](std::vector<DmpRolloutRecord>& batch) { evaluate(batch); },
        [](const DmpRolloutRecord& rec) { return rec.result.reward; },
        [](const DmpRolloutRecord& rec) { return rec.result.ok; },
        [&](int epoch, int latent_dims, const std::vector<DmpRolloutRecord>& batch) {
          result.epochs.push_back(epochStats(algorithm, run, epoch, latent_dims, batch));
          if (observer.epoch) observer.epoch(result.epochs.back());
          writeEpochs(done, result);
        });
    result.seconds = realtime::secondsSince(start);
    return result;
  }
};

DmpLearner::DmpLearner(DmpTaskModel model, const DmpLearningConfig& config, const std::string& out_dir,
                       std::unique_ptr<Evaluator> evaluator, DmpLearningObserver observer)
    : impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  if (model.dofs < 1 || !model.forcing || model.demonstration.cols() != model.dofs || model.demonstration.rows() < 2 ||
      !(model.step > 0.0)) {
    throw std::invalid_argument("DMP learning: the task model needs DoF, forcing parameters and a demonstration");
  }
  if (!evaluator) throw std::invalid_argument("DMP learning: no evaluator");
  config.validate(model.dofs);
  for (std::size_t t = 0; t < model.terms.size(); ++t) {
    if (model.terms[t] == model.success) m.success_term = static_cast<int>(t);
  }
  if (!model.success.empty() && m.success_term < 0) {
    throw std::invalid_argument("DMP learning: no term '" + model.success + "' among the task's terms");
  }
  m.model = std::move(model);
  m.config = config;
  m.evaluator = std::move(evaluator);
  m.observer = std::move(observer);
  m.dir = std::make_unique<RunDirectory>(out_dir, m.model.terms, "DMP learning", config.robot_retries,
                                         config.robot_fault_limit);
  for (const auto& [name, text] : m.model.locks) m.dir->lock(name, text, "of another configuration");
  m.dir->open();
}

DmpLearner::~DmpLearner() = default;

DmpLearningResult DmpLearner::learn() {
  Impl& m = *impl_;
  const auto start = realtime::Clock::now();
  DmpLearningResult result;
  for (std::size_t a = 0; a < m.config.algorithms.size(); ++a) {
    for (int run = 0; run < m.config.runs; ++run) {
      result.runs.push_back(m.learnRun(m.config.algorithms[a], static_cast<int>(a), run, result.runs));
    }
  }
  result.ran = m.dir->ran();
  result.resumed = m.dir->resumed();
  result.robot_faults = m.dir->robotFaults();
  result.seconds = realtime::secondsSince(start);
  return result;
}

}  // namespace bimanual_skills::rollout

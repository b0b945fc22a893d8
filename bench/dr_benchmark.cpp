// The thesis' reward-oriented dimensionality-reduction experiments (Ch. 7: Fig. 7.2, Fig. 7.5, Tables 7.3 and 7.4)
// and the E-step benchmark, and the NAO walking synergies (Figs. 7.3-7.4, from generated walks), as one seeded
// program.
//
//   dr_benchmark --experiment estep|em_vs_pca|planar15|planar10|wam_circle|optima|nao_walking|all --runs R --seed S
//                --out DIR [--jobs N] [--quick]
//
// Independent runs go to N threads; every run draws from its own generator seeded by (seed, experiment, run), the
// same for every algorithm, so the results do not depend on N. Writes DIR/<experiment>.csv (rows in run order),
// DIR/summary.json, for planar10 and wam_circle the first run's paths before and after learning and the task's
// target (DIR/<experiment>_paths.csv, DIR/<experiment>_target.csv), then runs scripts/plot_dr_benchmark.py for the
// PNGs (learning curves with the mean and 95 % interval over runs, paths) and DIR/tables.md.
#include "bimanual_skills/learning/coordinated_reps.hpp"
#include "bimanual_skills/learning/gaussian.hpp"
#include "bimanual_skills/learning/latent_trajectory_em.hpp"
#include "bimanual_skills/learning/student_t.hpp"
#include "bimanual_skills/primitives/dr_dmp.hpp"
#include "bimanual_skills/primitives/dr_promp.hpp"
#include "bimanual_skills/realtime/clock.hpp"
#include "bimanual_skills/tasks/dr_tasks.hpp"
#include "bimanual_skills/tasks/nao_walking.hpp"
#include "cli/package_share.hpp"
#include "cli/pinned_numerics.hpp"
#include "experiment_cli.hpp"
#include "parallel_runs.hpp"

#include <Eigen/QR>
#include <nlopt.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <memory>
#include <random>
#include <stdexcept>
#include <string>
#include <tuple>
#include <vector>

namespace bb = bimanual_skills::bench;
namespace bk = bimanual_skills::kinematics;
namespace bl = bimanual_skills::learning;
namespace bp = bimanual_skills::primitives;
namespace bt = bimanual_skills::tasks;

namespace {

constexpr double kInfinity = std::numeric_limits<double>::infinity();

using Options = bb::ExperimentOptions;

/// --algorithms: the names of the algorithms to run in planar15, planar10 and wam_circle (empty: all).
std::vector<std::string> selected_algorithms;
/// Command-line overrides of the planar10 and wam_circle settings (NaN or -1: the experiment's).
struct DrDmpOverrides {
  double covariance_memory = std::numeric_limits<double>::quiet_NaN();  ///< --covariance-memory: λ.
  double exploration = std::numeric_limits<double>::quiet_NaN();        ///< --exploration: σ outside the subspace.
  double epsilon = std::numeric_limits<double>::quiet_NaN();            ///< --epsilon: REPS' KL bound.
  double forcing_variance = std::numeric_limits<double>::quiet_NaN();   ///< --forcing-variance (one demonstration).
  double relative_prior = std::numeric_limits<double>::quiet_NaN();     ///< --relative-prior (demonstrations).
  double alpha_z = std::numeric_limits<double>::quiet_NaN();            ///< --alpha-z: the DMPs' stiffness.
  long kernels = -1;                ///< --kernels: basis functions per latent DoF (-1: the experiment's).
  long rollouts = -1;               ///< --rollouts: rollouts per update (-1: the thesis' 20).
  long reuse = -1;                  ///< --reuse: rollouts kept (-1: the experiment's).
  long updates = -1;                ///< --updates: policy updates per run (-1: the thesis').
  bool adapted_covariance = false;  ///< --adapted-covariance: CovarianceRule::Adapted instead of REPS' own.
  /// --demonstration: where wam_circle's demonstration is perturbed.
  bt::CirclePerturbation demonstration = bt::CirclePerturbation::Joint;
  /// --circle: the circle wam_circle's reward measures distances from.
  bt::CircleTarget circle = bt::CircleTarget::Fitted;
} overrides;
using bimanual_skills::realtime::Clock;
using bimanual_skills::realtime::secondsSince;

// ---- the learning loop shared by planar15, planar10 and wam_circle ----

/// A rollout of latent weights ω through coordination matrices Ω_s: fills the values the coordination update
/// learns from (forcing terms or positions) and returns the reward. `rng` is null for the noise-free evaluation of
/// the mean policy.
using Rollout = std::function<double(const std::vector<Eigen::MatrixXd>& coordination, const Eigen::VectorXd& weights,
                                     std::mt19937* rng, Eigen::MatrixXd& values)>;

/// Everything one run of one algorithm needs; built inside the run (tasks hold scratch).
struct Setup {
  bl::CoordinatedRepsParameters parameters;
  std::shared_ptr<const bl::CoordinationGrid> grid;
  bl::CoordinatedPolicy policy;
  std::vector<Eigen::MatrixXd> excitation;
  Rollout rollout;
  /// The noise-free path of a policy for the pictures (one row per sample; empty: none).
  std::function<Eigen::MatrixXd(const std::vector<Eigen::MatrixXd>& coordination, const Eigen::VectorXd& weights)> path;
};

struct Protocol {
  int runs = 10;
  int updates = 100;
  int rollouts = 20;        ///< Per update.
  int first_rollouts = 20;  ///< Of the first update.
};

/// One run's learning curve: the mean policy's reward before the first update and after each, the mean reward of
/// each update's rollouts, the latent dimension after each update; the mean policy's path before and after learning.
struct Curve {
  std::vector<double> policy_reward, rollout_reward;
  std::vector<int> latent_dims;
  double seconds = 0.0;
  Eigen::MatrixXd initial_path, final_path;
};

Curve learn(const Setup& setup, const Protocol& protocol, std::mt19937& rng) {
  Curve curve;
  bl::CoordinatedReps learner(setup.parameters, *setup.grid, setup.policy, setup.excitation);
  bl::GaussianSampler sampler;
  Eigen::MatrixXd values;
  const auto evaluate = [&]() {
    const bl::CoordinatedPolicy& policy = learner.policy();
    return setup.rollout(policy.coordination, policy.mean, nullptr, values);
  };
  curve.policy_reward.push_back(evaluate());
  curve.latent_dims.push_back(learner.policy().latentDims());
  if (setup.path) curve.initial_path = setup.path(learner.policy().coordination, learner.policy().mean);
  const auto start = Clock::now();
  for (int u = 0; u < protocol.updates; ++u) {
    const bl::CoordinatedPolicy& policy = learner.policy();
    const int count = u == 0 ? protocol.first_rollouts : protocol.rollouts;
    const Eigen::MatrixXd L = bl::choleskyFactor(policy.covariance);
    Eigen::MatrixXd samples(count, policy.mean.size());
    std::vector<Eigen::MatrixXd> rollout_values(static_cast<std::size_t>(count));
    Eigen::VectorXd rewards(count);
    for (int k = 0; k < count; ++k) {
      samples.row(k) = sampler.draw(policy.mean, L, rng).transpose();
      rewards[k] = setup.rollout(policy.coordination, samples.row(k).transpose(), &rng,
                                 rollout_values[static_cast<std::size_t>(k)]);
    }
    learner.update(samples, rollout_values, rewards);
    curve.policy_reward.push_back(evaluate());
    curve.rollout_reward.push_back(rewards.mean());
    curve.latent_dims.push_back(learner.policy().latentDims());
  }
  curve.seconds = secondsSince(start);
  if (setup.path) curve.final_path = setup.path(learner.policy().coordination, learner.policy().mean);
  return curve;
}

struct Algorithm {
  std::string name;
  std::function<Setup()> setup;
};

/// Row of summary.json.
struct Summary {
  std::string experiment, algorithm;
  std::vector<std::pair<std::string, double>> numbers;
  std::vector<std::pair<std::string, std::string>> texts;
};

/// Rows of DIR/<experiment>_paths.csv: the first run's path of one algorithm's mean policy before and after learning.
void writePaths(std::ofstream& csv, const std::string& algorithm, const Curve& curve) {
  for (const auto& [policy, path] :
       {std::pair{"initial", &curve.initial_path}, std::pair{"final", &curve.final_path}}) {
    for (Eigen::Index i = 0; i < path->rows(); ++i) {
      csv << '"' << algorithm << "\"," << policy << ',' << i;
      for (Eigen::Index j = 0; j < path->cols(); ++j) csv << ',' << (*path)(i, j);
      csv << '\n';
    }
  }
}

/// Runs every (algorithm, run) pair on options.jobs threads; writes DIR/<experiment>.csv in (algorithm, run) order
/// and one summary row per algorithm.
void runLearning(const Options& options, const std::string& experiment, const Protocol& protocol,
                 std::vector<Algorithm> algorithms, std::vector<Summary>& out,
                 const std::vector<std::string>& path_columns = {}) {
  if (!selected_algorithms.empty()) {
    std::string names;
    for (const Algorithm& a : algorithms) names += (names.empty() ? "" : ", ") + a.name;
    algorithms.erase(std::remove_if(algorithms.begin(), algorithms.end(),
                                    [](const Algorithm& a) {
                                      return std::find(selected_algorithms.begin(), selected_algorithms.end(),
                                                       a.name) == selected_algorithms.end();
                                    }),
                     algorithms.end());
    if (algorithms.empty() && options.experiment == "all") {
      std::printf("  %s: none of --algorithms is one of its algorithms (%s); skipped\n", experiment.c_str(),
                  names.c_str());
      return;
    }
    if (algorithms.empty()) {
      throw std::invalid_argument("--algorithms names none of " + experiment + "'s algorithms: " + names);
    }
  }
  const int runs = protocol.runs;
  const int jobs = static_cast<int>(algorithms.size()) * runs;
  std::vector<Curve> curves(static_cast<std::size_t>(jobs));
  std::ofstream csv(options.out + "/" + experiment + ".csv");
  csv << "experiment,algorithm,run,update,policy_reward,rollout_reward,latent_dims\n";
  csv.precision(10);
  std::ofstream paths;
  if (!path_columns.empty()) {
    paths.open(options.out + "/" + experiment + "_paths.csv");
    paths << "algorithm,policy,sample";
    for (const std::string& column : path_columns) paths << ',' << column;
    paths << '\n';
    paths.precision(10);
  }
  const auto wall = Clock::now();
  bb::parallelRuns(
      jobs, options.jobs,
      [&](int i) {
        const Algorithm& algorithm = algorithms[static_cast<std::size_t>(i / runs)];
        std::mt19937 rng = bb::runGenerator(options, experiment, i % runs);
        curves[static_cast<std::size_t>(i)] = learn(algorithm.setup(), protocol, rng);
      },
      [&](int i) {
        const Algorithm& algorithm = algorithms[static_cast<std::size_t>(i / runs)];
        const Curve& c = curves[static_cast<std::size_t>(i)];
        for (std::size_t u = 0; u < c.policy_reward.size(); ++u) {
          csv << experiment << ",\"" << algorithm.name << "\"," << i % runs << ',' << u << ',' << c.policy_reward[u]
              << ',' << (u > 0 ? c.rollout_reward[u - 1] : c.policy_reward[0]) << ',' << c.latent_dims[u] << '\n';
        }
        csv.flush();
        if (paths.is_open() && i % runs == 0) {
          writePaths(paths, algorithm.name, c);
          paths.flush();
        }
        if (i % runs == runs - 1) {
          double sum = 0.0, squares = 0.0, dims = 0.0, time = 0.0;
          for (int r = i - runs + 1; r <= i; ++r) {
            const Curve& run = curves[static_cast<std::size_t>(r)];
            sum += run.policy_reward.back();
            squares += run.policy_reward.back() * run.policy_reward.back();
            dims += run.latent_dims.back();
            time += run.seconds;
          }
          const double mean = sum / runs;
          const double std = std::sqrt(std::max(0.0, squares / runs - mean * mean));
          std::printf("  %s %-22s %d runs: final policy reward %.4g ± %.2g, latent dims %.1f (%.1f s per run)\n",
                      experiment.c_str(), algorithm.name.c_str(), runs, mean, std, dims / runs, time / runs);
          std::fflush(stdout);
          out.push_back({experiment,
                         algorithm.name,
                         {{"runs", runs},
                          {"updates", protocol.updates},
                          {"rollouts_per_update", protocol.rollouts},
                          {"final_reward", mean},
                          {"final_reward_std", std},
                          {"final_reward_ci95", runs > 1 ? bimanual_skills::learning::studentT975(runs - 1) * std *
                                                               std::sqrt(runs / (runs - 1.0)) / std::sqrt(runs)
                                                         : 0.0},
                          {"initial_reward", curves[static_cast<std::size_t>(i)].policy_reward.front()},
                          {"final_latent_dims", dims / runs},
                          {"seconds_per_update", time / (runs * std::max(protocol.updates, 1))}},
                         {}});
        }
      });
  std::printf("  %s: %d runs of %zu algorithms in %.1f s on %d threads\n", experiment.c_str(), runs, algorithms.size(),
              secondsSince(wall), options.jobs);
}

int runsOf(const Options& options, int runs, int quick_runs) {
  return options.runs > 0 ? options.runs : (options.quick ? quick_runs : runs);
}

// ---- estep: the E-step with the Kronecker structure against the printed one ----

/// A random latent model of d DoF, r latent DoF and the grid's kernels (orthonormal Ω, Σ_ω and Σ_y of full rank),
/// and `trajectories` drawn from it with weights from 0.5 to 1.5.
struct RandomModel {
  bl::LatentTrajectoryModel model;
  bl::WeightedTrajectories data;
};

RandomModel randomModel(const bl::CoordinationGrid& grid, int d, int r, int trajectories, std::mt19937& rng) {
  const int n = grid.kernels();
  std::normal_distribution<double> normal(0.0, 1.0);
  const auto random = [&](int rows, int cols) {
    Eigen::MatrixXd m(rows, cols);
    for (int j = 0; j < cols; ++j) {
      for (int i = 0; i < rows; ++i) m(i, j) = normal(rng);
    }
    return m;
  };
  RandomModel out;
  out.model.coordination =
      Eigen::HouseholderQR<Eigen::MatrixXd>(random(d, r)).householderQ() * Eigen::MatrixXd::Identity(d, r);
  out.model.mean = random(r * n, 1);
  const Eigen::MatrixXd B = random(r * n, r * n) / std::sqrt(r * n);
  out.model.covariance = B * B.transpose() + 0.05 * Eigen::MatrixXd::Identity(r * n, r * n);
  const Eigen::MatrixXd C = random(d, d) / std::sqrt(d);
  out.model.noise = 0.01 * (C * C.transpose() + Eigen::MatrixXd::Identity(d, d));
  out.model.context_gain = Eigen::MatrixXd(r * n, 0);
  if (trajectories == 0) return out;
  const Eigen::MatrixXd L = bl::choleskyFactor(out.model.covariance), Ly = bl::choleskyFactor(out.model.noise);
  bl::GaussianSampler sampler;
  for (int k = 0; k < trajectories; ++k) {
    const Eigen::VectorXd w = sampler.draw(out.model.mean, L, rng);
    Eigen::MatrixXd y = bl::coordinatedValues(grid, {out.model.coordination}, w);
    for (int t = 0; t < grid.steps(); ++t) y.row(t) += sampler.draw(Eigen::VectorXd::Zero(d), Ly, rng).transpose();
    out.data.trajectories.push_back(y);
  }
  out.data.weights = Eigen::VectorXd::LinSpaced(trajectories, 0.5, 1.5);
  out.data.contexts = Eigen::MatrixXd(trajectories, 0);
  return out;
}

/// Median time of `call` in milliseconds over `repetitions` calls.
double medianMilliseconds(int repetitions, const std::function<void()>& call) {
  std::vector<double> times;
  for (int i = 0; i < repetitions; ++i) {
    const auto start = Clock::now();
    call();
    times.push_back(1e3 * secondsSince(start));
  }
  std::sort(times.begin(), times.end());
  return times[times.size() / 2];
}

void estep(const Options& options, std::vector<Summary>& out) {
  constexpr int steps = 100, d = 14, r = 4, kernels = 20, trajectories = 20;
  bp::ProMpParameters promp;
  promp.kernels = kernels;
  const bl::CoordinationGrid grid = bp::DrProMp::grid(promp, steps);
  std::mt19937 rng = bb::runGenerator(options, "estep", 0);
  const RandomModel random = randomModel(grid, d, r, trajectories, rng);
  bl::LatentPosterior fast, naive;
  const double naive_ms = medianMilliseconds(options.quick ? 1 : 5,
                                             [&]() { naive = bl::latentEStepNaive(grid, random.model, random.data); });
  const double fast_ms =
      medianMilliseconds(options.quick ? 5 : 101, [&]() { fast = bl::latentEStep(grid, random.model, random.data); });
  const double mean_difference = (fast.means - naive.means).cwiseAbs().maxCoeff();
  const double covariance_difference = (fast.covariance - naive.covariance).cwiseAbs().maxCoeff();
  const double likelihood_fast = bl::latentLogLikelihood(grid, random.model, random.data);
  const double likelihood_naive = bl::latentLogLikelihoodNaive(grid, random.model, random.data);
  std::printf(
      "  estep: N_t = %d, d = %d, r = %d, %d kernels, %d trajectories: naive %.2f ms, fast %.3f ms "
      "(%.0fx), max |difference| %.2e (means) %.2e (covariance)\n",
      steps, d, r, kernels, trajectories, naive_ms, fast_ms, naive_ms / fast_ms, mean_difference,
      covariance_difference);
  out.push_back({"estep",
                 "E-step",
                 {{"steps", steps},
                  {"dofs", d},
                  {"latent_dims", r},
                  {"kernels", kernels},
                  {"trajectories", trajectories},
                  {"naive_ms", naive_ms},
                  {"fast_ms", fast_ms},
                  {"speedup", naive_ms / fast_ms},
                  {"max_difference_means", mean_difference},
                  {"max_difference_covariance", covariance_difference},
                  {"log_likelihood_relative_difference",
                   std::abs(likelihood_fast - likelihood_naive) / std::abs(likelihood_naive)},
                  {"final_reward", std::numeric_limits<double>::quiet_NaN()}},
                 {}});
}

// ---- em_vs_pca: KL(data ‖ model) of the EM and the PCA fits (Fig. 7.2, ρ of 7.21) ----

void emVsPca(const Options& options, std::vector<Summary>& out) {
  const std::vector<int> dofs = options.quick ? std::vector<int>{3, 5} : std::vector<int>{3, 5, 7, 10, 12};
  const int runs = runsOf(options, 5, 1);
  constexpr int steps = 100, kernels = 10, trajectories = 60;
  bp::ProMpParameters promp;
  promp.kernels = kernels;
  const bl::CoordinationGrid grid = bp::DrProMp::grid(promp, steps);
  struct Cell {
    int d, r, run;
    double kl_em = 0.0, kl_pca = 0.0;
    int iterations = 0;
  };
  std::vector<Cell> cells;
  for (const int d : dofs) {
    for (int r = 1; r < d; ++r) {
      for (int run = 0; run < runs; ++run) cells.push_back({d, r, run});
    }
  }
  bl::LatentEmParameters em;
  em.max_iterations = options.quick ? 5 : 100;
  em.tolerance = 1e-9;
  em.noise_floor = 1e-10;
  std::ofstream csv(options.out + "/em_vs_pca.csv");
  csv << "experiment,d,r,run,kl_em,kl_pca,rho,em_iterations\n";
  csv.precision(10);
  bb::parallelRuns(
      static_cast<int>(cells.size()), options.jobs,
      [&](int i) {
        Cell& cell = cells[static_cast<std::size_t>(i)];
        // The same data for every r of one (d, run): a full-rank d-DoF ProMP whose DoF are mixed by a random
        // orthonormal matrix with decaying scales 0.7^j, plus observation noise of 0.01² (Sec. 7.1.3, "simulated
        // ProMP data").
        std::mt19937 rng = bb::runGenerator(options, "em_vs_pca/" + std::to_string(cell.d), cell.run);
        bl::LatentTrajectoryModel generator = randomModel(grid, cell.d, cell.d, 0, rng).model;
        Eigen::VectorXd scales(cell.d);
        for (int j = 0; j < cell.d; ++j) scales[j] = std::pow(0.7, j);
        generator.coordination = generator.coordination * scales.asDiagonal();
        bl::WeightedTrajectories data;
        const Eigen::MatrixXd L = bl::choleskyFactor(generator.covariance);
        bl::GaussianSampler sampler;
        for (int k = 0; k < trajectories; ++k) {
          Eigen::MatrixXd y =
              bl::coordinatedValues(grid, {generator.coordination}, sampler.draw(generator.mean, L, rng));
          for (int t = 0; t < steps; ++t) {
            for (int j = 0; j < cell.d; ++j) y(t, j) += 0.01 * sampler.standardNormal(rng);
          }
          data.trajectories.push_back(y);
        }
        data.weights = Eigen::VectorXd::Ones(trajectories);
        data.contexts = Eigen::MatrixXd(trajectories, 0);
        bl::LatentPcaParameters pca;
        pca.noise_floor = 1e-10;
        const bl::LatentTrajectoryModel initial = bl::latentPcaModel(grid, data, cell.r, pca);
        const bl::LatentEmResult fitted = bl::latentEm(grid, data, initial, em);
        cell.iterations = fitted.iterations;
        // Σ_t KL(p(y_t; data) ‖ p(y_t; θ)), p(y_t; data) the Gaussian of the trajectories at step t.
        for (int t = 0; t < steps; ++t) {
          Eigen::MatrixXd at(trajectories, cell.d);
          for (int k = 0; k < trajectories; ++k) at.row(k) = data.trajectories[static_cast<std::size_t>(k)].row(t);
          const auto [mean, covariance] = bl::sampleMoments(at);
          Eigen::VectorXd model_mean;
          Eigen::MatrixXd model_covariance;
          bl::latentMarginal(grid, fitted.model, t, Eigen::VectorXd(), model_mean, model_covariance);
          cell.kl_em += bl::gaussianKl(mean, covariance, model_mean, model_covariance);
          bl::latentMarginal(grid, initial, t, Eigen::VectorXd(), model_mean, model_covariance);
          cell.kl_pca += bl::gaussianKl(mean, covariance, model_mean, model_covariance);
        }
      },
      [&](int i) {
        const Cell& c = cells[static_cast<std::size_t>(i)];
        const double rho = (c.kl_em - c.kl_pca) / c.kl_pca;
        csv << "em_vs_pca," << c.d << ',' << c.r << ',' << c.run << ',' << c.kl_em << ',' << c.kl_pca << ',' << rho
            << ',' << c.iterations << '\n';
        for (const bool is_em : {true, false}) {
          out.push_back({"em_vs_pca",
                         is_em ? "EM" : "PCA",
                         {{"d", c.d},
                          {"r", c.r},
                          {"run", c.run},
                          {"kl", is_em ? c.kl_em : c.kl_pca},
                          {"rho", rho},
                          {"final_reward", std::numeric_limits<double>::quiet_NaN()}},
                         {{"method", is_em ? "EM" : "PCA"}}});
        }
      });
  double em_sum = 0.0, pca_sum = 0.0;
  for (const Cell& c : cells) {
    em_sum += c.kl_em;
    pca_sum += c.kl_pca;
  }
  double rho_mean = 0.0;
  for (const Cell& c : cells) rho_mean += (c.kl_em - c.kl_pca) / c.kl_pca / cells.size();
  std::printf("  em_vs_pca: %zu fits, mean rho %.3f, rho of the sums %.3f\n", cells.size(), rho_mean,
              (em_sum - pca_sum) / pca_sum);
  out.push_back({"em_vs_pca",
                 "rho",
                 {{"fits", static_cast<double>(cells.size())},
                  {"rho_mean", rho_mean},
                  {"rho_of_sums", (em_sum - pca_sum) / pca_sum},
                  {"final_reward", std::numeric_limits<double>::quiet_NaN()}},
                 {}});
}

// ---- planar15: Cartesian tracking with a 15-DoF planar arm (Fig. 7.5) ----

/// Full-space weights (Ω ⊗ I_n) ω of latent weights.
Eigen::VectorXd liftedWeights(const Eigen::MatrixXd& omega, const Eigen::VectorXd& latent, int n) {
  Eigen::VectorXd out = Eigen::VectorXd::Zero(omega.rows() * n);
  for (Eigen::Index j = 0; j < omega.rows(); ++j) {
    for (Eigen::Index i = 0; i < omega.cols(); ++i) out.segment(j * n, n) += omega(j, i) * latent.segment(i * n, n);
  }
  return out;
}

void planar15(const Options& options, std::vector<Summary>& out) {
  constexpr int dofs = 15, kernels = 8;
  const bt::PlanarTrackingTask task(dofs, options.seed);
  const int samples = task.samples();
  Protocol protocol;
  protocol.runs = runsOf(options, 10, 2);
  protocol.updates = options.quick ? 3 : 100;
  protocol.rollouts = 20;
  protocol.first_rollouts = 100;
  bl::CoordinatedRepsParameters reps;
  reps.reps.epsilon = 0.5;
  reps.reps.reuse = 80;  // windows of 100 rollouts, 20 new per update
  reps.em.max_iterations = 20;
  reps.em.tolerance = 1e-6;
  reps.em.noise_floor = 1e-8;
  bp::ProMpParameters promp;
  promp.kernels = kernels;
  const auto grid = std::make_shared<const bl::CoordinationGrid>(bp::DrProMp::grid(promp, samples));
  const bp::ProMp full = bp::ProMp::fit(promp, task.demonstrations(), 1.0);

  std::vector<Algorithm> algorithms;
  // DMP+REPS: a DMP per DoF (8 kernels), weights of each demonstration by least squares, N(μ, Σ) over them; as a
  // DR-DMP with Ω = I fixed, which is exactly that DMP.
  algorithms.push_back(
      {"DMP+REPS", [&, grid]() {
         bp::DrDmpParameters parameters;
         parameters.dmp.kernels = kernels;
         const bp::DrDmpFit fit = bp::DrDmp::fit(parameters, task.demonstrations(), task.dt(), dofs);
         Eigen::MatrixXd weights(fit.latent_weights.rows(), dofs * kernels);
         for (Eigen::Index k = 0; k < weights.rows(); ++k) {
           weights.row(k) =
               liftedWeights(fit.dmp.coordination().front(), fit.latent_weights.row(k).transpose(), kernels)
                   .transpose();
         }
         auto [mean, covariance] = bl::sampleMoments(weights);
         covariance.diagonal().array() += 1e-6;
         const bp::DrDmp dmp = fit.dmp.withCoordination({Eigen::MatrixXd::Identity(dofs, dofs)}, mean);
         const int steps = samples - 1;
         const auto dmp_grid = std::make_shared<const bl::CoordinationGrid>(dmp.grid(task.dt(), steps));
         Setup setup{reps, dmp_grid, {{Eigen::MatrixXd::Identity(dofs, dofs)}, mean, covariance, {}}, {}, {}, {}};
         setup.parameters.rule = bl::CoordinationRule::Fixed;
         auto rollout = std::make_shared<bt::DrDmpRollout>();
         setup.rollout = [&task, dmp, rollout, steps](const std::vector<Eigen::MatrixXd>& omega,
                                                      const Eigen::VectorXd& w, std::mt19937* rng,
                                                      Eigen::MatrixXd& values) {
           std::mt19937 unused;
           bt::rolloutDrDmp(dmp.withCoordination(omega, w), task.dt(), steps, 0.0, rng != nullptr ? *rng : unused,
                            *rollout);
           values = rollout->positions;
           return task.reward(rollout->positions);
         };
         return setup;
       }});
  // ProMP+REPS: the ProMP of the demonstrations (Ω = I), REPS on its weights.
  algorithms.push_back({"ProMP+REPS", [&, grid]() {
                          bl::CoordinatedPolicy policy{
                              {Eigen::MatrixXd::Identity(dofs, dofs)}, full.weightMean(), full.weightCovariance(), {}};
                          Setup setup{reps, grid, std::move(policy), {}, {}, {}};
                          setup.parameters.rule = bl::CoordinationRule::Fixed;
                          setup.rollout = [&task, grid](const std::vector<Eigen::MatrixXd>& omega,
                                                        const Eigen::VectorXd& w, std::mt19937*,
                                                        Eigen::MatrixXd& values) {
                            values = bl::coordinatedValues(*grid, omega, w);
                            return task.reward(values);
                          };
                          return setup;
                        }});
  // EM-ProMP+REPS (Alg. 7.1): DR-ProMP fitted by EM, REPS weights, EM on the rollouts; Ω perturbed by N(0, α²) per
  // element before each rollout.
  for (const auto& [r, alpha] : std::vector<std::pair<int, double>>{{dofs, 0.0}, {8, 0.0}, {8, 0.01}}) {
    std::string name = "EM-ProMP(" + std::to_string(r) + ")";
    if (alpha > 0.0) name += ", alpha=0.01";
    algorithms.push_back({name, [&, grid, r = r, alpha = alpha]() {
                            bp::DrProMpParameters parameters;
                            parameters.promp = promp;
                            parameters.latent_dims = r;
                            parameters.em = reps.em;
                            const bp::DrProMp model = bp::DrProMp::fit(parameters, task.demonstrations(), 1.0);
                            Setup setup{reps,
                                        grid,
                                        {{model.coordination()},
                                         model.latent().weightMean(),
                                         model.latent().weightCovariance(),
                                         model.observationCovariance()},
                                        {},
                                        {},
                                        {}};
                            setup.parameters.rule = bl::CoordinationRule::Em;
                            setup.rollout = [&task, grid, alpha](const std::vector<Eigen::MatrixXd>& omega,
                                                                 const Eigen::VectorXd& w, std::mt19937* rng,
                                                                 Eigen::MatrixXd& values) {
                              Eigen::MatrixXd perturbed = omega.front();
                              if (rng != nullptr && alpha > 0.0) {
                                std::normal_distribution<double> normal(0.0, alpha);
                                for (Eigen::Index i = 0; i < perturbed.size(); ++i) perturbed.data()[i] += normal(*rng);
                              }
                              values = bl::coordinatedValues(*grid, {perturbed}, w);
                              return task.reward(values);
                            };
                            return setup;
                          }});
  }
  runLearning(options, "planar15", protocol, algorithms, out);
}

// ---- DR-DMP variants of Tables 7.1–7.2 (planar10, wam_circle) ----

struct DrDmpVariant {
  std::string name;
  int matrices;  ///< N_s
  int r;         ///< Initial latent dimension.
  bl::CoordinationRule rule;
  double eta;  ///< ∞: fixed dimension.
};

/// DR-DMP⁰(r) and DR-DMP⁰_MCMU(N_s, r) are "DR-DMP0(r)" and "DR-DMP0_MCMU(Ns,r)".
std::vector<DrDmpVariant> drDmpVariants(const std::string& experiment, int d, const std::vector<int>& dims, int ns,
                                        double eta) {
  std::vector<DrDmpVariant> out;
  const std::string s = std::to_string(ns);
  if (experiment == "wam_circle") {
    for (const int r : dims)
      out.push_back({"DR-DMP0(" + std::to_string(r) + ")", 1, r, bl::CoordinationRule::Fixed, kInfinity});
  }
  for (const int r : dims)
    out.push_back({"DR-DMP_CMU(" + std::to_string(r) + ")", 1, r, bl::CoordinationRule::Cmu, kInfinity});
  if (experiment == "wam_circle") {
    for (const int r : dims) {
      out.push_back(
          {"DR-DMP0_MCMU(" + s + "," + std::to_string(r) + ")", ns, r, bl::CoordinationRule::Fixed, kInfinity});
    }
  }
  for (const int r : dims) {
    out.push_back({"DR-DMP_MCMU(" + s + "," + std::to_string(r) + ")", ns, r, bl::CoordinationRule::Cmu, kInfinity});
  }
  out.push_back({"IDR-DMP_CMU", 1, d, bl::CoordinationRule::Cmu, eta});
  out.push_back({"IDR-DMP_MCMU(" + s + ")", ns, d, bl::CoordinationRule::Cmu, eta});
  if (experiment == "wam_circle") {
    for (const int r : dims) {
      if (r < d) out.push_back({"EM DR-DMP(" + std::to_string(r) + ")", 1, r, bl::CoordinationRule::Em, kInfinity});
    }
  }
  return out;
}

/// A DR-DMP task: demonstrations, dt, steps, exploration outside the latent space, and the reward of a rollout.
struct DrDmpTask {
  std::vector<Eigen::MatrixXd> demonstrations;
  double dt = 0.01;
  int steps = 100;
  int kernels = 10;
  double alpha_z = 25.0;  ///< The DMPs' α_z, with β_z = α_z/4 (critically damped).
  double smoothing_hz = 20.0;
  double exploration = 0.0;
  /// Latent Σ_ω: the demonstrations' sample covariance plus `relative_prior` times its mean variance, or, with one
  /// demonstration, diag(forcing_variance / max_t g_i(x_t)²) for the weights of kernel i: every weight moves the
  /// forcing term at its kernel's peak by about √forcing_variance (an isotropic Σ_ω would explore the early kernels
  /// up to 1/x(τ)² ≈ 3000 times as much, in variance, as the last ones, whose basis carries the factor x).
  double relative_prior = 0.01, forcing_variance = 1.0;
  bl::CoordinatedRepsParameters parameters;
  std::function<std::function<double(const bt::DrDmpRollout&)>()> reward;  ///< A fresh reward (own scratch).
  /// For the pictures: a fresh map from a rollout to its path (one row per sample, `path_columns` wide: the planar
  /// arm's joint angles, the WAM's tool position) and the target (rows of `target_columns`: the via-points, points
  /// of the circle).
  std::function<std::function<Eigen::MatrixXd(const bt::DrDmpRollout&)>()> path;
  std::vector<std::string> path_columns, target_columns;
  Eigen::MatrixXd target;
  /// Labels of how the task was made, for summary.json (wam_circle: where its demonstration was perturbed).
  std::vector<std::pair<std::string, std::string>> labels;

  /// Adds to a row of summary.json how the task was made: the DMPs' shape and the labels.
  void describe(Summary& row) const {
    row.numbers.insert(row.numbers.end(), {{"kernels", kernels}, {"alpha_z", alpha_z}, {"beta_z", alpha_z / 4.0}});
    row.texts.insert(row.texts.end(), labels.begin(), labels.end());
  }

  /// The DR-DMP's shape with `matrices` coordination matrices. \throws std::invalid_argument for an α_z whose steps
  /// of dt are unstable over the demonstration's duration (DmpParameters::stableStep).
  bp::DrDmpParameters dmpParameters(int matrices) const {
    bp::DrDmpParameters parameters;
    parameters.dmp.kernels = kernels;
    parameters.dmp.alpha_z = alpha_z;
    parameters.dmp.beta_z = alpha_z / 4.0;
    parameters.matrices = matrices;
    if (!parameters.dmp.stableStep(dt, dt * steps)) {
      char text[160];
      std::snprintf(text, sizeof text, "alpha_z = %g makes the DMP's steps of %g s unstable over %g s", alpha_z, dt,
                    dt * steps);
      throw std::invalid_argument(text);
    }
    return parameters;
  }
};

Algorithm drDmpAlgorithm(const DrDmpTask& task, const DrDmpVariant& variant) {
  return {variant.name, [&task, variant]() {
            const bp::DrDmpParameters parameters = task.dmpParameters(variant.matrices);
            const bp::DrDmpFit fit =
                bp::DrDmp::fit(parameters, task.demonstrations, task.dt, variant.r, task.smoothing_hz);
            Eigen::VectorXd mean = fit.dmp.weights();
            auto grid = std::make_shared<const bl::CoordinationGrid>(fit.dmp.grid(task.dt, task.steps));
            Eigen::MatrixXd covariance;
            if (fit.latent_weights.rows() > 1) {
              covariance = bl::sampleMoments(fit.latent_weights).second;
              covariance.diagonal().array() += task.relative_prior * covariance.diagonal().mean();
            } else {
              const Eigen::ArrayXd peak = grid->basis().colwise().maxCoeff().transpose().array();
              covariance = Eigen::MatrixXd::Zero(mean.size(), mean.size());
              covariance.diagonal() = (task.forcing_variance / peak.square()).replicate(variant.r, 1).matrix();
            }
            Setup setup;
            setup.parameters = task.parameters;
            setup.parameters.rule = variant.rule;
            if (variant.rule == bl::CoordinationRule::Em) {
              setup.parameters.covariance_rule = bl::CovarianceRule::MaximumLikelihood;  // EM fits its own Σ_ω
            }
            setup.parameters.update.eta = variant.eta;
            setup.grid = std::move(grid);
            setup.policy = {fit.dmp.coordination(), mean, covariance, {}};
            setup.excitation = fit.excitation;
            if (variant.rule == bl::CoordinationRule::Em) {
              // Σ_f: the residual covariance of the mean demonstrated forcing terms' latent reconstruction, plus the
              // exploration noise outside the latent space.
              const Eigen::MatrixXd residual = fit.excitation.front().transpose() -
                                               bl::coordinatedValues(*setup.grid, setup.policy.coordination, mean);
              Eigen::MatrixXd noise = residual.transpose() * residual / task.steps;
              noise.diagonal().array() += task.parameters.em.noise_floor + task.exploration * task.exploration;
              setup.policy.noise = noise;
            }
            const bp::DrDmp dmp = fit.dmp;
            auto rollout = std::make_shared<bt::DrDmpRollout>();
            auto reward = std::make_shared<std::function<double(const bt::DrDmpRollout&)>>(task.reward());
            const double dt = task.dt, exploration = task.exploration;
            const int steps = task.steps;
            setup.rollout = [dmp, rollout, reward, dt, steps, exploration](const std::vector<Eigen::MatrixXd>& omega,
                                                                           const Eigen::VectorXd& w, std::mt19937* rng,
                                                                           Eigen::MatrixXd& values) {
              std::mt19937 unused;
              bt::rolloutDrDmp(dmp.withCoordination(omega, w), dt, steps, rng != nullptr ? exploration : 0.0,
                               rng != nullptr ? *rng : unused, *rollout);
              values = rollout->forcing;
              return (*reward)(*rollout);
            };
            auto path = std::make_shared<std::function<Eigen::MatrixXd(const bt::DrDmpRollout&)>>(task.path());
            setup.path = [dmp, rollout, path, dt, steps](const std::vector<Eigen::MatrixXd>& omega,
                                                         const Eigen::VectorXd& w) {
              std::mt19937 unused;
              bt::rolloutDrDmp(dmp.withCoordination(omega, w), dt, steps, 0.0, unused, *rollout);
              return (*path)(*rollout);
            };
            return setup;
          }};
}

/// Table 7.3's task (10-DoF planar arm, two via-points) with the settings of planar10.
DrDmpTask planar10Task(std::uint32_t seed) {
  auto via = std::make_shared<const bt::PlanarViaPointTask>(10, seed);
  DrDmpTask task;
  task.demonstrations = via->demonstrations();
  task.dt = via->dt();
  task.steps = via->steps();
  // The thesis gives ε = 0.5, η = 50 and the exploration N(0, 0.1) outside the latent space (taken as a variance),
  // not the kernels per DoF, the reuse, the prior on Σ_ω or λ. 5 kernels per latent DoF (a sweep of DR-DMP_CMU(2)
  // preferred them to 10). The prior (0.01 of the demonstrations' mean weight variance, the default) and λ = 0.8 by a
  // sweep of DR-DMP_CMU(10, 5, 2, 1), IDR-DMP_CMU and IDR-DMP_MCMU(2) (4 runs, seed 1, 200 updates; docs/RESULTS.md).
  task.kernels = 5;
  task.exploration = std::sqrt(0.1);
  task.parameters.reps.epsilon = 0.5;
  task.parameters.reps.reuse = 80;  // the last 4 updates of 20 rollouts, as in the WAM experiment
  task.parameters.covariance_memory = 0.8;
  task.reward = [via]() {
    return [via](const bt::DrDmpRollout& rollout) { return via->reward(rollout.positions, rollout.accelerations); };
  };
  task.path = []() { return [](const bt::DrDmpRollout& rollout) { return rollout.positions; }; };
  for (int j = 1; j <= via->dofs(); ++j) task.path_columns.push_back("q" + std::to_string(j));
  task.target_columns = {"t", "x", "y"};
  task.target.resize(static_cast<Eigen::Index>(via->viaPoints().size()), 3);
  for (std::size_t v = 0; v < via->viaPoints().size(); ++v) {
    const auto row = static_cast<Eigen::Index>(v);
    task.target(row, 0) = via->viaSteps()[v] * via->dt();
    task.target.row(row).tail(2) = via->viaPoints()[v].transpose();
  }
  return task;
}

/// Table 7.4's task (the WAM circle) with the settings of wam_circle.
DrDmpTask wamCircleTask(std::uint32_t seed) {
  auto circle = std::make_shared<const bt::WamCircleTask>(
      bk::ChainModel::fromUrdfFile(bimanual_skills::cli::packageFile("urdf/wam.urdf"), "wam_base", "wam_tool"), seed,
      overrides.demonstration, overrides.circle);
  DrDmpTask task;
  task.demonstrations = {circle->demonstration()};
  task.dt = circle->dt();
  task.steps = circle->steps();
  task.kernels = 20;
  task.smoothing_hz = 2.0;
  task.exploration = std::sqrt(0.1);
  // The initial Σ_ω and λ are not in the thesis; chosen by a sweep of DR-DMP0(7), DR-DMP_CMU(3) and IDR-DMP_CMU
  // (2 runs, seed 7, 250 updates, λ = 0.9; docs/RESULTS.md): forcing variances 10, 30, 100, 300 reached −0.37, −0.36,
  // −0.37, −0.45; −0.33, −0.31, −0.31, −0.28; −0.34, −0.35, −0.33, −0.45, against −0.50, −0.32, −0.51 with the
  // isotropic Σ_ω = 1000 I.
  task.forcing_variance = 100.0;
  task.parameters.covariance_memory = 0.9;
  task.parameters.reps.epsilon = 0.5;
  task.parameters.reps.reuse = 80;  // the last 4 epochs of 20 rollouts
  task.parameters.update.eta = 50.0;
  task.parameters.em.max_iterations = 10;
  task.parameters.em.tolerance = 1e-6;
  task.parameters.em.noise_floor = 1e-6;
  task.reward = [circle]() {
    auto own = std::make_shared<bt::WamCircleTask>(*circle);  // its own scratch
    return [own](const bt::DrDmpRollout& rollout) { return own->reward(rollout.positions, rollout.accelerations); };
  };
  task.path = [circle]() {
    auto own = std::make_shared<bt::WamCircleTask>(*circle);
    return [own](const bt::DrDmpRollout& rollout) { return own->toolPath(rollout.positions); };
  };
  task.path_columns = task.target_columns = {"x", "y", "z"};
  task.labels = {{"demonstration", overrides.demonstration == bt::CirclePerturbation::Task ? "task" : "joint"},
                 {"circle", overrides.circle == bt::CircleTarget::Nominal ? "nominal" : "fitted"}};
  // 200 points of the circle the reward measures distances from.
  const bt::Circle3d& fit = circle->circle();
  const Eigen::Vector3d u = fit.normal.unitOrthogonal(), v = fit.normal.cross(u);
  task.target.resize(200, 3);
  for (Eigen::Index i = 0; i < task.target.rows(); ++i) {
    const double angle = 2.0 * M_PI * static_cast<double>(i) / static_cast<double>(task.target.rows());
    task.target.row(i) = (fit.centre + fit.radius * (std::cos(angle) * u + std::sin(angle) * v)).transpose();
  }
  return task;
}

/// planar10 and wam_circle: every DR-DMP variant of the experiment's table, learned in `runs` runs.
struct DrDmpExperiment {
  std::string name;
  std::function<DrDmpTask(std::uint32_t seed)> task;
  int runs, updates, dofs;
  std::vector<int> dims;  ///< The fixed latent dimensions of the table.
  int matrices;           ///< N_s of the MCMU variants.
};

const std::vector<DrDmpExperiment>& drDmpExperiments() {
  static const std::vector<DrDmpExperiment> experiments = {
      {"planar10", planar10Task, 20, 200, 10, {10, 8, 5, 2, 1}, 2},
      {"wam_circle", wamCircleTask, 10, 250, 7, {7, 6, 5, 4, 3, 2, 1}, 3}};
  return experiments;
}

/// The experiment's task with the command line's overrides. \throws std::invalid_argument for an unstable --alpha-z.
DrDmpTask configuredTask(const DrDmpExperiment& experiment, std::uint32_t seed) {
  DrDmpTask task = experiment.task(seed);
  if (!std::isnan(overrides.exploration)) task.exploration = overrides.exploration;
  if (!std::isnan(overrides.covariance_memory)) task.parameters.covariance_memory = overrides.covariance_memory;
  if (!std::isnan(overrides.epsilon)) task.parameters.reps.epsilon = overrides.epsilon;
  if (!std::isnan(overrides.forcing_variance)) task.forcing_variance = overrides.forcing_variance;
  if (!std::isnan(overrides.relative_prior)) task.relative_prior = overrides.relative_prior;
  if (overrides.reuse >= 0) task.parameters.reps.reuse = static_cast<int>(overrides.reuse);
  if (overrides.kernels > 0) task.kernels = static_cast<int>(overrides.kernels);
  if (!std::isnan(overrides.alpha_z)) task.alpha_z = overrides.alpha_z;
  task.dmpParameters(1);  // throws for an unstable α_z
  if (overrides.adapted_covariance) {
    task.parameters.covariance_rule = bl::CovarianceRule::Adapted;
    task.parameters.covariance_memory = 0.0;
  }
  return task;
}

void learnDrDmp(const Options& options, const DrDmpExperiment& experiment, std::vector<Summary>& out) {
  const DrDmpTask task = configuredTask(experiment, options.seed);
  Protocol protocol;
  protocol.runs = runsOf(options, experiment.runs, 2);
  protocol.updates = options.quick           ? 3
                     : overrides.updates > 0 ? static_cast<int>(overrides.updates)
                                             : experiment.updates;
  protocol.rollouts = protocol.first_rollouts = overrides.rollouts > 0 ? static_cast<int>(overrides.rollouts) : 20;
  std::vector<Algorithm> algorithms;
  for (const DrDmpVariant& variant :
       drDmpVariants(experiment.name, experiment.dofs, experiment.dims, experiment.matrices, 50.0)) {
    algorithms.push_back(drDmpAlgorithm(task, variant));
  }
  std::ofstream target(options.out + "/" + experiment.name + "_target.csv");
  target.precision(10);
  for (std::size_t c = 0; c < task.target_columns.size(); ++c) target << (c > 0 ? "," : "") << task.target_columns[c];
  target << '\n';
  for (Eigen::Index i = 0; i < task.target.rows(); ++i) {
    for (Eigen::Index j = 0; j < task.target.cols(); ++j) target << (j > 0 ? "," : "") << task.target(i, j);
    target << '\n';
  }
  const std::size_t first = out.size();
  runLearning(options, experiment.name, protocol, algorithms, out, task.path_columns);
  // Every row says what it learned with, overrides included.
  const bool adapted = task.parameters.covariance_rule == bl::CovarianceRule::Adapted;
  const bool one_demonstration = task.demonstrations.size() == 1;
  for (std::size_t i = first; i < out.size(); ++i) {
    task.describe(out[i]);
    out[i].numbers.insert(out[i].numbers.end(), {{"epsilon", task.parameters.reps.epsilon},
                                                 {"reuse", task.parameters.reps.reuse},
                                                 {"exploration", task.exploration},
                                                 {"covariance_memory", task.parameters.covariance_memory},
                                                 {one_demonstration ? "forcing_variance" : "relative_prior",
                                                  one_demonstration ? task.forcing_variance : task.relative_prior}});
    out[i].texts.emplace_back("covariance_rule", adapted ? "adapted" : "reps");
  }
}

void planar10(const Options& options, std::vector<Summary>& out) {
  learnDrDmp(options, drDmpExperiments()[0], out);
}

void wamCircle(const Options& options, std::vector<Summary>& out) {
  learnDrDmp(options, drDmpExperiments()[1], out);
}

// ---- optima: the best reward a fixed coordination allows, by a local optimiser with gradients ----

/// The noise-free reward of latent weights through the fixed coordination matrices of a DR-DMP, the number of
/// rollouts the optimiser spent, the best iterate, and the optimiser's progress: the best reward of its iterates
/// against the rollouts spent, a row whenever it improved by 0.5 % or more.
class FixedCoordinationObjective {
 public:
  FixedCoordinationObjective(bp::DrDmp dmp, const DrDmpTask& task)
      : dmp_(std::move(dmp)), dt_(task.dt), steps_(task.steps), reward_(task.reward()), path_(task.path()) {}

  /// The reward of `w`, counted as a rollout of the optimiser.
  double operator()(const double* w, int size) {
    ++rollouts_;
    return reward(w, size);
  }
  /// The reward of `w`, not counted (a reference point, not a step of the optimiser).
  double reward(const double* w, int size) { return reward_(rollout(w, size)); }
  /// The length of the task's path for `w` (the sum of its steps' Euclidean lengths): the tool's travel for
  /// wam_circle, in m, the joints' for planar10, in rad. Not counted.
  double pathLength(const std::vector<double>& w) {
    const Eigen::MatrixXd path = path_(rollout(w.data(), static_cast<int>(w.size())));
    return (path.bottomRows(path.rows() - 1) - path.topRows(path.rows() - 1)).rowwise().norm().sum();
  }
  long rollouts() const noexcept { return rollouts_; }
  /// The best iterate so far (empty before the first).
  const std::vector<double>& best() const noexcept { return best_; }

  /// The optimiser evaluated the iterate `w` (with its gradient) to `value`.
  void iterate(const double* w, int size, double value) {
    if (best_.empty() || value > best_value_) {
      best_.assign(w, w + size);
      best_value_ = value;
    }
    if (progress_.empty() || value - progress_.back().second >= 0.005 * std::abs(progress_.back().second)) {
      progress_.emplace_back(rollouts_, value);
    }
  }
  /// (rollouts, best reward) rows, ending with the final count.
  std::vector<std::pair<long, double>> progress() const {
    std::vector<std::pair<long, double>> out = progress_;
    if (!out.empty()) out.emplace_back(rollouts_, out.back().second);
    return out;
  }

 private:
  const bt::DrDmpRollout& rollout(const double* w, int size) {
    std::mt19937 unused;
    bt::rolloutDrDmp(dmp_.withWeights(Eigen::Map<const Eigen::VectorXd>(w, size)), dt_, steps_, 0.0, unused, rollout_);
    return rollout_;
  }

  bp::DrDmp dmp_;
  double dt_;
  int steps_;
  std::function<double(const bt::DrDmpRollout&)> reward_;
  std::function<Eigen::MatrixXd(const bt::DrDmpRollout&)> path_;
  bt::DrDmpRollout rollout_;
  long rollouts_ = 0;
  std::vector<double> best_;
  double best_value_ = 0.0;
  std::vector<std::pair<long, double>> progress_;
};

/// L-BFGS (NLopt) on the objective with central differences of step 10⁻⁴.
double lbfgsObjective(unsigned n, const double* w, double* gradient, void* data) {
  auto& objective = *static_cast<FixedCoordinationObjective*>(data);
  const int size = static_cast<int>(n);
  const double value = objective(w, size);
  if (gradient != nullptr) {
    std::vector<double> x(w, w + n);
    for (int i = 0; i < size; ++i) {
      constexpr double h = 1e-4;
      x[i] = w[i] + h;
      const double up = objective(x.data(), size);
      x[i] = w[i] - h;
      const double down = objective(x.data(), size);
      x[i] = w[i];
      gradient[i] = (up - down) / (2.0 * h);
    }
    objective.iterate(w, size, value);
  }
  return value;
}

/// For each fixed-dimension DR-DMP with constant coordination (the PCA initialisation, DR-DMP⁰(r) and
/// DR-DMP⁰_MCMU(N_s, r)), the noise-free reward L-BFGS reaches from the initial mean weights: a local optimum, the
/// reference for how far policy search ends from it. Beside it, the reward with all latent weights zero (no forcing
/// term: only the transformation system's pull from start to goal), a point every coordination contains, so a lower
/// bound on each coordination's global optimum. optima_progress.csv has the rollouts L-BFGS spent to reach each
/// level, against the learners' budget.
void optima(const Options& options, std::vector<Summary>& out) {
  struct Job {
    std::string task;
    const DrDmpTask* setup;
    DrDmpVariant variant;
  };
  std::vector<DrDmpTask> tasks;
  for (const DrDmpExperiment& experiment : drDmpExperiments()) {
    tasks.push_back(configuredTask(experiment, options.seed));
  }
  std::vector<Job> jobs;
  for (std::size_t e = 0; e < tasks.size(); ++e) {
    const DrDmpExperiment& experiment = drDmpExperiments()[e];
    for (const int ns : {1, experiment.matrices}) {
      for (const int r : experiment.dims) {
        const std::string name = ns == 1 ? "DR-DMP0(" + std::to_string(r) + ")"
                                         : "DR-DMP0_MCMU(" + std::to_string(ns) + "," + std::to_string(r) + ")";
        jobs.push_back({experiment.name, &tasks[e], {name, ns, r, bl::CoordinationRule::Fixed, kInfinity}});
      }
    }
  }
  const long budget = options.quick ? 2000 : 1000000;  // rollouts per optimisation
  struct Result {
    double initial = 0.0, optimum = 0.0, zero_weights = 0.0, initial_path = 0.0, optimum_path = 0.0, seconds = 0.0;
    long rollouts = 0;
    int weights = 0;
    std::vector<std::pair<long, double>> progress;
  };
  std::vector<Result> results(jobs.size());
  std::ofstream csv(options.out + "/optima.csv");
  csv << "task,algorithm,latent_dims,matrices,weights,initial_reward,optimum_reward,zero_weights_reward,"
         "initial_path_length,optimum_path_length,rollouts,seconds\n";
  csv.precision(10);
  std::ofstream progress(options.out + "/optima_progress.csv");
  progress << "task,algorithm,rollouts,best_reward\n";
  progress.precision(10);
  bb::parallelRuns(
      static_cast<int>(jobs.size()), options.jobs,
      [&](int i) {
        const Job& job = jobs[static_cast<std::size_t>(i)];
        const auto start = Clock::now();
        const bp::DrDmpParameters parameters = job.setup->dmpParameters(job.variant.matrices);
        const bp::DrDmpFit fit = bp::DrDmp::fit(parameters, job.setup->demonstrations, job.setup->dt, job.variant.r,
                                                job.setup->smoothing_hz);
        FixedCoordinationObjective objective(fit.dmp, *job.setup);
        const Eigen::VectorXd w0 = fit.dmp.weights();
        std::vector<double> w(w0.data(), w0.data() + w0.size());
        Result& result = results[static_cast<std::size_t>(i)];
        result.weights = static_cast<int>(w.size());
        result.initial = objective(w.data(), result.weights);
        const std::vector<double> zero(w.size(), 0.0);
        result.zero_weights = objective.reward(zero.data(), result.weights);
        result.initial_path = objective.pathLength(w);
        nlopt::opt optimiser(nlopt::LD_LBFGS, static_cast<unsigned>(w.size()));
        optimiser.set_max_objective(
            [](unsigned n, const double* x, double* g, void* d) { return lbfgsObjective(n, x, g, d); }, &objective);
        optimiser.set_maxeval(static_cast<int>(budget / (2 * static_cast<long>(w.size()) + 1)));
        optimiser.set_ftol_rel(1e-10);
        double value = result.initial;
        try {
          optimiser.optimize(w, value);
        } catch (const std::runtime_error&) {
          // Round-off limited or a failed line search (the reward has kinks where the tool meets the circle): the
          // best point found stands.
          value = optimiser.last_optimum_value();
        }
        result.optimum = std::max(value, result.initial);
        // The best iterate (the first is the initial point) is where the optimum was reached.
        result.optimum_path = objective.best().empty() ? result.initial_path : objective.pathLength(objective.best());
        result.rollouts = objective.rollouts();
        result.progress = objective.progress();
        result.seconds = secondsSince(start);
      },
      [&](int i) {
        const Job& job = jobs[static_cast<std::size_t>(i)];
        const Result& r = results[static_cast<std::size_t>(i)];
        csv << job.task << ",\"" << job.variant.name << "\"," << job.variant.r << ',' << job.variant.matrices << ','
            << r.weights << ',' << r.initial << ',' << r.optimum << ',' << r.zero_weights << ',' << r.initial_path
            << ',' << r.optimum_path << ',' << r.rollouts << ',' << r.seconds << '\n';
        csv.flush();
        for (const auto& [rollouts, best] : r.progress) {
          progress << job.task << ",\"" << job.variant.name << "\"," << rollouts << ',' << best << '\n';
        }
        progress.flush();
        std::printf(
            "  optima %-10s %-20s %3d weights: %.4g -> %.4g, path %.3g -> %.3g (%ld rollouts, %.1f s; zero weights "
            "%.4g)\n",
            job.task.c_str(), job.variant.name.c_str(), r.weights, r.initial, r.optimum, r.initial_path, r.optimum_path,
            r.rollouts, r.seconds, r.zero_weights);
        std::fflush(stdout);
        out.push_back({"optima",
                       job.variant.name,
                       {{"latent_dims", job.variant.r},
                        {"matrices", job.variant.matrices},
                        {"weights", r.weights},
                        {"initial_reward", r.initial},
                        {"optimum_reward", r.optimum},
                        {"zero_weights_reward", r.zero_weights},
                        {"initial_path_length", r.initial_path},
                        {"optimum_path_length", r.optimum_path},
                        {"rollouts", static_cast<double>(r.rollouts)},
                        {"seconds", r.seconds}},
                       {{"task", job.task}}});
        job.setup->describe(out.back());
      });
}

// ---- nao_walking: a DR-ProMP of 13 NAO walks, the legs' synergies (Sec. 7.1, Figs. 7.3–7.4) ----

/// The correlation matrix of a covariance.
Eigen::MatrixXd correlationOf(const Eigen::MatrixXd& covariance) {
  const Eigen::VectorXd scale = covariance.diagonal().cwiseMax(1e-300).cwiseSqrt().cwiseInverse();
  return scale.asDiagonal() * covariance * scale.asDiagonal();
}

void naoWalking(const Options& options, std::vector<Summary>& out) {
  const bt::NaoLegs legs = bt::NaoLegs::fromUrdfFile(bimanual_skills::cli::packageFile("urdf/nao_legs.urdf"));
  constexpr int walks = 13, samples = 100, kernels = 15, first_step = 3;
  constexpr double kDegrees = 180.0 / M_PI;
  const std::vector<std::string> names = bt::naoLegJointNames();
  const int d = static_cast<int>(names.size());
  // 13 walks of varied step length, period, foot lift, torso height and turn, drawn from the seed; one stride of
  // each (steps 3 and 4: each foot swings once) on a normalised time, in degrees.
  std::mt19937 rng = bb::runGenerator(options, "nao_walking", 0);
  const auto uniform = [&rng](double lo, double hi) { return std::uniform_real_distribution<double>(lo, hi)(rng); };
  bl::WeightedTrajectories data;
  std::ofstream walks_csv(options.out + "/nao_walks.csv"), strides_csv(options.out + "/nao_strides.csv");
  walks_csv << "walk,step_length,step_period,foot_lift,torso_height,turn,zmp_error_max,right_heading_error\n";
  strides_csv << "walk,sample,phase";
  for (const std::string& name : names) strides_csv << ',' << name;
  strides_csv << '\n';
  walks_csv.precision(8);
  strides_csv.precision(8);
  for (int w = 0; w < walks; ++w) {
    bt::NaoWalkParameters p;
    p.step_length = uniform(0.02, 0.05);
    p.step_period = uniform(0.4, 0.6);
    p.foot_lift = uniform(0.01, 0.025);
    p.torso_height = uniform(0.29, 0.31);
    p.turn = uniform(-0.1, 0.1);
    const bt::NaoWalk walk = bt::generateNaoWalk(legs, p);
    const Eigen::MatrixXd stride = kDegrees * bt::naoStride(walk, first_step, samples);
    data.trajectories.push_back(stride);
    walks_csv << w << ',' << p.step_length << ',' << p.step_period << ',' << p.foot_lift << ',' << p.torso_height << ','
              << p.turn << ',' << (walk.zmp - walk.zmp_reference).rowwise().norm().maxCoeff() << ','
              << walk.right_heading_error << '\n';
    for (int t = 0; t < samples; ++t) {
      strides_csv << w << ',' << t << ',' << t / (samples - 1.0);
      for (int j = 0; j < d; ++j) strides_csv << ',' << stride(t, j);
      strides_csv << '\n';
    }
  }
  data.weights = Eigen::VectorXd::Ones(walks);
  data.contexts = Eigen::MatrixXd(walks, 0);
  std::printf("  nao_walking: %d walks generated (ZMP preview control, NAO V5 legs); strides of steps %d-%d\n", walks,
              first_step, first_step + 1);
  // The data's distribution at each normalised time, and the correlation of the joints over all samples.
  std::vector<Eigen::VectorXd> data_mean(samples), data_std(samples);
  for (int t = 0; t < samples; ++t) {
    Eigen::MatrixXd at(walks, d);
    for (int w = 0; w < walks; ++w) at.row(w) = data.trajectories[static_cast<std::size_t>(w)].row(t);
    const auto [mean, covariance] = bl::sampleMoments(at);
    data_mean[static_cast<std::size_t>(t)] = mean;
    data_std[static_cast<std::size_t>(t)] = covariance.diagonal().cwiseMax(0.0).cwiseSqrt();
  }
  Eigen::MatrixXd all(walks * samples, d);
  for (int w = 0; w < walks; ++w) all.middleRows(w * samples, samples) = data.trajectories[static_cast<std::size_t>(w)];
  const Eigen::MatrixXd data_correlation = correlationOf(bl::sampleMoments(all).second);
  // Within the walks: each walk's own mean taken out first, so that what differs between walks (a lower torso bends
  // both knees) does not hide the legs' alternation in time.
  Eigen::MatrixXd within = all;
  for (int w = 0; w < walks; ++w) {
    auto rows = within.middleRows(w * samples, samples);
    rows.rowwise() -= rows.colwise().mean();
  }
  const Eigen::MatrixXd within_correlation = correlationOf(within.transpose() * within);

  bp::ProMpParameters promp;
  promp.kernels = kernels;
  const bl::CoordinationGrid grid = bp::DrProMp::grid(promp, samples);
  bl::LatentEmParameters em;
  em.max_iterations = options.quick ? 10 : 200;
  em.tolerance = 1e-9;
  em.noise_floor = 1e-6;  // [deg²]: HipYawPitch is one motor, the data have rank 11 at most
  bl::LatentPcaParameters pca;
  pca.noise_floor = 1e-6;
  const std::vector<int> dims =
      options.quick ? std::vector<int>{1, 4, 12} : std::vector<int>{1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12};
  std::ofstream fit_csv(options.out + "/nao_fit.csv"), distribution_csv(options.out + "/nao_distribution.csv"),
      correlation_csv(options.out + "/nao_correlation.csv");
  fit_csv << "r,rms_mean_error_deg,rms_std_error_deg,log_likelihood_per_walk,em_iterations\n";
  distribution_csv << "sample,phase,joint,data_mean,data_std,fit_mean,fit_std\n";
  correlation_csv << "i,j,joint_i,joint_j,model,coordination,data,data_within_walks\n";
  for (std::ofstream* csv : {&fit_csv, &distribution_csv, &correlation_csv}) csv->precision(8);
  const int shown = 4;  // Fig. 7.4's r
  for (const int r : dims) {
    const bl::LatentTrajectoryModel initial = bl::latentPcaModel(grid, data, r, pca);
    const bl::LatentEmResult fitted = bl::latentEm(grid, data, initial, em);
    double mean_error = 0.0, std_error = 0.0;
    Eigen::MatrixXd second = Eigen::MatrixXd::Zero(d, d);
    Eigen::VectorXd first = Eigen::VectorXd::Zero(d);
    for (int t = 0; t < samples; ++t) {
      Eigen::VectorXd mean;
      Eigen::MatrixXd covariance;
      bl::latentMarginal(grid, fitted.model, t, Eigen::VectorXd(), mean, covariance);
      const Eigen::VectorXd std = covariance.diagonal().cwiseMax(0.0).cwiseSqrt();
      mean_error += (mean - data_mean[static_cast<std::size_t>(t)]).squaredNorm();
      std_error += (std - data_std[static_cast<std::size_t>(t)]).squaredNorm();
      // The joints' covariance over time and walks as the model has it (the synergies, without Σ_y).
      second += covariance - fitted.model.noise + mean * mean.transpose();
      first += mean;
      if (r == shown) {
        for (int j = 0; j < d; ++j) {
          distribution_csv << t << ',' << t / (samples - 1.0) << ',' << names[static_cast<std::size_t>(j)] << ','
                           << data_mean[static_cast<std::size_t>(t)][j] << ','
                           << data_std[static_cast<std::size_t>(t)][j] << ',' << mean[j] << ',' << std[j] << '\n';
        }
      }
    }
    mean_error = std::sqrt(mean_error / (samples * d));
    std_error = std::sqrt(std_error / (samples * d));
    const double likelihood = fitted.log_likelihood.back() / walks;
    fit_csv << r << ',' << mean_error << ',' << std_error << ',' << likelihood << ',' << fitted.iterations << '\n';
    std::printf(
        "  nao_walking: r = %2d: mean off by %.3f deg (rms), spread by %.3f deg, log-likelihood %.1f per walk, "
        "%d EM iterations\n",
        r, mean_error, std_error, likelihood, fitted.iterations);
    out.push_back({"nao_walking",
                   "DR-ProMP",
                   {{"r", r},
                    {"rms_mean_error_deg", mean_error},
                    {"rms_std_error_deg", std_error},
                    {"log_likelihood_per_walk", likelihood},
                    {"em_iterations", fitted.iterations},
                    {"final_reward", std::numeric_limits<double>::quiet_NaN()}},
                   {{"kind", "fit"}}});
    if (r != shown) continue;
    first /= samples;
    const Eigen::MatrixXd model_correlation = correlationOf(second / samples - first * first.transpose());
    // Ω Ωᵀ normalised, the correlation read off the coordination matrix alone (it depends on how the EM scaled and
    // turned the latent space; the model's above does not).
    const Eigen::MatrixXd& omega = fitted.model.coordination;
    const Eigen::MatrixXd coordination_correlation = correlationOf(omega * omega.transpose());
    for (int i = 0; i < d; ++i) {
      for (int j = 0; j < d; ++j) {
        correlation_csv << i + 1 << ',' << j + 1 << ',' << names[static_cast<std::size_t>(i)] << ','
                        << names[static_cast<std::size_t>(j)] << ',' << model_correlation(i, j) << ','
                        << coordination_correlation(i, j) << ',' << data_correlation(i, j) << ','
                        << within_correlation(i, j) << '\n';
      }
    }
    // The couplings the thesis names: <1,7>, <3,9>, <4,10>, <5,11> opposite, <2,8>, <6,12> the same sign.
    for (const auto& [i, j, opposite] : {std::tuple{1, 7, true}, std::tuple{3, 9, true}, std::tuple{4, 10, true},
                                         std::tuple{5, 11, true}, std::tuple{2, 8, false}, std::tuple{6, 12, false}}) {
      const double model = model_correlation(i - 1, j - 1), measured = data_correlation(i - 1, j - 1),
                   coordination = coordination_correlation(i - 1, j - 1), in_time = within_correlation(i - 1, j - 1);
      const bool as_said = opposite ? model < 0.0 : model > 0.0;
      std::printf(
          "  nao_walking: <%d,%d> %s-%s: correlation %+.3f (model, r = %d), %+.3f (Omega Omega^T), %+.3f "
          "(data), %+.3f (data within walks); the thesis: %s -> %s\n",
          i, j, names[static_cast<std::size_t>(i - 1)].c_str(), names[static_cast<std::size_t>(j - 1)].c_str(), model,
          shown, coordination, measured, in_time, opposite ? "opposite" : "same sign",
          as_said ? "as said" : "not as said");
      out.push_back({"nao_walking",
                     "coupling",
                     {{"i", i},
                      {"j", j},
                      {"model_correlation", model},
                      {"data_correlation", measured},
                      {"coordination_correlation", coordination},
                      {"within_walks_correlation", in_time},
                      {"as_thesis", as_said ? 1.0 : 0.0},
                      {"final_reward", std::numeric_limits<double>::quiet_NaN()}},
                     {{"thesis", opposite ? "opposite" : "same sign"}}});
    }
  }
}

void writeSummary(const Options& options, const std::vector<Summary>& rows) {
  std::vector<bb::JsonRow> json;
  for (const Summary& r : rows) {
    bb::JsonRow& row = json.emplace_back();
    row.add("experiment", r.experiment).add("algorithm", r.algorithm);
    for (const auto& [key, value] : r.texts) row.add(key, value);
    for (const auto& [key, value] : r.numbers) row.add(key, value);
  }
  bb::writeSummaryJson(options, "dr_benchmark", json);
}

}  // namespace

int main(int argc, char** argv) {
  bimanual_skills::cli::pinNumerics(argv);
  bb::ExperimentProgram program;
  program.name = "dr_benchmark";
  program.description =
      "The thesis' reward-oriented dimensionality-reduction experiments (Ch. 7): the fast E-step against the naive\n"
      "one, EM vs PCA fits (Fig. 7.2), the 15-DoF planar tracking task (Fig. 7.5), the 10-DoF via-point task\n"
      "(Table 7.3) and the WAM circle (Table 7.4), and (optima) the local optimum L-BFGS reaches from each\n"
      "constant coordination's initial policy of the last two, with its path length and the reward of all latent\n"
      "weights zero. Writes DIR/<experiment>.csv, DIR/summary.json,\n"
      "learning-curve PNGs (mean and 95 % interval over runs), the first run's paths before and after learning\n"
      "with the task's target (planar10 and wam_circle: <experiment>_paths.csv, _target.csv, _paths.png) and\n"
      "DIR/tables.md. nao_walking: a DR-ProMP (r = 1..12) of 13 generated walks of a NAO's 12 leg joints (ZMP\n"
      "preview control; the thesis' recordings are not available), Fig. 7.4's distribution at r = 4 and Fig. 7.3's\n"
      "correlations (nao_*.csv, nao_*.png).";
  program.experiments = {"estep", "em_vs_pca", "planar15", "planar10", "wam_circle", "optima", "nao_walking", "all"};
  program.with_runs = true;
  program.with_jobs = true;
  std::string algorithms, demonstration = "joint", circle = "fitted";
  program.extra = [&](bimanual_skills::cli::CommandLine& line) {
    line.option("--algorithms", "A,B,...",
                "run only these algorithms of planar15, planar10 and wam_circle (their names in summary.json, e.g. "
                "\"IDR-DMP_CMU,DR-DMP0(7)\")",
                &algorithms);
    line.option("--covariance-memory", "L",
                "planar10, wam_circle: the new latent covariance keeps L of the one sampled from, (1 - L) Sigma_ML + "
                "L Sigma, 0 <= L < 1 (default: the experiment's)",
                &overrides.covariance_memory);
    line.flag("--adapted-covariance",
              "planar10, wam_circle: REPS' weights and mean with the latent covariance and a step size adapted as in "
              "CMA-ES (Hansen 2006, the thesis' ref. [135]) instead of REPS' weighted maximum likelihood; not in the "
              "thesis' experiments (the EM variants keep theirs; --covariance-memory does not apply)",
              &overrides.adapted_covariance);
    line.option("--exploration", "S",
                "planar10, wam_circle: the standard deviation of the noise added to every forcing value outside the "
                "latent space, per step, S >= 0 (default: the experiment's, sqrt(0.1))",
                &overrides.exploration);
    line.option("--epsilon", "E",
                "planar10, wam_circle: REPS' bound on the KL divergence of each update, E > 0 (default: the thesis' "
                "0.5)",
                &overrides.epsilon);
    line.option("--reuse", "N",
                "planar10, wam_circle: rollouts of earlier updates reused in each update (default: the experiment's, "
                "80)",
                &overrides.reuse, 0, 100000);
    line.option("--kernels", "K",
                "planar10, wam_circle, optima: basis functions per latent DoF (default: the experiment's, 5 and 20)",
                &overrides.kernels, 2, 1000);
    line.option("--rollouts", "N", "planar10, wam_circle: rollouts per policy update (default: the thesis', 20)",
                &overrides.rollouts, 2, 100000);
    line.option("--updates", "N",
                "planar10, wam_circle: policy updates per run (default: the thesis', 200 and 250; tables stop at 200)",
                &overrides.updates, 1, 100000);
    line.option("--forcing-variance", "V",
                "wam_circle: the initial latent variance, as the variance of the forcing term each weight moves at "
                "its kernel's peak, V > 0 (default: the experiment's, 100)",
                &overrides.forcing_variance);
    line.option(
        "--alpha-z", "A",
        "planar10, wam_circle, optima: the DMPs' alpha_z, with beta_z = alpha_z/4 (critically damped), A > 0 and small "
        "enough for a stable step (default 25)",
        &overrides.alpha_z);
    line.choice("--demonstration", {"joint", "task"},
                "wam_circle, optima: where the demonstration's smooth perturbations act, on the joints after IK "
                "(default) or on the tool before IK, as a hand guiding it would (tasks::CirclePerturbation)",
                &demonstration);
    line.choice("--circle", {"fitted", "nominal"},
                "wam_circle, optima: the circle the reward measures distances from, the one that best fits the "
                "demonstrated tool path (default, as the thesis computes it) or the one the demonstration was made "
                "from (tasks::CircleTarget)",
                &circle);
    line.option("--relative-prior", "P",
                "planar10: the initial latent covariance is the demonstrations' plus P times their mean weight "
                "variance on the diagonal, P > 0 (default: the experiment's, 0.01)",
                &overrides.relative_prior);
  };
  const Options options = bb::parseExperimentOptions(argc, argv, program);
  const double memory = overrides.covariance_memory;
  if (!std::isnan(memory) && !(memory >= 0.0 && memory < 1.0)) {
    std::fprintf(stderr, "dr_benchmark: --covariance-memory must be in [0, 1) (see --help)\n");
    return 2;
  }
  if (!std::isnan(memory) && overrides.adapted_covariance) {
    std::fprintf(stderr, "dr_benchmark: --covariance-memory does not apply with --adapted-covariance (see --help)\n");
    return 2;
  }
  if (!std::isnan(overrides.exploration) && !(overrides.exploration >= 0.0 && std::isfinite(overrides.exploration))) {
    std::fprintf(stderr, "dr_benchmark: --exploration must be finite and >= 0 (see --help)\n");
    return 2;
  }
  for (const auto& [value, name] :
       {std::pair{overrides.epsilon, "--epsilon"}, std::pair{overrides.forcing_variance, "--forcing-variance"},
        std::pair{overrides.relative_prior, "--relative-prior"}, std::pair{overrides.alpha_z, "--alpha-z"}}) {
    if (!std::isnan(value) && !(value > 0.0 && std::isfinite(value))) {
      std::fprintf(stderr, "dr_benchmark: %s must be finite and > 0 (see --help)\n", name);
      return 2;
    }
  }
  if (demonstration == "task") overrides.demonstration = bt::CirclePerturbation::Task;
  if (circle == "nominal") overrides.circle = bt::CircleTarget::Nominal;
  // Names hold commas inside parentheses ("DR-DMP_MCMU(3,4)"): split only at the others.
  std::string name;
  int depth = 0;
  for (const char c : algorithms + ",") {
    depth += c == '(' ? 1 : c == ')' ? -1 : 0;
    if (c != ',' || depth > 0) {
      name += c;
    } else if (!name.empty()) {
      selected_algorithms.push_back(name);
      name.clear();
    }
  }
  const auto wants = [&](const std::string& name) { return options.experiment == "all" || options.experiment == name; };
  try {
    // An --alpha-z whose steps are unstable is a bad argument: refuse it before any experiment runs.
    for (const DrDmpExperiment& experiment : drDmpExperiments()) {
      if (std::isnan(overrides.alpha_z) || !(wants(experiment.name) || wants("optima"))) continue;
      try {
        configuredTask(experiment, options.seed);
      } catch (const std::invalid_argument& e) {
        std::fprintf(stderr, "dr_benchmark: --alpha-z: %s in %s (see --help)\n", e.what(), experiment.name.c_str());
        return 2;
      }
    }
    std::filesystem::create_directories(options.out);
    std::printf("dr_benchmark: experiment %s, seed %u, %d jobs%s, output %s\n", options.experiment.c_str(),
                options.seed, options.jobs, options.quick ? " (quick)" : "", options.out.c_str());
    std::fflush(stdout);
    std::vector<Summary> rows;
    const auto timed = [&](const char* name, const std::function<void(const Options&, std::vector<Summary>&)>& run) {
      if (!wants(name)) return;
      const auto start = Clock::now();
      run(options, rows);
      std::printf("dr_benchmark: %s done in %.1f s\n", name, secondsSince(start));
      std::fflush(stdout);
    };
    timed("estep", estep);
    timed("em_vs_pca", emVsPca);
    timed("planar15", planar15);
    timed("planar10", planar10);
    timed("wam_circle", wamCircle);
    timed("optima", optima);
    timed("nao_walking", naoWalking);
    writeSummary(options, rows);
    if (!bb::runPlotScript("dr_benchmark", "plot_dr_benchmark.py", options.out)) return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "dr_benchmark: %s\n", e.what());
    return 1;
  }
  return 0;
}

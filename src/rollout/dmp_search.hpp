/// \file
/// One run's policy search over a DR-DMP fitted to a demonstration (module-private to rollout), shared by the fold's
/// and the generic DMP learner: the fit by the variant's PCA, the searched distribution (REPS' with its coordination
/// updates, or the peers' PI2-CMA, CMA-ES, REPS and DREPS on the fitted coordination, PI2-CMA optionally on a second
/// layer of Gaussians), each epoch's draws and the update from their rewards.
#pragma once

#include "bimanual_skills/learning/coordinated_reps.hpp"
#include "bimanual_skills/learning/covariance_adaptation.hpp"
#include "bimanual_skills/learning/dual_reps.hpp"
#include "bimanual_skills/learning/gaussian.hpp"
#include "bimanual_skills/primitives/dr_dmp.hpp"
#include "bimanual_skills/rollout/dmp_learning.hpp"

#include <Eigen/Core>

#include <cstdint>
#include <functional>
#include <optional>
#include <random>
#include <string>
#include <vector>

namespace bimanual_skills::rollout {

class DmpSearch {
 public:
  struct Settings {
    double epsilon = 0.5, covariance_memory = 0.0, h = 10.0;
    int reuse = 12;
    double initial_stddev = 1.0;  ///< Of each searched weight.
    /// Of each latent goal weight (DrDmpParameters::goal_offsets) [forcing units]; 0: initial_stddev.
    double goal_stddev = 0.0;
    int dual_kernels = 0;  ///< DmpLearningConfig::dual_kernels (PI2-CMA only).
    bool diagonal_covariance = false;
  };

  /// Fits `variant`'s DR-DMP (`parameters` with its matrices) to `demonstration` (samples × d every `step`).
  DmpSearch(const DrDmpVariant& variant, const primitives::DrDmpParameters& parameters,
            const Eigen::MatrixXd& demonstration, double step, const Settings& settings);

  /// The searched distribution: REPS' latent policy, or the peers' (on θ with a second layer).
  const learning::CoordinatedPolicy& policy() const noexcept;
  /// The latent weights a searched vector runs.
  Eigen::VectorXd weights(const Eigen::VectorXd& searched) const;

  /// One epoch's draws: make(kind, index, latent weights) for the noise-free mean (Policy, 0), then for each of
  /// `count` samples, in this order, drawing each sample from `rng` before its make(); returns the samples (searched
  /// vectors, one per row).
  Eigen::MatrixXd draw(int count, std::mt19937& rng,
                       const std::function<void(RolloutKind, int, const Eigen::VectorXd&)>& make);
  /// The update from the samples of draw() and their rewards.
  void update(const Eigen::MatrixXd& samples, const Eigen::VectorXd& rewards);

 private:
  DrDmpVariant variant_;
  Settings settings_;
  primitives::DrDmpFit fit_;
  learning::CoordinationGrid grid_;
  Eigen::MatrixXd phi_;  ///< The second layer (kernels × L), or the identity.
  bool dual_ = false;
  learning::CoordinatedReps learner_;
  learning::CoordinatedPolicy peer_;
  learning::CovarianceAdaptation adaptation_;
  std::optional<learning::DualReps> dual_reps_;  ///< REPS and DREPS.
  learning::GaussianSampler sampler_;
};

/// One run's epochs e = 0 … updates over `search`: each draws its batch (records of type Record, which has the
/// fields algorithm, run, epoch, kind, index, coordination, weights and seed, each given a rollout seed from `rng`
/// after its draw), evaluate(batch) fills the results, done(epoch, latent_dims, batch) takes them, and (e < updates)
/// the search updates from reward(record) of the samples.
template <typename Record, typename Evaluate, typename Reward, typename Done>
void searchEpochs(DmpSearch& search, const std::string& algorithm, int run, int updates, int rollouts,
                  std::mt19937& rng, Evaluate evaluate, Reward reward, Done done) {
  for (int epoch = 0; epoch <= updates; ++epoch) {
    const int latent_dims = search.policy().latentDims();
    std::vector<Record> batch;
    const Eigen::MatrixXd samples =
        search.draw(rollouts, rng, [&](RolloutKind kind, int index, const Eigen::VectorXd& weights) {
          Record& rec = batch.emplace_back();
          rec.algorithm = algorithm;
          rec.run = run;
          rec.epoch = epoch;
          rec.kind = kind;
          rec.index = index;
          rec.coordination = search.policy().coordination;
          rec.weights = weights;
          rec.seed = static_cast<std::uint32_t>(rng());
        });
    evaluate(batch);
    done(epoch, latent_dims, batch);
    if (epoch == updates) break;
    Eigen::VectorXd rewards(rollouts);
    for (const Record& rec : batch) {
      if (rec.kind == RolloutKind::Sample) rewards[rec.index] = reward(rec);
    }
    search.update(samples, rewards);
  }
}

/// One learning run, the loop every learner shares: the run-th run of its algorithm-index-th algorithm draws from
/// the generator seeded by (seed, algorithm_index, run) and runs searchEpochs; `result` (a run result with the fields
/// algorithm, run, best, initial_policy and final_policy, best's reward set below any) keeps the best rollout that
/// ok(record) accepts and the noise-free policies of the first and last epoch; epoch_done(epoch, latent_dims, batch)
/// then takes each epoch (its statistics, the learner's files).
template <typename Record, typename RunResult, typename Evaluate, typename Reward, typename Ok, typename EpochDone>
void searchRun(DmpSearch& search, const std::string& algorithm, int algorithm_index, int run, std::uint32_t seed,
               int updates, int rollouts, RunResult& result, Evaluate evaluate, Reward reward, Ok ok,
               EpochDone epoch_done) {
  std::seed_seq sequence{seed, static_cast<std::uint32_t>(algorithm_index), static_cast<std::uint32_t>(run)};
  std::mt19937 rng(sequence);
  result.algorithm = algorithm;
  result.run = run;
  searchEpochs<Record>(search, algorithm, run, updates, rollouts, rng, evaluate, reward,
                       [&](int epoch, int latent_dims, const std::vector<Record>& batch) {
                         for (const Record& rec : batch) {
                           if (ok(rec) && reward(rec) > reward(result.best)) result.best = rec;
                           if (rec.kind == RolloutKind::Policy && epoch == 0) result.initial_policy = rec;
                           if (rec.kind == RolloutKind::Policy && epoch == updates) result.final_policy = rec;
                         }
                         epoch_done(epoch, latent_dims, batch);
                       });
}

}  // namespace bimanual_skills::rollout

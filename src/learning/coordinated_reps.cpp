#include "bimanual_skills/learning/coordinated_reps.hpp"

#include "bimanual_skills/learning/gaussian.hpp"

#include <stdexcept>
#include <string>
#include <tuple>
#include <utility>

namespace bimanual_skills::learning {

void CoordinatedRepsParameters::validate() const {
  reps.validate();
  update.validate();
  em.validate();
  if (!(covariance_memory >= 0.0 && covariance_memory < 1.0)) {
    throw std::invalid_argument("CoordinatedRepsParameters: covariance_memory must be in [0, 1)");
  }
  if (covariance_rule == CovarianceRule::Adapted && (rule == CoordinationRule::Em || covariance_memory != 0.0)) {
    throw std::invalid_argument(
        "CoordinatedRepsParameters: the adapted covariance needs the Fixed or Cmu rule and covariance_memory 0");
  }
}

CoordinatedReps::CoordinatedReps(const CoordinatedRepsParameters& parameters, const CoordinationGrid& grid,
                                 const CoordinatedPolicy& initial,
                                 const std::vector<Eigen::MatrixXd>& initial_excitation)
    : parameters_(parameters), grid_(grid), policy_(initial), excitation_(initial_excitation) {
  parameters_.validate();
  if (static_cast<int>(policy_.coordination.size()) != grid_.matrices()) {
    throw std::invalid_argument("CoordinatedReps: needs one coordination matrix per activation of the grid (" +
                                std::to_string(grid_.matrices()) + ")");
  }
  const auto d = policy_.coordination.front().rows();
  const auto size = policy_.coordination.front().cols() * grid_.kernels();
  for (const Eigen::MatrixXd& omega : policy_.coordination) {
    if (omega.rows() != d || omega.cols() != policy_.coordination.front().cols() || omega.cols() < 1 ||
        omega.cols() > d || !omega.allFinite()) {
      throw std::invalid_argument("CoordinatedReps: coordination matrices must be finite, all d x r, 1 <= r <= d");
    }
  }
  if (policy_.mean.size() != size || policy_.covariance.rows() != size || policy_.covariance.cols() != size ||
      !policy_.mean.allFinite() || !policy_.covariance.allFinite()) {
    throw std::invalid_argument("CoordinatedReps: the latent mean needs r*kernels = " + std::to_string(size) +
                                " finite entries and the covariance that square size");
  }
  if (parameters_.rule == CoordinationRule::Em &&
      (grid_.matrices() != 1 || policy_.noise.rows() != d || policy_.noise.cols() != d)) {
    throw std::invalid_argument("CoordinatedReps: the EM rule needs one coordination matrix and a d x d noise");
  }
  for (const Eigen::MatrixXd& F : excitation_) {
    if (excitation_.size() != policy_.coordination.size() || F.rows() != d || F.cols() != grid_.steps()) {
      throw std::invalid_argument(
          "CoordinatedReps: the initial excitation needs one dofs x steps matrix per "
          "coordination matrix");
    }
  }
  if (parameters_.covariance_rule == CovarianceRule::Adapted) {
    adaptation_ = CovarianceAdaptation::start(policy_.covariance);
  }
}

CoordinatedRepsReport CoordinatedReps::update(const Eigen::MatrixXd& samples,
                                              const std::vector<Eigen::MatrixXd>& values,
                                              const Eigen::VectorXd& rewards) {
  const Eigen::Index batch = rewards.size();
  const Eigen::Index size = policy_.mean.size();
  if (batch < 2 || samples.rows() != batch || samples.cols() != size ||
      static_cast<Eigen::Index>(values.size()) != batch || !samples.allFinite() || !rewards.allFinite()) {
    throw std::invalid_argument("CoordinatedReps::update: needs >= 2 rollouts, each with a finite latent sample of " +
                                std::to_string(size) + " entries, its values and a finite reward");
  }
  // Kept rollouts first, then this batch.
  const auto count = static_cast<Eigen::Index>(kept_.size()) + batch;
  Eigen::MatrixXd theta(count, size);
  Eigen::VectorXd r(count);
  std::vector<Eigen::MatrixXd> all;
  all.reserve(static_cast<std::size_t>(count));
  Eigen::Index row = 0;
  for (const Rollout& rollout : kept_) {
    theta.row(row) = rollout.sample.transpose();
    r[row++] = rollout.reward;
    all.push_back(rollout.values);
  }
  theta.bottomRows(batch) = samples;
  r.tail(batch) = rewards;
  all.insert(all.end(), values.begin(), values.end());

  CoordinatedRepsReport report;
  report.weights = Reps::weights(parameters_.reps.normalise_rewards ? normalisedRewards(r) : r,
                                 parameters_.reps.epsilon, report.eta, report.kl);
  const double regularisation = parameters_.reps.covariance_regularisation;
  Eigen::MatrixXd sample_map;  // M† when the coordination changed
  const bool adapted = parameters_.covariance_rule == CovarianceRule::Adapted;
  // Fixed and Cmu: REPS' mean, and its weighted maximum-likelihood covariance blended with the sampled one by λ or
  // the adapted σ² C.
  const auto repsGaussian = [&]() -> std::pair<Eigen::VectorXd, Eigen::MatrixXd> {
    if (adapted) {
      Eigen::VectorXd mean = theta.transpose() * report.weights;  // REPS' mean, as weightedGaussian has it
      adaptation_.update(policy_.mean, mean, theta, report.weights);
      Eigen::MatrixXd covariance = adaptation_.covariance();
      covariance.diagonal().array() += regularisation;
      return {std::move(mean), std::move(covariance)};
    }
    auto gaussian = weightedGaussian(theta, report.weights, regularisation);
    const double memory = parameters_.covariance_memory;
    gaussian.second = (1.0 - memory) * gaussian.second + memory * policy_.covariance;
    return gaussian;
  };
  switch (parameters_.rule) {
    case CoordinationRule::Fixed: {
      std::tie(policy_.mean, policy_.covariance) = repsGaussian();
      break;
    }
    case CoordinationRule::Cmu: {
      auto [mean, covariance] = repsGaussian();
      CoordinationUpdateResult result = coordinationMatrixUpdate(grid_, parameters_.update, policy_.coordination,
                                                                 excitation_, all, report.weights, mean, covariance);
      policy_.coordination = std::move(result.matrices);
      policy_.mean = std::move(result.mean);
      policy_.covariance = std::move(result.covariance);
      // M† Σ M†ᵀ (7.36) is singular where M† loses rank (a new direction the old coordination did not span): the
      // same ridge as REPS' keeps it a sampling distribution.
      policy_.covariance.diagonal().array() += regularisation;
      excitation_ = std::move(result.excitation);
      sample_map = std::move(result.sample_map);
      if (adapted) {
        adaptation_.moveTo(sample_map.size() > 0 ? sample_map : Eigen::MatrixXd::Identity(size, size),
                           policy_.covariance);
      }
      report.reduced = result.reduced;
      break;
    }
    case CoordinationRule::Em: {
      LatentTrajectoryModel model{policy_.coordination.front(), policy_.mean, policy_.covariance, policy_.noise,
                                  Eigen::MatrixXd(size, 0)};
      const WeightedTrajectories data{all, report.weights, Eigen::MatrixXd(count, 0)};
      LatentEmResult result = latentEm(grid_, data, model, parameters_.em);
      policy_.coordination.front() = std::move(result.model.coordination);
      policy_.mean = std::move(result.model.mean);
      policy_.covariance = std::move(result.model.covariance);
      policy_.covariance.diagonal().array() += regularisation;
      policy_.noise = std::move(result.model.noise);
      report.em_iterations = result.iterations;
      break;
    }
  }
  // Keep the newest `reuse` rollouts, their samples in the current coordinates.
  for (Rollout& rollout : kept_) {
    if (sample_map.size() > 0) rollout.sample = sample_map * rollout.sample;
  }
  for (Eigen::Index k = 0; k < batch; ++k) {
    Eigen::VectorXd sample = samples.row(k).transpose();
    if (sample_map.size() > 0) sample = sample_map * sample;
    kept_.push_back({std::move(sample), values[static_cast<std::size_t>(k)], rewards[k]});
  }
  while (static_cast<int>(kept_.size()) > parameters_.reps.reuse) kept_.pop_front();
  return report;
}

}  // namespace bimanual_skills::learning

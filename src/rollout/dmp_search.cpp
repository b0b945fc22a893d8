#include "dmp_search.hpp"

namespace bimanual_skills::rollout {

namespace {

/// Diagonal variances of the fitted latent weights: initial_stddev², and per latent goal weight goal_stddev².
Eigen::VectorXd latentVariances(const primitives::DrDmpParameters& parameters, Eigen::Index size,
                                const DmpSearch::Settings& s) {
  Eigen::VectorXd variances = Eigen::VectorXd::Constant(size, s.initial_stddev * s.initial_stddev);
  const int basis = parameters.basisSize(), kernels = parameters.dmp.kernels;
  const double goal = s.goal_stddev > 0.0 ? s.goal_stddev : s.initial_stddev;
  for (Eigen::Index j = 0; basis > kernels && j < size / basis; ++j) variances[j * basis + kernels] = goal * goal;
  return variances;
}

learning::CoordinatedRepsParameters repsParameters(const DrDmpVariant& variant, const DmpSearch::Settings& s) {
  learning::CoordinatedRepsParameters reps;
  reps.reps.epsilon = s.epsilon;
  reps.reps.reuse = s.reuse;
  reps.covariance_memory = s.covariance_memory;
  reps.rule = variant.rule;
  reps.update.eta = variant.eta;
  return reps;
}

}  // namespace

DmpSearch::DmpSearch(const DrDmpVariant& variant, const primitives::DrDmpParameters& parameters,
                     const Eigen::MatrixXd& demonstration, double step, const Settings& settings)
    : variant_(variant),
      settings_(settings),
      fit_(primitives::DrDmp::fit(parameters, {demonstration}, step, variant.latent_dims, 0.0)),
      grid_(fit_.dmp.grid(step, static_cast<int>(demonstration.rows()) - 1)),
      phi_(variant.search == PolicySearch::Pi2Cma && settings.dual_kernels > 0
               ? dualLayer(parameters.basisSize(), settings.dual_kernels)
               : Eigen::MatrixXd::Identity(parameters.basisSize(), parameters.basisSize())),
      dual_(variant.search == PolicySearch::Pi2Cma && settings.dual_kernels > 0),
      learner_(repsParameters(variant, settings), grid_,
               {fit_.dmp.coordination(),
                fit_.dmp.weights(),
                latentVariances(parameters, fit_.dmp.weights().size(), settings).asDiagonal(),
                {}},
               fit_.excitation) {
  // The peers keep their own policy on the fitted coordination: on the latent weights, or on θ (L per latent DoF)
  // moving them by Φ θ from the fit, so that the search starts at the demonstration itself (θ = 0).
  peer_ = learner_.policy();
  if (dual_) {
    const Eigen::Index size = static_cast<Eigen::Index>(variant.latent_dims) * phi_.cols();
    peer_.mean = Eigen::VectorXd::Zero(size);
    peer_.covariance = Eigen::MatrixXd::Identity(size, size) * (settings.initial_stddev * settings.initial_stddev);
  }
  adaptation_ = learning::CovarianceAdaptation::start(peer_.covariance);
  if (variant.search == PolicySearch::StandardReps)
    dual_reps_.emplace(learning::thesisReps(settings.epsilon, settings.reuse));
  if (variant.search == PolicySearch::Dreps)
    dual_reps_.emplace(learning::thesisDreps(settings.epsilon, settings.reuse));
}

const learning::CoordinatedPolicy& DmpSearch::policy() const noexcept {
  return variant_.search == PolicySearch::Reps ? learner_.policy() : peer_;
}

Eigen::VectorXd DmpSearch::weights(const Eigen::VectorXd& searched) const {
  if (!dual_) return searched;
  const Eigen::Index basis = phi_.rows(), layer = phi_.cols();
  Eigen::VectorXd w = fit_.dmp.weights();
  for (Eigen::Index j = 0; j < variant_.latent_dims; ++j) {
    w.segment(j * basis, basis) += phi_ * searched.segment(j * layer, layer);
  }
  return w;
}

Eigen::MatrixXd DmpSearch::draw(int count, std::mt19937& rng,
                                const std::function<void(RolloutKind, int, const Eigen::VectorXd&)>& make) {
  const learning::CoordinatedPolicy& p = policy();
  const Eigen::MatrixXd factor = learning::choleskyFactor(p.covariance);
  Eigen::MatrixXd samples(count, p.mean.size());
  // The noise-free mean policy first (what a user of the learning gets at that point; not an exploration rollout
  // and not used by the update).
  make(RolloutKind::Policy, 0, weights(p.mean));
  for (int k = 0; k < count; ++k) {
    samples.row(k) = sampler_.draw(p.mean, factor, rng).transpose();
    make(RolloutKind::Sample, k, weights(samples.row(k).transpose()));
  }
  return samples;
}

void DmpSearch::update(const Eigen::MatrixXd& samples, const Eigen::VectorXd& rewards) {
  if (variant_.search == PolicySearch::Reps) {
    std::vector<Eigen::MatrixXd> values;
    for (Eigen::Index k = 0; k < samples.rows(); ++k) {
      values.push_back(learning::coordinatedValues(grid_, learner_.policy().coordination, samples.row(k).transpose()));
    }
    learner_.update(samples, values, rewards);
  } else if (variant_.search == PolicySearch::Pi2Cma) {
    peer_ = pi2CmaStep(peer_, samples, rewards, grid_.basis() * phi_, settings_.covariance_memory, settings_.h,
                       settings_.diagonal_covariance);
  } else if (dual_reps_) {
    const learning::DualRepsUpdate u = dual_reps_->update(peer_.mean, peer_.covariance, samples, rewards);
    peer_.mean = u.policy.mean;
    peer_.covariance =
        (1.0 - settings_.covariance_memory) * u.policy.covariance + settings_.covariance_memory * peer_.covariance;
  } else {
    peer_.mean = learning::cmaEsStep(peer_.mean, adaptation_, samples, rewards);
    peer_.covariance = adaptation_.covariance();
  }
}

}  // namespace bimanual_skills::rollout

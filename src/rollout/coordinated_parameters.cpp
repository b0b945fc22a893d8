#include "bimanual_skills/rollout/coordinated_parameters.hpp"

#include <cmath>

namespace bimanual_skills::rollout {

Eigen::VectorXd encodeCoordinatedPolicy(const std::vector<Eigen::MatrixXd>& coordination,
                                        const Eigen::VectorXd& weights) {
  Eigen::Index size = 2 + weights.size();
  for (const Eigen::MatrixXd& omega : coordination) size += omega.size();
  Eigen::VectorXd out(size);
  out[0] = static_cast<double>(coordination.size());
  out[1] = coordination.empty() ? 0.0 : static_cast<double>(coordination.front().cols());
  out.segment(2, weights.size()) = weights;
  Eigen::Index at = 2 + weights.size();
  for (const Eigen::MatrixXd& omega : coordination) {
    out.segment(at, omega.size()) = Eigen::Map<const Eigen::VectorXd>(omega.data(), omega.size());
    at += omega.size();
  }
  return out;
}

bool decodeCoordinatedPolicy(const Eigen::VectorXd& parameters, int dofs, int basis,
                             std::vector<Eigen::MatrixXd>& coordination, Eigen::VectorXd& weights) {
  if (parameters.size() < 2 || !std::isfinite(parameters[0]) || !std::isfinite(parameters[1])) return false;
  const double ns = parameters[0], r = parameters[1];
  if (ns != std::floor(ns) || r != std::floor(r) || ns < 1 || ns > 20 || r < 1 || r > dofs) return false;
  const auto matrices = static_cast<Eigen::Index>(ns), latent = static_cast<Eigen::Index>(r);
  if (parameters.size() != 2 + latent * basis + matrices * dofs * latent) return false;
  weights = parameters.segment(2, latent * basis);
  coordination.clear();
  Eigen::Index at = 2 + latent * basis;
  for (Eigen::Index s = 0; s < matrices; ++s) {
    coordination.push_back(Eigen::Map<const Eigen::MatrixXd>(parameters.data() + at, dofs, latent));
    at += dofs * latent;
  }
  return true;
}

}  // namespace bimanual_skills::rollout

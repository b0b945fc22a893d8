#include "bimanual_skills/primitives/promp_blending.hpp"

#include <Eigen/Cholesky>

#include <stdexcept>
#include <string>

namespace bimanual_skills::primitives {

TrajectoryDistribution blend(const std::vector<ProMp>& promps, const Eigen::VectorXd& phases,
                             const Eigen::MatrixXd& activations) {
  if (promps.empty()) throw std::invalid_argument("blend: needs at least one ProMP");
  const int dofs = promps.front().dofs();
  for (const ProMp& promp : promps) {
    if (promp.dofs() != dofs) throw std::invalid_argument("blend: every ProMP must have the same DoF");
  }
  if (activations.rows() != phases.size() || activations.cols() != static_cast<Eigen::Index>(promps.size())) {
    throw std::invalid_argument("blend: activations must be (number of phases) x (number of ProMPs)");
  }
  if (!phases.allFinite() || !activations.allFinite() || (activations.array() < 0.0).any()) {
    throw std::invalid_argument("blend: phases must be finite and activations finite and >= 0");
  }
  const int m = 2 * dofs;
  TrajectoryDistribution out;
  out.phases = phases;
  std::vector<ProMpData> data;
  for (const ProMp& promp : promps) data.emplace_back(promp);
  Eigen::VectorXd state_mean(m), information_mean(m);
  Eigen::MatrixXd state_covariance(m, m), information(m, m);
  Eigen::LLT<Eigen::MatrixXd> llt(m);
  for (Eigen::Index t = 0; t < phases.size(); ++t) {
    if (!(activations.row(t).maxCoeff() > 0.0)) {
      throw std::invalid_argument("blend: activations of phase " + std::to_string(t) + " are all zero");
    }
    information.setZero();
    information_mean.setZero();
    for (std::size_t i = 0; i < promps.size(); ++i) {
      const double alpha = activations(t, static_cast<Eigen::Index>(i));
      if (alpha == 0.0) continue;
      const ProMp& promp = promps[i];
      if (promp.mean(data[i], phases[t], state_mean.head(dofs), state_mean.tail(dofs)) != ProMpStatus::Success ||
          promp.stateCovariance(data[i], phases[t], state_covariance) != ProMpStatus::Success) {
        throw std::invalid_argument("blend: could not evaluate ProMP " + std::to_string(i));
      }
      llt.compute(state_covariance);
      if (llt.info() != Eigen::Success) {
        throw std::invalid_argument("blend: the state covariance of ProMP " + std::to_string(i) + " at phase " +
                                    std::to_string(t) + " is not positive definite");
      }
      information += alpha * llt.solve(Eigen::MatrixXd::Identity(m, m));
      information_mean += alpha * llt.solve(state_mean);
    }
    information = 0.5 * (information + information.transpose());
    llt.compute(information);
    if (llt.info() != Eigen::Success) {
      throw std::invalid_argument("blend: the blended information matrix at phase " + std::to_string(t) +
                                  " is not positive definite");
    }
    Eigen::MatrixXd covariance = llt.solve(Eigen::MatrixXd::Identity(m, m));
    out.means.push_back(covariance * information_mean);
    out.covariances.push_back(0.5 * (covariance + covariance.transpose()));
  }
  return out;
}

}  // namespace bimanual_skills::primitives

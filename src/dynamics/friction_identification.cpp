#include "bimanual_skills/dynamics/friction_identification.hpp"

#include "bimanual_skills/dynamics/rigid_body_dynamics.hpp"
#include "bimanual_skills/signal/acceleration_sign.hpp"

#include <Eigen/QR>
#include <nlopt.hpp>

#include <cmath>
#include <random>
#include <stdexcept>

namespace bimanual_skills::dynamics {
namespace {

[[noreturn]] void fail(const std::string& message) {
  throw std::invalid_argument(message);
}

/// Nonlinear parameters searched for each model type: none, s, (s, z) or (s, z, h).
int nonlinearCount(FrictionModelType type) {
  switch (type) {
    case FrictionModelType::Viscous:
      return 0;
    case FrictionModelType::Initial:
      return 1;
    case FrictionModelType::Basic:
      return 2;
    case FrictionModelType::Advanced:
      return 3;
  }
  return 0;
}

/// Samples of one joint to fit: position, velocity, acceleration sign and observed friction.
struct JointData {
  std::vector<double> q, qd, sign, f;
  int size() const { return static_cast<int>(q.size()); }
};

/// Ridge least-squares b for fixed nonlinear parameters, min ‖Φ b − F‖² + λ ‖b‖² with λ = ridge · rows (solved as
/// the least-squares problem of Φ stacked on √λ I), and that minimum (the search's objective: a fit that needs huge
/// coefficients costs more).
double solveLinear(JointFriction& joint, const JointData& data, int stride, double ridge) {
  const int p = linearParameterCount(joint.type);
  const int rows = (data.size() + stride - 1) / stride;
  Eigen::MatrixXd phi = Eigen::MatrixXd::Zero(rows + p, p);
  Eigen::VectorXd f = Eigen::VectorXd::Zero(rows + p);
  Eigen::VectorXd row(p);
  for (int k = 0, r = 0; k < data.size(); k += stride, ++r) {
    const auto i = static_cast<std::size_t>(k);
    frictionRegressor(joint, data.q[i], data.qd[i], data.sign[i], row);
    phi.row(r) = row.transpose();
    f[r] = data.f[i];
  }
  phi.bottomRows(p).diagonal().setConstant(std::sqrt(ridge * rows));
  joint.b = phi.colPivHouseholderQr().solve(f);
  if (!joint.b.allFinite()) joint.b.setZero();
  return (phi * joint.b - f).squaredNorm();
}

struct SearchContext {
  JointFriction* joint;
  const JointData* data;
  int stride;
  double ridge;
};

void setNonlinear(JointFriction& joint, const double* x) {
  const int k = nonlinearCount(joint.type);
  if (k >= 1) joint.s = x[0];
  if (k >= 2) joint.z = x[1];
  if (k >= 3) joint.h = x[2];
}

double objective(unsigned n, const double* x, double* gradient, void* context) {
  (void)n;
  (void)gradient;  // derivative-free (BOBYQA)
  auto* c = static_cast<SearchContext*>(context);
  setNonlinear(*c->joint, x);
  return solveLinear(*c->joint, *c->data, c->stride, c->ridge);
}

/// Best model of `type` for the samples, over seeded restarts of the nonlinear search.
JointFriction fitJoint(FrictionModelType type, const JointData& data, const FrictionFitOptions& options,
                       std::mt19937& rng) {
  JointFriction best;
  best.type = type;
  best.b = Eigen::VectorXd::Zero(linearParameterCount(type));
  if (data.size() < linearParameterCount(type) + 3) return best;  // not enough samples: zero friction
  const int k = nonlinearCount(type);
  const int stride = std::max(1, data.size() / std::max(1, options.max_search_samples));
  if (k == 0) {
    solveLinear(best, data, 1, options.ridge);
    return best;
  }
  const std::vector<double> lower = {options.s_min, options.z_min, options.h_min};
  const std::vector<double> upper = {options.s_max, options.z_max, options.h_max};
  double best_cost = std::numeric_limits<double>::infinity();
  for (int restart = 0; restart < options.restarts; ++restart) {
    JointFriction candidate = best;
    std::vector<double> x(static_cast<std::size_t>(k));
    for (int i = 0; i < k; ++i) {
      // s is searched log-uniformly (its range spans orders of magnitude), z and h uniformly.
      const auto j = static_cast<std::size_t>(i);
      x[j] = i == 0 ? std::exp(std::uniform_real_distribution<double>(std::log(lower[0]), std::log(upper[0]))(rng))
                    : std::uniform_real_distribution<double>(lower[j], upper[j])(rng);
    }
    SearchContext context{&candidate, &data, stride, options.ridge};
    nlopt::opt optimiser(nlopt::LN_BOBYQA, static_cast<unsigned>(k));
    optimiser.set_lower_bounds(std::vector<double>(lower.begin(), lower.begin() + k));
    optimiser.set_upper_bounds(std::vector<double>(upper.begin(), upper.begin() + k));
    optimiser.set_min_objective(objective, &context);
    optimiser.set_xtol_rel(1e-8);
    optimiser.set_maxeval(400);
    double cost = 0.0;
    try {
      optimiser.optimize(x, cost);
    } catch (const std::exception&) {
      cost = objective(static_cast<unsigned>(k), x.data(), nullptr, &context);  // keep the last point
    }
    setNonlinear(candidate, x.data());
    if (cost < best_cost) {
      best_cost = cost;
      best = candidate;
    }
  }
  solveLinear(best, data, 1, options.ridge);  // final coefficients on every sample
  return best;
}

}  // namespace

Eigen::MatrixXd observedFriction(const kinematics::ChainModel& model, const FrictionLog& log) {
  if (log.joints() != model.nq()) {
    fail("the log has " + std::to_string(log.joints()) + " joints, the model " + std::to_string(model.nq()));
  }
  DynamicsData data(model);
  Eigen::MatrixXd friction(log.samples(), log.joints());
  Eigen::VectorXd tau(model.nq());
  for (int r = 0; r < log.samples(); ++r) {
    const Eigen::VectorXd q = log.q.row(r).transpose();
    const Eigen::VectorXd qd = log.qd.row(r).transpose();
    const Eigen::VectorXd qdd = log.qdd.row(r).transpose();
    if (inverseDynamics(model, data, q, qd, qdd, tau) != DynamicsStatus::Success) {
      fail("inverse dynamics failed at sample " + std::to_string(r + 1));
    }
    friction.row(r) = log.tau.row(r) - tau.transpose();
  }
  return friction;
}

Eigen::MatrixXd accelerationSigns(const FrictionLog& log, SignSource source) {
  Eigen::MatrixXd signs(log.samples(), log.joints());
  if (source == SignSource::LoggedAcceleration) {
    signs = log.qdd.unaryExpr([](double a) { return signal::sign(a); });
    return signs;
  }
  const double period = (log.t[log.samples() - 1] - log.t[0]) / (log.samples() - 1);
  signal::AccelerationSign filter(log.joints(), period);
  for (int r = 0; r < log.samples(); ++r) {
    if (filter.update(log.qd.row(r).transpose()) != signal::SignalStatus::Success) {
      fail("acceleration signs: sample " + std::to_string(r + 1) + " has a non-finite velocity");
    }
    signs.row(r) = filter.sign().transpose();
  }
  return signs;
}

void FrictionFitOptions::validate() const {
  if (!(holdout >= 0.0 && holdout < 1.0)) fail("holdout must be in [0, 1)");
  if (restarts < 1) fail("restarts must be >= 1");
  if (!(epsilon >= 0.0)) fail("epsilon must be >= 0");
  if (!(s_min > 0.0 && s_min < s_max && z_min < z_max && h_min > 0.0 && h_min < h_max)) fail("bad search bounds");
  if (max_search_samples < 10) fail("max_search_samples must be >= 10");
  if (!(ridge >= 0.0)) fail("ridge must be >= 0");
}

std::vector<FrictionErrors> evaluateFriction(const FrictionModel& model, const FrictionLog& log,
                                             const Eigen::MatrixXd& friction, const Eigen::MatrixXd& signs, int first,
                                             int last) {
  const int n = log.joints();
  std::vector<FrictionErrors> errors(static_cast<std::size_t>(n));
  FrictionState state(model);
  Eigen::VectorXd tau(n);
  for (int r = 0; r < last; ++r) {
    if (frictionTorques(model, state, log.q.row(r).transpose(), log.qd.row(r).transpose(), signs.row(r).transpose(),
                        tau) != DynamicsStatus::Success) {
      fail("friction evaluation failed at sample " + std::to_string(r + 1));
    }
    if (r < first) continue;
    for (int j = 0; j < n; ++j) {
      const double e = std::abs(tau[j] - friction(r, j));
      FrictionErrors& err = errors[static_cast<std::size_t>(j)];
      err.mae += e;
      err.mse += e * e;
      err.max_error = std::max(err.max_error, e);
      ++err.samples;
    }
  }
  for (FrictionErrors& err : errors) {
    if (err.samples > 0) {
      err.mae /= err.samples;
      err.mse /= err.samples;
    }
  }
  return errors;
}

FrictionFit fitFriction(const FrictionLog& log, const Eigen::MatrixXd& friction, const Eigen::MatrixXd& signs,
                        const FrictionFitOptions& options) {
  options.validate();
  const int n = log.joints();
  const int m = log.samples();
  if (friction.rows() != m || friction.cols() != n || signs.rows() != m || signs.cols() != n) {
    fail("friction and sign matrices must be samples x joints");
  }
  const int train_end = std::max(10, static_cast<int>(std::lround((1.0 - options.holdout) * m)));
  // Pair modes along the log with the switching rule of the controller.
  FrictionModel switching;
  switching.joints.assign(static_cast<std::size_t>(n), JointFriction());
  for (const auto& [a, b] : options.pairs) switching.pairs.push_back(CoupledPair{a, b, {}, {}, options.epsilon});
  switching.validate();
  FrictionState state(switching);
  std::vector<std::vector<char>> mode(static_cast<std::size_t>(m));
  for (int r = 0; r < m; ++r) {
    updatePairModes(switching, state, log.qd.row(r).transpose());
    mode[static_cast<std::size_t>(r)] = state.reduced;
  }
  const auto samplesOf = [&](int joint, char reduced) {
    JointData data;
    for (int r = 0; r < train_end; ++r) {
      if (mode[static_cast<std::size_t>(r)][static_cast<std::size_t>(joint)] != reduced) continue;
      data.q.push_back(log.q(r, joint));
      data.qd.push_back(log.qd(r, joint));
      data.sign.push_back(signs(r, joint));
      data.f.push_back(friction(r, joint));
    }
    return data;
  };
  std::mt19937 rng(options.seed);
  FrictionFit fit;
  fit.model = switching;
  for (int j = 0; j < n; ++j) {
    fit.model.joints[static_cast<std::size_t>(j)] = fitJoint(options.type, samplesOf(j, 0), options, rng);
  }
  for (CoupledPair& pair : fit.model.pairs) {
    for (auto [joint, reduced] :
         {std::pair{pair.first, &pair.reduced_first}, std::pair{pair.second, &pair.reduced_second}}) {
      const JointData data = samplesOf(joint, 1);
      *reduced = data.size() >= linearParameterCount(options.type) + 3
                     ? fitJoint(options.type, data, options, rng)
                     : fit.model.joints[static_cast<std::size_t>(joint)];
    }
  }
  fit.train = evaluateFriction(fit.model, log, friction, signs, 0, train_end);
  fit.test = evaluateFriction(fit.model, log, friction, signs, train_end, m);
  return fit;
}

}  // namespace bimanual_skills::dynamics

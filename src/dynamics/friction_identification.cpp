#include "bimanual_skills/dynamics/friction_identification.hpp"

#include "bimanual_skills/dynamics/rigid_body_dynamics.hpp"

#include <yaml-cpp/yaml.h>
#include <Eigen/QR>
#include <nlopt.hpp>

#include <cmath>
#include <fstream>
#include <map>
#include <random>
#include <sstream>
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

/// Least-squares b for fixed nonlinear parameters, and the sum of squared residuals.
double solveLinear(JointFriction& joint, const JointData& data, int stride) {
  const int p = linearParameterCount(joint.type);
  const int rows = (data.size() + stride - 1) / stride;
  Eigen::MatrixXd phi(rows, p);
  Eigen::VectorXd f(rows);
  Eigen::VectorXd row(p);
  for (int k = 0, r = 0; k < data.size(); k += stride, ++r) {
    const auto i = static_cast<std::size_t>(k);
    frictionRegressor(joint, data.q[i], data.qd[i], data.sign[i], row);
    phi.row(r) = row.transpose();
    f[r] = data.f[i];
  }
  joint.b = phi.colPivHouseholderQr().solve(f);
  if (!joint.b.allFinite()) joint.b.setZero();
  return (phi * joint.b - f).squaredNorm();
}

struct SearchContext {
  JointFriction* joint;
  const JointData* data;
  int stride;
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
  return solveLinear(*c->joint, *c->data, c->stride);
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
    solveLinear(best, data, 1);
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
    SearchContext context{&candidate, &data, stride};
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
  solveLinear(best, data, 1);  // final coefficients on every sample
  return best;
}

JointFriction readJoint(const YAML::Node& node, FrictionModelType type, const std::string& where) {
  JointFriction joint;
  joint.type = type;
  if (!node.IsMap() || !node["b"] || !node["b"].IsSequence()) fail(where + ": needs a list 'b'");
  std::vector<double> b;
  try {
    b = node["b"].as<std::vector<double>>();
    if (node["s"]) joint.s = node["s"].as<double>();
    if (node["z"]) joint.z = node["z"].as<double>();
    if (node["h"]) joint.h = node["h"].as<double>();
  } catch (const YAML::Exception& e) {
    fail(where + ": " + e.what());
  }
  joint.b = Eigen::Map<const Eigen::VectorXd>(b.data(), static_cast<Eigen::Index>(b.size()));
  try {
    joint.validate();
  } catch (const std::invalid_argument& e) {
    fail(where + ": " + e.what());
  }
  return joint;
}

void writeJoint(YAML::Emitter& out, const JointFriction& joint) {
  out << YAML::BeginMap;
  out << YAML::Key << "b" << YAML::Value << YAML::Flow
      << std::vector<double>(joint.b.data(), joint.b.data() + joint.b.size());
  out << YAML::Key << "s" << YAML::Value << joint.s;
  out << YAML::Key << "z" << YAML::Value << joint.z;
  out << YAML::Key << "h" << YAML::Value << joint.h;
  out << YAML::EndMap;
}

}  // namespace

FrictionLog readFrictionLog(const std::string& path) {
  std::ifstream file(path);
  if (!file) fail("cannot read friction log '" + path + "'");
  std::string line;
  if (!std::getline(file, line)) fail("friction log '" + path + "' is empty");
  std::vector<std::string> header;
  {
    std::stringstream stream(line);
    std::string name;
    while (std::getline(stream, name, ',')) header.push_back(name);
  }
  std::map<std::string, int> column;
  for (std::size_t i = 0; i < header.size(); ++i) column[header[i]] = static_cast<int>(i);
  if (!column.count("t")) fail("friction log '" + path + "': no column 't'");
  int n = 0;
  while (column.count("q" + std::to_string(n + 1))) ++n;
  if (n == 0) fail("friction log '" + path + "': no columns q1, q2, ...");
  for (const char* prefix : {"qd", "qdd", "tau"}) {
    for (int j = 1; j <= n; ++j) {
      if (!column.count(prefix + std::to_string(j))) {
        fail("friction log '" + path + "': missing column '" + prefix + std::to_string(j) + "'");
      }
    }
  }
  std::vector<std::vector<double>> rows;
  int line_number = 1;
  while (std::getline(file, line)) {
    ++line_number;
    if (line.empty()) continue;
    std::vector<double> values;
    std::stringstream stream(line);
    std::string cell;
    while (std::getline(stream, cell, ',')) {
      char* end = nullptr;
      const double v = std::strtod(cell.c_str(), &end);
      if (cell.empty() || *end != '\0' || !std::isfinite(v)) {
        fail("friction log '" + path + "' line " + std::to_string(line_number) + ": '" + cell + "' is not a number");
      }
      values.push_back(v);
    }
    if (values.size() != header.size()) {
      fail("friction log '" + path + "' line " + std::to_string(line_number) + ": " + std::to_string(values.size()) +
           " values for " + std::to_string(header.size()) + " columns");
    }
    rows.push_back(std::move(values));
  }
  if (rows.size() < 10) fail("friction log '" + path + "' has fewer than 10 samples");
  FrictionLog log;
  const auto m = static_cast<Eigen::Index>(rows.size());
  log.t.resize(m);
  log.q.resize(m, n);
  log.qd.resize(m, n);
  log.qdd.resize(m, n);
  log.tau.resize(m, n);
  for (Eigen::Index r = 0; r < m; ++r) {
    const auto& row = rows[static_cast<std::size_t>(r)];
    log.t[r] = row[static_cast<std::size_t>(column["t"])];
    if (r > 0 && !(log.t[r] > log.t[r - 1])) {
      fail("friction log '" + path + "': time does not increase at sample " + std::to_string(r + 1));
    }
    for (int j = 0; j < n; ++j) {
      const std::string k = std::to_string(j + 1);
      log.q(r, j) = row[static_cast<std::size_t>(column["q" + k])];
      log.qd(r, j) = row[static_cast<std::size_t>(column["qd" + k])];
      log.qdd(r, j) = row[static_cast<std::size_t>(column["qdd" + k])];
      log.tau(r, j) = row[static_cast<std::size_t>(column["tau" + k])];
    }
  }
  return log;
}

void writeFrictionLog(const FrictionLog& log, const std::string& path) {
  std::ofstream file(path);
  if (!file) fail("cannot write friction log '" + path + "'");
  file.precision(12);
  file << "t";
  for (const char* prefix : {"q", "qd", "qdd", "tau"}) {
    for (int j = 1; j <= log.joints(); ++j) file << ',' << prefix << j;
  }
  file << '\n';
  for (int r = 0; r < log.samples(); ++r) {
    file << log.t[r];
    for (const Eigen::MatrixXd* m : {&log.q, &log.qd, &log.qdd, &log.tau}) {
      for (int j = 0; j < log.joints(); ++j) file << ',' << (*m)(r, j);
    }
    file << '\n';
  }
}

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
    signs = log.qdd.unaryExpr([](double a) { return a > 0.0 ? 1.0 : a < 0.0 ? -1.0 : 0.0; });
    return signs;
  }
  const double period = (log.t[log.samples() - 1] - log.t[0]) / (log.samples() - 1);
  AccelerationSign filter(log.joints(), period);
  for (int r = 0; r < log.samples(); ++r) signs.row(r) = filter.update(log.qd.row(r).transpose()).transpose();
  return signs;
}

void FrictionFitOptions::validate() const {
  if (!(holdout >= 0.0 && holdout < 1.0)) fail("holdout must be in [0, 1)");
  if (restarts < 1) fail("restarts must be >= 1");
  if (!(epsilon >= 0.0)) fail("epsilon must be >= 0");
  if (!(s_min > 0.0 && s_min < s_max && z_min < z_max && h_min > 0.0 && h_min < h_max)) fail("bad search bounds");
  if (max_search_samples < 10) fail("max_search_samples must be >= 10");
}

std::vector<FrictionErrors> evaluateFriction(const FrictionModel& model, const FrictionLog& log,
                                             const Eigen::MatrixXd& friction, const Eigen::MatrixXd& signs, int first,
                                             int last) {
  const int n = log.joints();
  std::vector<FrictionErrors> errors(static_cast<std::size_t>(n));
  FrictionState state(model);
  Eigen::VectorXd tau(n);
  for (int r = 0; r < last; ++r) {
    if (!frictionTorques(model, state, log.q.row(r).transpose(), log.qd.row(r).transpose(), signs.row(r).transpose(),
                         tau)) {
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

void saveFrictionModel(const FrictionModel& model, const std::string& path, const std::string& comment) {
  model.validate();
  YAML::Emitter out;
  out.SetDoublePrecision(12);
  out << YAML::BeginMap;
  out << YAML::Key << "model" << YAML::Value << (model.joints.empty() ? "viscous" : toString(model.joints[0].type));
  out << YAML::Key << "joints" << YAML::Value << YAML::BeginSeq;
  for (const JointFriction& joint : model.joints) writeJoint(out, joint);
  out << YAML::EndSeq;
  out << YAML::Key << "pairs" << YAML::Value << YAML::BeginSeq;
  for (const CoupledPair& pair : model.pairs) {
    out << YAML::BeginMap;
    out << YAML::Key << "joints" << YAML::Value << YAML::Flow << std::vector<int>{pair.first + 1, pair.second + 1};
    out << YAML::Key << "epsilon" << YAML::Value << pair.epsilon;
    out << YAML::Key << "reduced" << YAML::Value << YAML::BeginSeq;
    writeJoint(out, pair.reduced_first);
    writeJoint(out, pair.reduced_second);
    out << YAML::EndSeq << YAML::EndMap;
  }
  out << YAML::EndSeq << YAML::EndMap;
  std::ofstream file(path);
  if (!file) fail("cannot write friction model '" + path + "'");
  std::stringstream text(comment);
  for (std::string line; std::getline(text, line);) file << "# " << line << '\n';
  file << out.c_str() << '\n';
}

FrictionModel loadFrictionModel(const std::string& path) {
  YAML::Node root;
  try {
    root = YAML::LoadFile(path);
  } catch (const YAML::Exception& e) {
    fail("friction model '" + path + "': " + e.what());
  }
  const std::string where = "friction model '" + path + "'";
  FrictionModelType type;
  if (!root.IsMap() || !root["model"] || !parseFrictionModelType(root["model"].as<std::string>(""), type)) {
    fail(where + ": 'model' must be viscous, initial, basic or advanced");
  }
  if (!root["joints"] || !root["joints"].IsSequence() || root["joints"].size() == 0) {
    fail(where + ": needs a non-empty list 'joints'");
  }
  FrictionModel model;
  for (std::size_t i = 0; i < root["joints"].size(); ++i) {
    model.joints.push_back(readJoint(root["joints"][i], type, where + " joint " + std::to_string(i + 1)));
  }
  if (root["pairs"]) {
    if (!root["pairs"].IsSequence()) fail(where + ": 'pairs' must be a list");
    for (std::size_t k = 0; k < root["pairs"].size(); ++k) {
      const YAML::Node node = root["pairs"][k];
      const std::string at = where + " pair " + std::to_string(k + 1);
      if (!node["joints"] || !node["joints"].IsSequence() || node["joints"].size() != 2 || !node["reduced"] ||
          !node["reduced"].IsSequence() || node["reduced"].size() != 2) {
        fail(at + ": needs 'joints' [i, j] and two 'reduced' models");
      }
      CoupledPair pair;
      try {
        pair.first = node["joints"][0].as<int>() - 1;
        pair.second = node["joints"][1].as<int>() - 1;
        pair.epsilon = node["epsilon"] ? node["epsilon"].as<double>() : pair.epsilon;
      } catch (const YAML::Exception& e) {
        fail(at + ": " + e.what());
      }
      pair.reduced_first = readJoint(node["reduced"][0], type, at + " reduced 1");
      pair.reduced_second = readJoint(node["reduced"][1], type, at + " reduced 2");
      model.pairs.push_back(pair);
    }
  }
  try {
    model.validate();
  } catch (const std::invalid_argument& e) {
    fail(where + ": " + e.what());
  }
  return model;
}

}  // namespace bimanual_skills::dynamics

// The thesis' inverse kinematics experiments (Ch. 3.1: Tables 3.4, 3.5, Figs. 3.2–3.5) and the TRAC-IK protocol
// against KDL's solvers, as one seeded program.
//
//   ik_benchmark --experiment table34|table35|fig35|fig32|fig33|tracik|closest|all --seed S --out DIR [--quick]
//                [--urdf FILE --base LINK --tip LINK]   (tracik and closest; default: the WAM)
//
// Writes DIR/summary.json (one object per solver x setting), DIR/<experiment>.csv (one row per sample, written as
// samples complete), then runs scripts/plot_ik_benchmark.py for the PNG plots and DIR/tables.md.
#include "bimanual_skills/kinematics/chain_model.hpp"
#include "bimanual_skills/kinematics/global_ik.hpp"
#include "cli/package_share.hpp"
#include "cli/pinned_numerics.hpp"
#include "experiment_cli.hpp"

#include <kdl/chainfksolverpos_recursive.hpp>
#include <kdl/chainiksolverpos_lma.hpp>
#include <kdl/chainiksolverpos_nr_jl.hpp>
#include <kdl/chainiksolvervel_pinv.hpp>
#include <kdl_parser/kdl_parser.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <random>
#include <sstream>
#include <string>
#include <vector>

namespace bk = bimanual_skills::kinematics;
using bk::InverseOperator;
using bk::LimitScheme;
using Clock = std::chrono::steady_clock;

namespace {

/// The WAM of urdf/wam.urdf.
std::string wamUrdf() {
  return bimanual_skills::cli::packageFile("urdf/wam.urdf");
}

using Options = bimanual_skills::bench::ExperimentOptions;

/// The chain of the tracik and closest experiments (--urdf, --base, --tip).
struct Arm {
  std::string urdf, base = "wam_base", tip = "wam_tool";  ///< urdf: empty until resolved (urdf/wam.urdf)
  /// The URDF file's name without directory and extension ("wam").
  std::string name() const { return std::filesystem::path(urdf).stem().string(); }
};

/// One row of summary.json.
struct Summary {
  std::string experiment, solver, setting;
  int samples = 0;
  double success_rate = 0, within_limits_rate = 0, median_us = 0, p99_us = 0, mean_iterations = 0;
  double mean_residual_failed = 0;
  std::string robot = "wam";
  std::vector<std::pair<std::string, double>> extra;  ///< Experiment-specific fields.
};

/// Accumulates per-sample outcomes of one solver x setting and writes them to the experiment's CSV as they come.
class Recorder {
 public:
  Recorder(std::ofstream& csv, std::string experiment, std::string solver, std::string setting) : csv_(csv) {
    summary_.experiment = std::move(experiment);
    summary_.solver = std::move(solver);
    summary_.setting = std::move(setting);
  }

  void add(bool success, bool within_limits, double time_us, int iterations, double residual) {
    csv_ << summary_.solver << ',' << summary_.setting << ',' << times_.size() << ',' << success << ',' << within_limits
         << ',' << time_us << ',' << iterations << ',' << residual << '\n';
    times_.push_back(time_us);
    ++summary_.samples;
    if (success) {
      ++successes_;
      iterations_ += iterations;
      if (within_limits) ++within_;
    } else {
      ++failures_;
      residual_failed_ += residual;
    }
  }

  Summary finish() {
    csv_.flush();
    std::sort(times_.begin(), times_.end());
    const auto at = [&](double f) {
      return times_.empty() ? 0.0 : times_[static_cast<std::size_t>(f * static_cast<double>(times_.size() - 1))];
    };
    const double n = std::max(1, summary_.samples);
    summary_.success_rate = successes_ / n;
    summary_.within_limits_rate = within_ / n;
    summary_.median_us = at(0.5);
    summary_.p99_us = at(0.99);
    summary_.mean_iterations = successes_ > 0 ? iterations_ / successes_ : 0.0;
    summary_.mean_residual_failed = failures_ > 0 ? residual_failed_ / failures_ : 0.0;
    std::printf(
        "  %-12s %-22s n=%-6d success %6.2f %%  within limits %6.2f %%  median %8.1f us  p99 %9.1f us  it %.1f\n",
        summary_.solver.c_str(), summary_.setting.c_str(), summary_.samples, 100 * summary_.success_rate,
        100 * summary_.within_limits_rate, summary_.median_us, summary_.p99_us, summary_.mean_iterations);
    std::fflush(stdout);
    return summary_;
  }

 private:
  std::ofstream& csv_;
  Summary summary_;
  std::vector<double> times_;
  double successes_ = 0, within_ = 0, failures_ = 0, iterations_ = 0, residual_failed_ = 0;
};

/// A CLIK method of the thesis with its table label and parameter note.
struct Method {
  std::string name;
  std::string setting;
  bk::ClikParameters parameters;
};

Method method(InverseOperator op, LimitScheme scheme, std::string setting) {
  bk::ClikParameters parameters;
  parameters.inverse = op;
  parameters.limits = scheme;
  return {bk::methodName(op, scheme), std::move(setting), parameters};
}

std::vector<Method> table34Methods() {
  return {method(InverseOperator::Pseudoinverse, LimitScheme::None, "-"),
          method(InverseOperator::Transpose, LimitScheme::None, "Buss step"),
          method(InverseOperator::SelectiveDamping, LimitScheme::None, "gamma_max=0.5"),
          method(InverseOperator::Damping, LimitScheme::None, "lambda=0.005"),
          method(InverseOperator::Filtering, LimitScheme::None, "lambda_max=4lambda"),
          method(InverseOperator::ErrorDamping, LimitScheme::None, "-"),
          method(InverseOperator::ImprovedErrorDamping, LimitScheme::None, "Omega=0.01I"),
          method(InverseOperator::SingularValueFilter, LimitScheme::None, "nu=10 sigma0=0.01"),
          method(InverseOperator::SvfErrorDamping, LimitScheme::None, "-"),
          method(InverseOperator::SvfSelectiveDamping, LimitScheme::None, "-")};
}

std::vector<Method> table35Methods() {
  return {method(InverseOperator::Pseudoinverse, LimitScheme::JointWeighting, "Chan-Dubey W"),
          method(InverseOperator::Pseudoinverse, LimitScheme::GradientProjection, "mu=0.2"),
          method(InverseOperator::Pseudoinverse, LimitScheme::TaskAugmentation, "h_beta rows"),
          method(InverseOperator::Pseudoinverse, LimitScheme::JointClamping, "H=I-h_beta"),
          method(InverseOperator::Pseudoinverse, LimitScheme::TaskPriority, "h_beta"),
          method(InverseOperator::Pseudoinverse, LimitScheme::ContinuousTaskPriority, "h_beta"),
          method(InverseOperator::SingularValueFilter, LimitScheme::ContinuousTaskPriority, "-"),
          method(InverseOperator::SelectiveDamping, LimitScheme::ContinuousTaskPriority, "-"),
          method(InverseOperator::SvfSelectiveDamping, LimitScheme::ContinuousTaskPriority, "-")};
}

/// q_F uniform in the box |q_F − q_0| < A intersected with the limits (the thesis' acceptance test, sampled directly:
/// rejection from independent draws has an acceptance of ~1e-7 at A = 0.25).
Eigen::VectorXd uniformNear(const bk::ChainModel& model, const Eigen::VectorXd& q0, double A, std::mt19937& rng) {
  Eigen::VectorXd q(model.nq());
  for (int i = 0; i < model.nq(); ++i) {
    const double lo = std::max(model.lowerLimits()[i], q0[i] - A);
    const double hi = std::min(model.upperLimits()[i], q0[i] + A);
    q[i] = std::uniform_real_distribution<double>(lo, hi)(rng);
  }
  return q;
}

/// Runs a local CLIK solve from every start to the FK of every goal.
Summary runClik(const bk::ChainModel& model, const Method& m, const std::vector<Eigen::VectorXd>& starts,
                const std::vector<Eigen::Isometry3d>& targets, std::ofstream& csv, const std::string& experiment,
                const std::string& setting) {
  bk::ClikData data(model, m.parameters);
  Recorder recorder(csv, experiment, m.name, setting);
  for (std::size_t k = 0; k < starts.size(); ++k) {
    Eigen::VectorXd q = starts[k];
    const auto t0 = Clock::now();
    const bk::IkResult result = bk::solve(model, m.parameters, data, q, targets[k]);
    const double us = std::chrono::duration<double, std::micro>(Clock::now() - t0).count();
    const bool success = result.status == bk::IkStatus::Converged;
    recorder.add(success, success && model.withinLimits(q), us, result.iterations, result.residual);
  }
  return recorder.finish();
}

std::vector<Eigen::Isometry3d> forward(const bk::ChainModel& model, const std::vector<Eigen::VectorXd>& qs) {
  bk::ChainData data(model);
  std::vector<Eigen::Isometry3d> poses;
  for (const auto& q : qs) {
    if (bk::forwardKinematics(model, data, q) != bk::KinematicsStatus::Success) throw std::runtime_error("FK failed");
    poses.push_back(data.tipPose());
  }
  return poses;
}

std::ofstream openCsv(const Options& options, const std::string& name, const std::string& header) {
  std::ofstream csv(options.out + "/" + name + ".csv");
  if (!csv) throw std::runtime_error("cannot write " + options.out + "/" + name + ".csv");
  csv.precision(10);
  csv << header << '\n';
  return csv;
}

const char* kSampleHeader = "solver,setting,sample,success,within_limits,time_us,iterations,residual";

void table34(const Options& options, std::vector<Summary>& out) {
  const bk::ChainModel model = bk::ChainModel::fromUrdfFile(wamUrdf(), "wam_base", "wam_tool");
  const int samples = options.quick ? 100 : 1000;
  std::mt19937 rng(options.seed);
  std::vector<Eigen::VectorXd> starts, goals;
  for (int k = 0; k < samples; ++k) {
    starts.push_back(bk::randomWithinLimits(model, rng));
    goals.push_back(bk::randomWithinLimits(model, rng));
  }
  const auto targets = forward(model, goals);
  std::ofstream csv = openCsv(options, "table34", kSampleHeader);
  std::printf("table34: %d random start/goal pairs uniform within the limits (seed %u)\n", samples, options.seed);
  for (const Method& m : table34Methods()) out.push_back(runClik(model, m, starts, targets, csv, "table34", m.setting));
}

void limitExperiment(const Options& options, const std::string& name, const std::vector<double>& amplitudes,
                     std::vector<Summary>& out) {
  const bk::ChainModel model = bk::ChainModel::fromUrdfFile(wamUrdf(), "wam_base", "wam_tool");
  const int samples = options.quick ? 100 : 1000;
  std::ofstream csv = openCsv(options, name, kSampleHeader);
  for (double A : amplitudes) {
    std::mt19937 rng(options.seed);
    std::vector<Eigen::VectorXd> starts, goals;
    for (int k = 0; k < samples; ++k) {
      starts.push_back(bk::randomWithinLimits(model, rng));
      goals.push_back(uniformNear(model, starts.back(), A, rng));
    }
    const auto targets = forward(model, goals);
    char setting[32];
    std::snprintf(setting, sizeof(setting), "A=%.2f", A);
    std::printf("%s: %d pairs with |q0 - qF| < %.2f per joint (seed %u)\n", name.c_str(), samples, A, options.seed);
    for (const Method& m : table35Methods()) out.push_back(runClik(model, m, starts, targets, csv, name, setting));
  }
}

/// A planar 4R arm (links of 0.25 m along x, joints about z, limits ±2 rad), as in the thesis' Figs. 3.2–3.4.
bk::ChainModel planar4R() {
  std::vector<bk::ChainJoint> joints;
  for (int i = 0; i < 4; ++i) {
    bk::ChainJoint joint;
    joint.name = "joint" + std::to_string(i + 1);
    joint.child_link = "link" + std::to_string(i + 1);
    joint.origin.translation() << (i == 0 ? 0.0 : 0.25), 0.0, 0.0;
    joint.lower = -2.0;
    joint.upper = 2.0;
    joints.push_back(joint);
  }
  Eigen::Isometry3d tip = Eigen::Isometry3d::Identity();
  tip.translation().x() = 0.25;
  return bk::ChainModel("base", "tip", joints, tip);
}

void fig32(const Options& options, std::vector<Summary>&) {
  // Condition number κ = max g(σ)/min g(σ) of each operator's inverse along a straight joint path into the
  // stretched (singular) configuration; parameters of the thesis' Fig. 3.2: λ = 1e-2, λ_max = 5λ, σ0 = 0.005, ν = 10.
  const bk::ChainModel model = planar4R();
  bk::ChainData data(model);
  bk::ClikParameters p;
  p.lambda = 1e-2;
  p.lambda_max = 5e-2;
  p.sigma0 = 0.005;
  p.nu = 10.0;
  p.pinv_tolerance = 0.0;
  const std::vector<std::pair<std::string, InverseOperator>> ops = {{"JP", InverseOperator::Pseudoinverse},
                                                                    {"JD", InverseOperator::Damping},
                                                                    {"JF", InverseOperator::Filtering},
                                                                    {"ED", InverseOperator::ErrorDamping},
                                                                    {"IED", InverseOperator::ImprovedErrorDamping},
                                                                    {"SVF", InverseOperator::SingularValueFilter}};
  std::ofstream csv = openCsv(options, "fig32", "method,t,sigma_min,condition_number");
  const Eigen::VectorXd q_start = (Eigen::VectorXd(4) << 0.9, -0.7, 0.6, -0.5).finished();
  const Eigen::Vector2d target(1.0, 0.0);  // the stretched configuration q = 0
  const int steps = options.quick ? 200 : 2000;
  for (int k = 0; k <= steps; ++k) {
    const double t = 1.0 - std::pow(10.0, -6.0 * k / steps);  // approach logarithmically: σ_min down to ~1e-6
    const Eigen::VectorXd q = (1.0 - t) * q_start;
    if (bk::computeJacobian(model, data, q) != bk::KinematicsStatus::Success) throw std::runtime_error("4R FK");
    const Eigen::JacobiSVD<Eigen::MatrixXd> svd(data.jacobian.topRows(2));
    const Eigen::Vector2d sigma = svd.singularValues();
    const double E = 0.5 * (target - data.tipPose().translation().head<2>()).squaredNorm();
    for (const auto& [name, op] : ops) {
      const double g1 = bk::inverseOperatorGain(p, op, sigma[0], sigma[1], E);
      const double g2 = bk::inverseOperatorGain(p, op, sigma[1], sigma[1], E);
      csv << name << ',' << t << ',' << sigma[1] << ',' << std::max(g1, g2) / std::min(g1, g2) << '\n';
    }
  }
  std::printf("fig32: condition numbers of 6 operators on %d points approaching the 4R singularity\n", steps + 1);
}

void fig33(const Options& options, std::vector<Summary>&) {
  // CLIK runs on the 4R arm from the horizontal (singular) start to a reachable target; joint trajectories and arm
  // drawings per method (Figs. 3.3 and 3.4).
  const bk::ChainModel model = planar4R();
  std::ofstream csv = openCsv(options, "fig33", "figure,method,iteration,q1,q2,q3,q4,x,y");
  Eigen::Isometry3d target = Eigen::Isometry3d::Identity();
  target.translation() << 0.15, 0.55, 0.0;
  std::vector<std::pair<std::string, Method>> runs;
  for (auto op : {InverseOperator::Pseudoinverse, InverseOperator::Transpose, InverseOperator::Filtering,
                  InverseOperator::ImprovedErrorDamping, InverseOperator::SelectiveDamping,
                  InverseOperator::SvfSelectiveDamping}) {
    runs.emplace_back("3.3", method(op, LimitScheme::None, ""));
  }
  for (const Method& m : table35Methods()) runs.emplace_back("3.4", m);
  bk::ChainData kinematics(model);
  for (auto& [figure, m] : runs) {
    m.parameters.mode = bk::TaskMode::PlanarPosition;
    m.parameters.max_iterations = 1;
    bk::ClikData data(model, m.parameters);
    Eigen::VectorXd q = Eigen::VectorXd::Zero(4);
    for (int iteration = 0; iteration <= 150; ++iteration) {
      if (bk::forwardKinematics(model, kinematics, q) != bk::KinematicsStatus::Success) break;
      const Eigen::Vector3d p = kinematics.tipPose().translation();
      csv << figure << ',' << m.name << ',' << iteration << ',' << q[0] << ',' << q[1] << ',' << q[2] << ',' << q[3]
          << ',' << p.x() << ',' << p.y() << '\n';
      if (bk::step(model, m.parameters, data, q, target) != bk::IkStatus::StepComputed) break;
      q += data.dq;
    }
  }
  std::printf("fig33: %zu 4R CLIK trajectories from the horizontal start to (0.15, 0.55)\n", runs.size());
}

bool twistWithin(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b, double tolerance) {
  Eigen::VectorXd e(6);
  bk::poseError(a, b, bk::TaskMode::Pose, e);
  return e.cwiseAbs().maxCoeff() <= tolerance;
}

void tracik(const Options& options, const Arm& arm, std::vector<Summary>& out) {
  // TRAC-IK's protocol (trac_ik_examples ik_tests): random configurations within limits, FK, IK from the mid-limit
  // nominal seed and from a random seed; success = every pose-error twist component ≤ 1e-5; 5 ms per solve,
  // failures counted with their whole time.
  const bk::ChainModel model = bk::ChainModel::fromUrdfFile(arm.urdf, arm.base, arm.tip);
  KDL::Tree tree;
  KDL::Chain chain;
  if (!kdl_parser::treeFromFile(arm.urdf, tree) || !tree.getChain(arm.base, arm.tip, chain)) {
    throw std::runtime_error("KDL cannot load the chain " + arm.base + " -> " + arm.tip + " of " + arm.urdf);
  }
  const unsigned n = chain.getNrOfJoints();
  KDL::JntArray lower(n), upper(n);
  lower.data = model.lowerLimits();
  upper.data = model.upperLimits();
  const int samples = options.quick ? 500 : 10000;
  const double budget = 0.005, eps = 1e-5;
  std::mt19937 rng(options.seed);
  std::vector<Eigen::VectorXd> goals, random_seeds;
  for (int k = 0; k < samples; ++k) goals.push_back(bk::randomWithinLimits(model, rng));
  for (int k = 0; k < samples; ++k) random_seeds.push_back(bk::randomWithinLimits(model, rng));
  const auto targets = forward(model, goals);
  const Eigen::VectorXd nominal = 0.5 * (model.lowerLimits() + model.upperLimits());
  std::ofstream csv = openCsv(options, "tracik", kSampleHeader);
  std::printf(
      "tracik: %s (%d joints), %d random poses, 5 ms budget, success = every twist component <= 1e-5 (seed %u)\n",
      arm.name().c_str(), model.nq(), samples, options.seed);

  KDL::ChainFkSolverPos_recursive fk(chain);
  KDL::ChainIkSolverVel_pinv vik(chain);
  KDL::ChainIkSolverPos_NR_JL nr_jl(chain, lower, upper, fk, vik, 1, eps);
  Eigen::Matrix<double, 6, 1> weights = Eigen::Matrix<double, 6, 1>::Ones();
  KDL::ChainIkSolverPos_LMA lma(chain, weights, eps, 500, 1e-15);

  using Solver =
      std::function<std::pair<bool, int>(const Eigen::VectorXd&, const Eigen::Isometry3d&, Eigen::VectorXd&)>;
  const auto toKdl = [](const Eigen::Isometry3d& T) {
    KDL::Frame f;
    for (int r = 0; r < 3; ++r) {
      f.p(r) = T.translation()[r];
      for (int c = 0; c < 3; ++c) f.M(r, c) = T.linear()(r, c);
    }
    return f;
  };
  // KDL solvers looped from their last result until success or the budget, as TRAC-IK's test does.
  const auto kdlLoop = [&](KDL::ChainIkSolverPos& solver) -> Solver {
    return
        [&solver, &toKdl, n, budget](const Eigen::VectorXd& seed, const Eigen::Isometry3d& target, Eigen::VectorXd& q) {
          KDL::JntArray in(n), result(n);
          result.data = seed;
          const KDL::Frame goal = toKdl(target);
          const auto start = Clock::now();
          int calls = 0, rc = -1;
          do {
            in = result;
            rc = solver.CartToJnt(in, goal, result);
            ++calls;
          } while (rc < 0 && std::chrono::duration<double>(Clock::now() - start).count() < budget);
          q = result.data;
          return std::make_pair(rc >= 0, calls);
        };
  };
  std::vector<std::tuple<std::string, std::string, Solver>> solvers;
  std::vector<std::unique_ptr<bk::GlobalIkSolver>> ours;
  // The service default (GlobalIkParameters{}), then single local methods, each restarted within the budget.
  for (const std::string& method : {std::string("default"), std::string("ED"), std::string("SVF+ED"), std::string("JD"),
                                    std::string("CTP+SD+SVF")}) {
    bk::GlobalIkParameters parameters;
    if (method != "default" && !bk::parseMethodName(method, parameters.local.inverse, parameters.local.limits)) {
      throw std::logic_error("unknown method " + method);
    }
    parameters.timeout = budget;
    parameters.seed = options.seed;
    const std::string label =
        "global " +
        (method == "default"
             ? "default (" + std::string(bk::methodName(parameters.local.inverse, parameters.local.limits)) + ")"
             : method);
    ours.push_back(std::make_unique<bk::GlobalIkSolver>(model, parameters));
    bk::GlobalIkSolver* solver = ours.back().get();
    solvers.emplace_back("ours", label,
                         [solver](const Eigen::VectorXd& seed, const Eigen::Isometry3d& target, Eigen::VectorXd& q) {
                           const bk::GlobalIkResult result = solver->solve(target, seed, q);
                           return std::make_pair(result.status == bk::IkStatus::Converged, result.iterations);
                         });
  }
  solvers.emplace_back("KDL", "NR_JL", kdlLoop(nr_jl));
  solvers.emplace_back("KDL", "LMA", kdlLoop(lma));

  bk::ChainData check(model);
  for (const auto& [solver_name, label, solve] : solvers) {
    for (const bool random_seed : {false, true}) {
      const std::string setting = label + (random_seed ? " / random seed" : " / nominal seed");
      Recorder recorder(csv, "tracik", solver_name, setting);
      Eigen::VectorXd q(model.nq());
      for (int k = 0; k < samples; ++k) {
        const Eigen::VectorXd& seed = random_seed ? random_seeds[static_cast<std::size_t>(k)] : nominal;
        const auto t0 = Clock::now();
        const auto [reported, iterations] = solve(seed, targets[static_cast<std::size_t>(k)], q);
        const double us = std::chrono::duration<double, std::micro>(Clock::now() - t0).count();
        // Success is judged here, independently of what the solver reports.
        (void)reported;
        const bool fk_ok = bk::forwardKinematics(model, check, q) == bk::KinematicsStatus::Success;
        const bool success = fk_ok && twistWithin(check.tipPose(), targets[static_cast<std::size_t>(k)], eps);
        Eigen::VectorXd e(6);
        bk::poseError(check.tipPose(), targets[static_cast<std::size_t>(k)], bk::TaskMode::Pose, e);
        recorder.add(success, success && model.withinLimits(q), us, iterations, e.cwiseAbs().maxCoeff());
        if ((k + 1) % (samples / 4) == 0 && k + 1 < samples) {
          std::printf("    %s %s: %d/%d\n", solver_name.c_str(), setting.c_str(), k + 1, samples);
          std::fflush(stdout);
        }
      }
      Summary summary = recorder.finish();
      summary.robot = arm.name();
      out.push_back(summary);
    }
  }
}

/// Percentile f ∈ [0, 1] of sorted values.
double percentile(const std::vector<double>& sorted, double f) {
  return sorted.empty() ? 0.0 : sorted[static_cast<std::size_t>(f * static_cast<double>(sorted.size() - 1))];
}

void closest(const Options& options, const Arm& arm, std::vector<Summary>& out) {
  // How close mode `closest` (and, for comparison, `first`) gets to the seed, against the closest solution found by
  // a long AllDistinct search from the same seed (100 ms) and the configuration the target came from. Seeds are the
  // goal configurations moved by up to ±A per joint (clamped into the limits): the seed is the current
  // configuration of a smooth motion, the target a nearby pose.
  const bk::ChainModel model = bk::ChainModel::fromUrdfFile(arm.urdf, arm.base, arm.tip);
  const int samples = options.quick ? 20 : 1000;
  std::ofstream csv = openCsv(options, "closest", "robot,mode,A,sample,distance,best_distance,excess");
  std::printf("closest: %s, %d targets, seeds within +-A of the goal configuration (seed %u)\n", arm.name().c_str(),
              samples, options.seed);
  const auto solverFor = [&](bk::SolutionMode mode, double timeout) {
    bk::GlobalIkParameters parameters;
    parameters.mode = mode;
    parameters.timeout = timeout;
    parameters.seed = options.seed;
    return std::make_unique<bk::GlobalIkSolver>(model, parameters);
  };
  const auto first = solverFor(bk::SolutionMode::FirstFound, 0.005);
  const auto nearest = solverFor(bk::SolutionMode::ClosestToSeed, 0.005);
  const auto all = solverFor(bk::SolutionMode::AllDistinct, options.quick ? 0.02 : 0.1);
  for (const double A : {0.1, 0.3}) {
    std::mt19937 rng(options.seed);
    std::vector<double> excess_first, excess_closest;
    int best_first = 0, best_closest = 0, failures = 0;
    for (int k = 0; k < samples; ++k) {
      const Eigen::VectorXd goal = bk::randomWithinLimits(model, rng);
      const Eigen::VectorXd seed = uniformNear(model, goal, A, rng);
      const Eigen::Isometry3d target = forward(model, {goal}).front();
      Eigen::VectorXd q(model.nq());
      // The reference: the nearest of every solution a long search finds, and of the goal itself.
      double best = (goal - seed).norm();
      if (all->solve(target, seed, q).status == bk::IkStatus::Converged) {
        for (int s = 0; s < all->solutionCount(); ++s) best = std::min(best, (all->solution(s) - seed).norm());
      }
      for (auto [solver, excess, at_best, mode] :
           {std::tuple{first.get(), &excess_first, &best_first, "first"},
            std::tuple{nearest.get(), &excess_closest, &best_closest, "closest"}}) {
        if (solver->solve(target, seed, q).status != bk::IkStatus::Converged) {
          ++failures;
          continue;
        }
        const double distance = (q - seed).norm();
        const double e = std::max(0.0, distance - best);
        excess->push_back(e);
        if (e <= 1e-6) ++*at_best;
        csv << arm.name() << ',' << mode << ',' << A << ',' << k << ',' << distance << ',' << best << ',' << e << '\n';
      }
    }
    for (auto [mode, excess, at_best] :
         {std::tuple{"first", &excess_first, best_first}, std::tuple{"closest", &excess_closest, best_closest}}) {
      std::sort(excess->begin(), excess->end());
      Summary s;
      s.experiment = "closest";
      s.solver = "ours";
      s.setting = std::string(mode) + " / A=" + std::to_string(A).substr(0, 3);
      s.samples = static_cast<int>(excess->size());
      s.robot = arm.name();
      s.success_rate = static_cast<double>(excess->size()) / samples;
      s.extra = {{"A", A},
                 {"fraction_at_best", static_cast<double>(at_best) / std::max<std::size_t>(1, excess->size())},
                 {"excess_median_rad", percentile(*excess, 0.5)},
                 {"excess_p90_rad", percentile(*excess, 0.9)},
                 {"excess_p99_rad", percentile(*excess, 0.99)},
                 {"excess_max_rad", excess->empty() ? 0.0 : excess->back()}};
      std::printf("  %-8s A=%.1f: %d solved, at the best %.1f %%, excess median %.4f p90 %.4f p99 %.4f max %.4f rad\n",
                  mode, A, s.samples, 100.0 * s.extra[1].second, s.extra[2].second, s.extra[3].second,
                  s.extra[4].second, s.extra[5].second);
      out.push_back(s);
    }
    csv.flush();
    if (failures > 0) std::printf("  (%d solves of %d failed within 5 ms)\n", failures, 2 * samples);
  }
}

void writeSummary(const Options& options, const std::vector<Summary>& rows) {
  std::vector<bimanual_skills::bench::JsonRow> json;
  for (const Summary& r : rows) {
    json.emplace_back()
        .add("experiment", r.experiment)
        .add("solver", r.solver)
        .add("setting", r.setting)
        .add("samples", r.samples)
        .add("success_rate", r.success_rate)
        .add("within_limits_rate", r.within_limits_rate)
        .add("median_us", r.median_us)
        .add("p99_us", r.p99_us)
        .add("mean_iterations", r.mean_iterations)
        .add("mean_residual_failed", r.mean_residual_failed)
        .add("robot", r.robot);
    for (const auto& [key, value] : r.extra) json.back().add(key, value);
  }
  bimanual_skills::bench::writeSummaryJson(options, "ik_benchmark", json);
}

}  // namespace

int main(int argc, char** argv) {
  bimanual_skills::cli::pinNumerics(argv);
  Arm arm;
  bimanual_skills::bench::ExperimentProgram program;
  program.name = "ik_benchmark";
  program.description =
      "The thesis' inverse-kinematics experiments (Ch. 3.1: Tables 3.4, 3.5, Figs. 3.2-3.5) on the WAM, TRAC-IK's\n"
      "protocol against KDL's solvers (tracik) and the distance of mode closest's answers to the seed (closest).\n"
      "Writes DIR/<experiment>.csv as samples complete, DIR/summary.json, PNG plots and DIR/tables.md.";
  program.experiments = {"table34", "table35", "fig35", "fig32", "fig33", "tracik", "closest", "all"};
  program.extra = [&arm](bimanual_skills::cli::CommandLine& line) {
    line.option("--urdf", "FILE", "robot description of tracik and closest (default: urdf/wam.urdf)", &arm.urdf);
    line.option("--base", "LINK", "base link of the chain (default: wam_base)", &arm.base);
    line.option("--tip", "LINK", "tip link of the chain (default: wam_tool)", &arm.tip);
  };
  const Options options = bimanual_skills::bench::parseExperimentOptions(argc, argv, program);
  try {
    if (arm.urdf.empty()) arm.urdf = wamUrdf();
    std::filesystem::create_directories(options.out);
    std::printf("ik_benchmark: experiment %s, seed %u%s, output %s\n", options.experiment.c_str(), options.seed,
                options.quick ? " (quick)" : "", options.out.c_str());
    std::vector<Summary> rows;
    const auto wants = [&](const char* name) { return options.experiment == "all" || options.experiment == name; };
    if (wants("fig32")) fig32(options, rows);
    if (wants("fig33")) fig33(options, rows);
    if (wants("table34")) table34(options, rows);
    if (wants("table35")) limitExperiment(options, "table35", {1.0}, rows);
    if (wants("fig35")) {
      std::vector<double> amplitudes;
      for (double A = 0.25; A <= 2.5 + 1e-9; A += 0.25) amplitudes.push_back(A);
      limitExperiment(options, "fig35", amplitudes, rows);
    }
    if (wants("tracik")) tracik(options, arm, rows);
    if (wants("closest")) closest(options, arm, rows);
    writeSummary(options, rows);
    if (!bimanual_skills::bench::runPlotScript("ik_benchmark", "plot_ik_benchmark.py", options.out)) {
      return 1;
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "ik_benchmark: %s\n", e.what());
    return 1;
  }
  return 0;
}

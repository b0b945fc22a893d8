// CLIK inverse kinematics: operators against their closed forms, the continuous pseudoinverse against a brute-force
// power-set sum, convergence on the WAM, bad input, and allocation-free steps for every method.
#include "bimanual_skills/kinematics/clik.hpp"
#include "test_support.hpp"
#include "testing/no_alloc_guard.hpp"

#include <gtest/gtest.h>
#include <Eigen/Dense>

#include <cmath>
#include <random>
#include <set>
#include <string>
#include <vector>

namespace bk = bimanual_skills::kinematics;
using bimanual_skills::testing::NoAllocGuard;
using bk::InverseOperator;
using bk::LimitScheme;

using bimanual_skills::test_support::randomWithinLimits;
using bimanual_skills::test_support::tipPose;
using bimanual_skills::test_support::wam;

namespace {

constexpr unsigned kSeed = 31415;

Eigen::MatrixXd pinv(const Eigen::MatrixXd& A) {
  return A.completeOrthogonalDecomposition().pseudoInverse();
}

/// (3.22) summed over the whole power set, as written: J_Q = J H0_Q with the other columns zeroed.
Eigen::MatrixXd bruteForceContinuousPinv(const Eigen::MatrixXd& J, const Eigen::VectorXd& a) {
  const int n = static_cast<int>(J.cols());
  Eigen::MatrixXd sum = Eigen::MatrixXd::Zero(n, J.rows());
  for (unsigned mask = 0; mask < (1U << n); ++mask) {
    double weight = 1.0;
    Eigen::MatrixXd JQ = J;
    for (int i = 0; i < n; ++i) {
      if (mask & (1U << i)) {
        weight *= a[i];
      } else {
        weight *= 1.0 - a[i];
        JQ.col(i).setZero();
      }
    }
    if (weight != 0.0) sum += weight * pinv(JQ);
  }
  return sum;
}

}  // namespace

TEST(ContinuousPseudoinverse, EqualsBruteForcePowerSetSum) {
  const bk::ChainModel model = wam();
  bk::ClikParameters parameters;
  bk::ClikData data(model, parameters);
  std::mt19937 rng(kSeed);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  Eigen::MatrixXd ours(7, 6);
  double worst = 0.0;
  for (int trial = 0; trial < 40; ++trial) {
    const Eigen::MatrixXd J = Eigen::MatrixXd::NullaryExpr(6, 7, [&] { return 2.0 * unit(rng) - 1.0; });
    Eigen::VectorXd a(7);
    for (int i = 0; i < 7; ++i) {
      const double u = unit(rng);
      // Mix fully active, inactive and transitional joints; trial 0 has all seven in transition (2^7 terms).
      a[i] = trial == 0 ? 0.05 + 0.9 * u : (u < 0.3 ? 1.0 : u < 0.45 ? 0.0 : unit(rng));
    }
    bk::continuousPseudoinverse(parameters, data, J, a, InverseOperator::Pseudoinverse, 0.0, ours);
    worst = std::max(worst, (ours - bruteForceContinuousPinv(J, a)).cwiseAbs().maxCoeff());
  }
  EXPECT_LE(worst, 1e-9);
}

TEST(ContinuousPseudoinverse, IsContinuousInTheActivation) {
  const bk::ChainModel model = wam();
  bk::ClikParameters parameters;
  bk::ClikData data(model, parameters);
  std::mt19937 rng(kSeed + 1);
  const Eigen::MatrixXd J = Eigen::MatrixXd::Random(6, 7);
  Eigen::VectorXd a = Eigen::VectorXd::Ones(7);
  Eigen::MatrixXd at_one(7, 6), near_one(7, 6), near_zero(7, 6), at_zero(7, 6);
  bk::continuousPseudoinverse(parameters, data, J, a, InverseOperator::Pseudoinverse, 0.0, at_one);
  a[2] = 1.0 - 1e-7;
  bk::continuousPseudoinverse(parameters, data, J, a, InverseOperator::Pseudoinverse, 0.0, near_one);
  a[2] = 1e-7;
  bk::continuousPseudoinverse(parameters, data, J, a, InverseOperator::Pseudoinverse, 0.0, near_zero);
  a[2] = 0.0;
  bk::continuousPseudoinverse(parameters, data, J, a, InverseOperator::Pseudoinverse, 0.0, at_zero);
  EXPECT_LE((at_one - near_one).norm(), 1e-5);
  EXPECT_LE((at_zero - near_zero).norm(), 1e-5);
  EXPECT_TRUE(at_zero.row(2).isZero(0.0));  // a deactivated joint does not move
  // The ordinary pseudoinverse jumps as soon as a_i leaves 0 (Theorem 4.2 of Mansard et al.): this one does not.
  EXPECT_GT((pinv(J) - at_zero).norm(), 1e-2);
}

TEST(InverseOperators, StepsEqualTheirClosedForms) {
  const bk::ChainModel model = wam();
  std::mt19937 rng(kSeed + 2);
  const Eigen::VectorXd q = randomWithinLimits(model, rng);
  const Eigen::Isometry3d target = tipPose(model, randomWithinLimits(model, rng));
  bk::ClikParameters parameters;
  parameters.limits = LimitScheme::None;
  parameters.pinv_tolerance = 0.0;
  const auto stepOf = [&](InverseOperator op) {
    parameters.inverse = op;
    bk::ClikData data(model, parameters);
    EXPECT_EQ(bk::step(model, parameters, data, q, target), bk::IkStatus::StepComputed);
    return std::make_tuple(Eigen::VectorXd(data.dq), Eigen::MatrixXd(data.jacobian), Eigen::VectorXd(data.task));
  };
  const auto [dq_jp, J, e] = stepOf(InverseOperator::Pseudoinverse);
  const double E = 0.5 * e.squaredNorm();
  const Eigen::MatrixXd JJt = J * J.transpose();
  const Eigen::MatrixXd I = Eigen::MatrixXd::Identity(6, 6);
  EXPECT_LE((dq_jp - pinv(J) * e).norm(), 1e-9);
  const Eigen::VectorXd Jte = J.transpose() * e;
  const Eigen::VectorXd JJte = J * Jte;
  EXPECT_LE((std::get<0>(stepOf(InverseOperator::Transpose)) - e.dot(JJte) / JJte.squaredNorm() * Jte).norm(), 1e-12);
  const double l2 = parameters.lambda * parameters.lambda;
  EXPECT_LE((std::get<0>(stepOf(InverseOperator::Damping)) - J.transpose() * (JJt + l2 * I).inverse() * e).norm(),
            1e-9);
  EXPECT_LE((std::get<0>(stepOf(InverseOperator::ErrorDamping)) - J.transpose() * (JJt + E * I).inverse() * e).norm(),
            1e-9);
  EXPECT_LE((std::get<0>(stepOf(InverseOperator::ImprovedErrorDamping)) -
             J.transpose() * (JJt + (E + parameters.ied_omega) * I).inverse() * e)
                .norm(),
            1e-9);
  // SD and SVF+SD never move a joint by more than γ_max.
  EXPECT_LE(std::get<0>(stepOf(InverseOperator::SelectiveDamping)).cwiseAbs().maxCoeff(), parameters.gamma_max + 1e-12);
  EXPECT_LE(std::get<0>(stepOf(InverseOperator::SvfSelectiveDamping)).cwiseAbs().maxCoeff(),
            parameters.gamma_max + 1e-12);
}

TEST(InverseOperators, SingularValueFilterBoundsTheConditionNumber) {
  // At the straight-up singularity JP's gain explodes; SVF's stays below 1/σ0 (3.14).
  const bk::ChainModel model = wam();
  bk::ClikParameters parameters;
  parameters.limits = LimitScheme::None;
  Eigen::VectorXd q = Eigen::VectorXd::Zero(7);
  q[1] = 1e-9;
  Eigen::Isometry3d target = tipPose(model, q);
  target.translation().x() += 0.01;
  parameters.inverse = InverseOperator::SingularValueFilter;
  bk::ClikData data(model, parameters);
  ASSERT_EQ(bk::step(model, parameters, data, q, target), bk::IkStatus::StepComputed);
  // The configuration is singular enough that JP's largest gain 1/σ_min would be 100× SVF's bound 1/σ0 ...
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(data.jacobian);
  EXPECT_LT(svd.singularValues().minCoeff(), parameters.sigma0 / 100.0);
  // ... while every SVF gain 1/h(σ) stays below 1/σ0 (h(σ) ≥ σ0, 3.11), so the step is bounded by ‖e‖/σ0.
  EXPECT_LE(data.dq.norm(), data.task.norm() / parameters.sigma0 * (1.0 + 1e-9));
  EXPECT_TRUE(data.dq.allFinite());
}

TEST(Clik, LimitActivationIsZeroFarOneAtLimitsAndMonotone) {
  EXPECT_EQ(bk::limitActivation(0.0, -1.0, 1.0, 0.2), 0.0);
  EXPECT_EQ(bk::limitActivation(0.8, -1.0, 1.0, 0.2), 0.0);
  EXPECT_EQ(bk::limitActivation(1.0, -1.0, 1.0, 0.2), 1.0);
  EXPECT_EQ(bk::limitActivation(-1.5, -1.0, 1.0, 0.2), 1.0);
  EXPECT_EQ(bk::limitActivation(5.0, -INFINITY, INFINITY, 0.2), 0.0);
  double previous = 0.0;
  for (double q = 0.8; q <= 1.0; q += 0.001) {
    const double h = bk::limitActivation(q, -1.0, 1.0, 0.2);
    EXPECT_GE(h, previous - 1e-15);
    previous = h;
  }
}

TEST(Clik, EveryMethodConvergesOnNearbyTargets) {
  // Goals within 0.3 rad per joint of the start, both at least 0.3 rad from every limit: every method but JT (whose
  // linear rate makes it slow, thesis Table 3.4: 40.7 %) should get there.
  const bk::ChainModel model = wam();
  std::mt19937 rng(kSeed + 3);
  std::uniform_real_distribution<double> offset(-0.3, 0.3);
  std::vector<std::pair<Eigen::VectorXd, Eigen::Isometry3d>> problems;
  while (problems.size() < 30) {
    const Eigen::VectorXd q0 = randomWithinLimits(model, rng);
    Eigen::VectorXd q1 = q0;
    for (int i = 0; i < 7; ++i) q1[i] += offset(rng);
    if (!model.withinLimits(q1, -0.3) || !model.withinLimits(q0, -0.3)) continue;
    problems.emplace_back(q0, tipPose(model, q1));
  }
  for (LimitScheme scheme : bk::kLimitSchemes) {
    for (InverseOperator op : bk::kInverseOperators) {
      if ((scheme != LimitScheme::None && scheme != LimitScheme::ContinuousTaskPriority &&
           op != InverseOperator::Pseudoinverse) ||
          (scheme == LimitScheme::ContinuousTaskPriority && op == InverseOperator::Transpose)) {
        continue;  // the thesis pairs JW, GP, JC, TA and TP with the pseudoinverse; CTP+JT is rejected
      }
      bk::ClikParameters parameters;
      parameters.inverse = op;
      parameters.limits = scheme;
      parameters.max_iterations = 2000;
      bk::ClikData data(model, parameters);
      int converged = 0;
      for (const auto& [q0, target] : problems) {
        Eigen::VectorXd q = q0;
        const bk::IkResult result = bk::solve(model, parameters, data, q, target);
        if (op == InverseOperator::Transpose) {
          // JT converges slowly: where it has not converged it must at least have halved the initial error.
          Eigen::VectorXd initial_error(6);
          bk::poseError(tipPose(model, q0), target, bk::TaskMode::Pose, initial_error);
          EXPECT_LT(result.residual, 0.5 * initial_error.cwiseAbs().maxCoeff()) << bk::methodName(op, scheme);
        }
        if (result.status == bk::IkStatus::Converged) {
          ++converged;
          EXPECT_LE((tipPose(model, q).translation() - target.translation()).cwiseAbs().maxCoeff(), 1e-5);
        }
      }
      // From a start 0.3 rad from the solution every method mostly succeeds (measured: 29 or 30 of 30 each, TP
      // included, whose discontinuity shows on Table 3.5's wider problems; JT 22 of 30 within the 2000 iterations).
      const int needed = op == InverseOperator::Transpose ? 20 : 27;
      EXPECT_GE(converged, needed) << bk::methodName(op, scheme) << ": " << converged << "/30";
    }
  }
}

TEST(Clik, PositionOnlyModeIgnoresOrientation) {
  const bk::ChainModel model = wam();
  bk::ClikParameters parameters;
  parameters.mode = bk::TaskMode::Position;
  bk::ClikData data(model, parameters);
  std::mt19937 rng(kSeed + 4);
  Eigen::VectorXd q = randomWithinLimits(model, rng);
  Eigen::Isometry3d target = tipPose(model, q);
  target.translation() += Eigen::Vector3d(0.05, -0.03, 0.02);
  target.linear() = Eigen::AngleAxisd(1.0, Eigen::Vector3d::UnitX()).toRotationMatrix() * target.linear();
  const bk::IkResult result = bk::solve(model, parameters, data, q, target);
  ASSERT_EQ(result.status, bk::IkStatus::Converged) << bk::toString(result.status);
  EXPECT_LE((tipPose(model, q).translation() - target.translation()).norm(), 2e-5);
  EXPECT_EQ(data.error.size(), 3);
}

TEST(Clik, BadInputIsAStatus) {
  const bk::ChainModel model = wam();
  bk::ClikParameters parameters;
  bk::ClikData data(model, parameters);
  Eigen::VectorXd q = Eigen::VectorXd::Zero(7);
  Eigen::Isometry3d target = Eigen::Isometry3d::Identity();
  target.translation().x() = std::nan("");
  EXPECT_EQ(bk::step(model, parameters, data, q, target), bk::IkStatus::InvalidInput);
  EXPECT_EQ(bk::solve(model, parameters, data, q, target).status, bk::IkStatus::InvalidInput);
  target.translation().x() = 0.3;
  Eigen::VectorXd wrong = Eigen::VectorXd::Zero(5);
  EXPECT_EQ(bk::solve(model, parameters, data, wrong, target).status, bk::IkStatus::InvalidInput);
  q[0] = INFINITY;
  EXPECT_EQ(bk::step(model, parameters, data, q, target), bk::IkStatus::InvalidInput);
}

TEST(Clik, UnreachableTargetEndsAtTheIterationCapWithItsResidual) {
  const bk::ChainModel model = wam();
  bk::ClikParameters parameters;
  parameters.max_iterations = 200;
  bk::ClikData data(model, parameters);
  Eigen::VectorXd q = Eigen::VectorXd::Constant(7, 0.2);
  Eigen::Isometry3d target = Eigen::Isometry3d::Identity();
  target.translation() << 3.0, 0.0, 1.0;  // 3 m away: out of reach
  const bk::IkResult result = bk::solve(model, parameters, data, q, target);
  EXPECT_EQ(result.status, bk::IkStatus::MaxIterations);
  EXPECT_EQ(result.iterations, 200);
  EXPECT_GT(result.residual, 1.0);
  EXPECT_TRUE(q.allFinite());
  parameters.timeout = 1e-9;
  parameters.max_iterations = 1000000;
  EXPECT_EQ(bk::solve(model, parameters, data, q, target).status, bk::IkStatus::Timeout);
}

TEST(Clik, InvalidParametersAreRejectedAtInit) {
  const bk::ChainModel model = wam();
  bk::ClikParameters parameters;
  parameters.nu = 500.0;  // violates ν σ0 < 2 (3.11)
  EXPECT_THROW(bk::ClikData(model, parameters), std::invalid_argument);
  parameters = bk::ClikParameters();
  parameters.tolerance = -1.0;
  EXPECT_THROW(parameters.validate(), std::invalid_argument);
  parameters = bk::ClikParameters();
  parameters.inverse = InverseOperator::Transpose;
  EXPECT_THROW(parameters.validate(), std::invalid_argument);  // with CTP, the default scheme
}

TEST(Clik, StepAndSolveDoNotAllocateForAnyMethod) {
  const bk::ChainModel model = wam();
  std::mt19937 rng(kSeed + 5);
  Eigen::VectorXd q0 = randomWithinLimits(model, rng);
  q0[3] = model.upperLimits()[3] - 0.05;  // one joint in its activation buffer
  q0[5] = model.lowerLimits()[5] + 0.1;   // and another: the continuous pseudoinverse branches
  const Eigen::Isometry3d target = tipPose(model, randomWithinLimits(model, rng));
  for (bk::TaskMode mode : {bk::TaskMode::Pose, bk::TaskMode::Position}) {
    for (LimitScheme scheme : bk::kLimitSchemes) {
      for (InverseOperator op : bk::kInverseOperators) {
        if (scheme == LimitScheme::ContinuousTaskPriority && op == InverseOperator::Transpose) continue;
        bk::ClikParameters parameters;
        parameters.inverse = op;
        parameters.limits = scheme;
        parameters.mode = mode;
        parameters.max_iterations = 20;
        bk::ClikData data(model, parameters);
        Eigen::VectorXd q = q0;
        bk::IkStatus status;
        bk::IkResult result;
        {
          NoAllocGuard guard;
          status = bk::step(model, parameters, data, q, target);
          result = bk::solve(model, parameters, data, q, target);
        }
        EXPECT_NE(status, bk::IkStatus::NumericalFailure) << bk::methodName(op, scheme);
        EXPECT_NE(result.status, bk::IkStatus::InvalidInput) << bk::methodName(op, scheme);
      }
    }
  }
}

TEST(Clik, MethodNamesRoundTrip) {
  int parsed = 0;
  for (LimitScheme scheme : bk::kLimitSchemes) {
    for (InverseOperator op : bk::kInverseOperators) {
      InverseOperator op_back;
      LimitScheme scheme_back;
      const std::string name = bk::methodName(op, scheme);
      if (name == "CTP+other") continue;
      ASSERT_TRUE(bk::parseMethodName(name, op_back, scheme_back)) << name;
      EXPECT_EQ(bk::methodName(op_back, scheme_back), name);
      ++parsed;
    }
  }
  EXPECT_GE(parsed, 19);
  // methodNames() lists exactly the distinct names that parse (the 19 of the thesis' tables), each once.
  std::set<std::string> distinct;
  for (LimitScheme scheme : bk::kLimitSchemes) {
    for (InverseOperator op : bk::kInverseOperators) {
      InverseOperator op_back;
      LimitScheme scheme_back;
      const std::string name = bk::methodName(op, scheme);
      if (name != "CTP+other" && bk::parseMethodName(name, op_back, scheme_back)) distinct.insert(name);
    }
  }
  const std::set<std::string> listed(bk::methodNames().begin(), bk::methodNames().end());
  EXPECT_EQ(listed.size(), bk::methodNames().size());
  EXPECT_EQ(listed, distinct);
  InverseOperator op;
  LimitScheme scheme;
  EXPECT_FALSE(bk::parseMethodName("SVF+XX", op, scheme));
  EXPECT_TRUE(bk::parseMethodName("CTP+SD+SVF", op, scheme));
  EXPECT_EQ(op, InverseOperator::SvfSelectiveDamping);
  EXPECT_EQ(scheme, LimitScheme::ContinuousTaskPriority);
}

namespace {

/// (3.29)-(3.40) written out with Eigen's own SVD of J^⊕ = data.inverse, from the state a step leaves in data.
Eigen::VectorXd referenceCtpSdStep(const bk::ClikParameters& p, const bk::ClikData& data, const Eigen::VectorXd& q,
                                   const bk::ChainModel& model) {
  const int n = model.nq();
  Eigen::VectorXd h(n), centre(n);
  for (int i = 0; i < n; ++i) {
    h[i] = bk::limitActivation(q[i], model.lowerLimits()[i], model.upperLimits()[i], p.beta);
    centre[i] = 0.5 * (model.lowerLimits()[i] + model.upperLimits()[i]);
  }
  const Eigen::VectorXd dq1 = -p.lambda_jl * h.cwiseProduct(q - centre);
  const Eigen::MatrixXd& Jp = data.inverse;
  const Eigen::MatrixXd& J = data.jacobian;
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(Jp, Eigen::ComputeThinU | Eigen::ComputeThinV);
  Eigen::VectorXd sum = Eigen::VectorXd::Zero(n);
  for (int s = 0; s < svd.singularValues().size(); ++s) {
    const double tau = svd.singularValues()[s];
    if (tau == 0.0) continue;
    Eigen::VectorXd w = tau * svd.matrixU().col(s) * svd.matrixV().col(s).dot(data.task);  // (3.37)
    double M = 0.0;                                                                        // (3.35)
    for (int j = 0; j < n; ++j) M += tau * std::abs(svd.matrixU()(j, s)) * J.col(j).norm();
    const double gamma = std::min(1.0, 1.0 / M) * p.gamma_max;                  // (3.36)
    if (w.cwiseAbs().maxCoeff() > gamma) w *= gamma / w.cwiseAbs().maxCoeff();  // (3.38)
    sum += w;
  }
  Eigen::VectorXd dq = dq1 - Jp * (J * dq1) + sum;                                           // (3.39)
  if (dq.cwiseAbs().maxCoeff() > p.gamma_max) dq *= p.gamma_max / dq.cwiseAbs().maxCoeff();  // (3.40)
  return dq;
}

}  // namespace

TEST(Clik, CtpSelectiveDampingStepEqualsItsEquations) {
  const bk::ChainModel model = wam();
  std::mt19937 rng(kSeed + 6);
  for (InverseOperator op : {InverseOperator::SelectiveDamping, InverseOperator::SvfSelectiveDamping}) {
    bk::ClikParameters parameters;
    parameters.inverse = op;
    bk::ClikData data(model, parameters);
    for (int trial = 0; trial < 20; ++trial) {
      Eigen::VectorXd q = randomWithinLimits(model, rng);
      if (trial % 2 == 1) q[3] = model.upperLimits()[3] - 0.3 * parameters.beta;  // a joint in transition
      const Eigen::Isometry3d target = tipPose(model, randomWithinLimits(model, rng));
      ASSERT_EQ(bk::step(model, parameters, data, q, target), bk::IkStatus::StepComputed);
      EXPECT_LE((data.dq - referenceCtpSdStep(parameters, data, q, model)).cwiseAbs().maxCoeff(), 1e-10)
          << bk::methodName(op, LimitScheme::ContinuousTaskPriority) << " trial " << trial;
    }
  }
}

TEST(Clik, BetaScheduleReleasesGoalsNextToALimit) {
  // Goals whose elbow (joint 4) is 4 mm from its upper limit, deep inside the activation buffer.
  const bk::ChainModel model = wam();
  std::mt19937 rng(kSeed + 7);
  std::uniform_real_distribution<double> offset(-0.5, 0.5);
  bk::ClikParameters scheduled;
  bk::ClikParameters fixed = scheduled;
  fixed.beta_decay = 1.0;
  bk::ClikData data(model, scheduled);
  int solved_fixed = 0, solved_scheduled = 0, problems = 0;
  while (problems < 30) {
    Eigen::VectorXd goal = randomWithinLimits(model, rng);
    goal[3] = model.upperLimits()[3] - 0.004;
    Eigen::VectorXd start = goal;
    for (int i = 0; i < 7; ++i) start[i] += offset(rng);
    if (!model.withinLimits(start, -0.1)) continue;
    ++problems;
    const Eigen::Isometry3d target = tipPose(model, goal);
    for (auto [parameters, solved] : {std::pair{&fixed, &solved_fixed}, std::pair{&scheduled, &solved_scheduled}}) {
      Eigen::VectorXd q = start;
      const bk::IkResult result = bk::solve(model, *parameters, data, q, target);
      if (result.status == bk::IkStatus::Converged && model.withinLimits(q)) ++*solved;
    }
  }
  EXPECT_GE(solved_scheduled, 27) << "fixed beta: " << solved_fixed;
  std::printf("goals 4 mm from a limit: fixed beta %d/30, scheduled %d/30\n", solved_fixed, solved_scheduled);
  EXPECT_GT(solved_scheduled, solved_fixed);
}

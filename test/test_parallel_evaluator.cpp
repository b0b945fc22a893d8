// The rollout evaluator: the same results in request order on any number of threads, every request reported once,
// a task's exception and a stop request end a batch cleanly; the fold task's policy encoding round-trips.
#include "bimanual_skills/rollout/fold_rollout_task.hpp"
#include "bimanual_skills/rollout/parallel_evaluator.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <set>
#include <stdexcept>

namespace br = bimanual_skills::rollout;

namespace {

/// A deterministic toy task: the reward is a function of the parameters and the seed; a first parameter of −1
/// makes the program fault (an exception), a NaN a failed rollout.
class ToyTask : public br::RolloutTask {
 public:
  std::vector<std::string> termNames() const override { return {"square", "noise"}; }
  br::RolloutResult run(const Eigen::VectorXd& parameters, std::uint32_t seed) override {
    if (parameters.size() > 0 && parameters[0] == -1.0) throw std::logic_error("toy fault");
    br::RolloutResult r;
    if (!parameters.allFinite()) {
      r.ok = false;
      r.outcome = "InvalidPolicy";
      r.reason = "not finite";
      r.reward = -10.0;
      return r;
    }
    std::mt19937 rng(seed);
    const double noise = std::normal_distribution<double>(0.0, 0.1)(rng);
    r.terms = Eigen::Vector2d(parameters.squaredNorm(), noise);
    r.reward = -r.terms.sum();
    r.outcome = "Ok";
    ++runs;
    return r;
  }
  int runs = 0;
};

std::vector<br::RolloutRequest> batch(int n) {
  std::vector<br::RolloutRequest> out;
  std::mt19937 rng(4);
  std::normal_distribution<double> normal;
  for (int i = 0; i < n; ++i) {
    Eigen::VectorXd p(3);
    for (int j = 0; j < 3; ++j) p[j] = normal(rng);
    out.push_back({p, static_cast<std::uint32_t>(1000 + i)});
  }
  return out;
}

br::ParallelEvaluator::Factory toy() {
  return [] { return std::make_unique<ToyTask>(); };
}

}  // namespace

TEST(ParallelEvaluator, SameResultsInRequestOrderOnAnyThreads) {
  const std::vector<br::RolloutRequest> requests = batch(37);
  br::ParallelEvaluator serial(toy(), 1);
  const std::vector<br::RolloutResult> expected = serial.evaluate(requests);
  ASSERT_EQ(expected.size(), requests.size());
  for (const int threads : {2, 3, 8}) {
    br::ParallelEvaluator evaluator(toy(), threads);
    EXPECT_EQ(evaluator.threads(), threads);
    std::multiset<std::size_t> reported;
    const std::vector<br::RolloutResult> results =
        evaluator.evaluate(requests, [&](std::size_t i, const br::RolloutResult& r, br::RolloutTask&) {
          reported.insert(i);
          EXPECT_EQ(r.reward, expected[i].reward);
        });
    ASSERT_EQ(results.size(), requests.size());
    for (std::size_t i = 0; i < results.size(); ++i) {
      EXPECT_EQ(results[i].reward, expected[i].reward) << threads << " threads, request " << i;
      EXPECT_EQ(results[i].terms, expected[i].terms);
      EXPECT_EQ(reported.count(i), 1u) << "each request is reported exactly once";
    }
    int runs = 0;
    for (int t = 0; t < evaluator.threads(); ++t) runs += static_cast<ToyTask&>(evaluator.task(t)).runs;
    EXPECT_EQ(runs, 37) << "no rollout lost or run twice";
  }
  EXPECT_TRUE(serial.evaluate({}).empty());
  EXPECT_GE(br::ParallelEvaluator(toy(), 0).threads(), 1);
}

TEST(ParallelEvaluator, FailedRolloutsAreResultsAndFaultsAreExceptions) {
  std::vector<br::RolloutRequest> requests = batch(10);
  requests[3].parameters[1] = NAN;
  br::ParallelEvaluator evaluator(toy(), 2);
  const std::vector<br::RolloutResult> results = evaluator.evaluate(requests);
  EXPECT_FALSE(results[3].ok);
  EXPECT_EQ(results[3].reason, "not finite");
  EXPECT_TRUE(results[4].ok);

  requests[6].parameters[0] = -1.0;
  EXPECT_THROW(evaluator.evaluate(requests), std::logic_error);
  // The evaluator stays usable.
  EXPECT_EQ(evaluator.evaluate(batch(4)).size(), 4u);
}

TEST(ParallelEvaluator, StopEndsTheBatchAfterTheRunningRollouts) {
  br::ParallelEvaluator evaluator(toy(), 2);
  int done = 0;
  EXPECT_THROW(evaluator.evaluate(
                   batch(50), [&](std::size_t, const br::RolloutResult&, br::RolloutTask&) { ++done; },
                   [&] { return done >= 5; }),
               std::runtime_error);
  EXPECT_GE(done, 5);
  EXPECT_LT(done, 50);
}

TEST(ParallelEvaluator, BadConstruction) {
  EXPECT_THROW(br::ParallelEvaluator(toy(), -1), std::invalid_argument);
  EXPECT_THROW(br::ParallelEvaluator([] { return std::unique_ptr<br::RolloutTask>(); }, 2), std::invalid_argument);
}

TEST(FoldRolloutTask, PolicyEncodingRoundTrips) {
  const int dofs = 12, kernels = 20;
  std::mt19937 rng(2);
  std::normal_distribution<double> normal;
  for (const int matrices : {1, 3}) {
    for (const int r : {12, 5, 1}) {
      std::vector<Eigen::MatrixXd> omega;
      for (int s = 0; s < matrices; ++s) {
        Eigen::MatrixXd m(dofs, r);
        for (Eigen::Index i = 0; i < m.size(); ++i) m.data()[i] = normal(rng);
        omega.push_back(m);
      }
      Eigen::VectorXd w(r * kernels);
      for (Eigen::Index i = 0; i < w.size(); ++i) w[i] = normal(rng);
      const Eigen::VectorXd encoded = br::FoldRolloutTask::encode(omega, w);
      std::vector<Eigen::MatrixXd> decoded;
      Eigen::VectorXd weights;
      ASSERT_TRUE(br::FoldRolloutTask::decode(encoded, dofs, kernels, decoded, weights));
      EXPECT_EQ(weights, w);
      ASSERT_EQ(decoded.size(), omega.size());
      for (std::size_t s = 0; s < omega.size(); ++s) EXPECT_EQ(decoded[s], omega[s]);
      // Truncated, padded, or with a header that does not fit: refused.
      std::vector<Eigen::MatrixXd> unused;
      EXPECT_FALSE(br::FoldRolloutTask::decode(encoded.head(encoded.size() - 1), dofs, kernels, unused, weights));
      Eigen::VectorXd longer(encoded.size() + 1);
      longer << encoded, 0.0;
      EXPECT_FALSE(br::FoldRolloutTask::decode(longer, dofs, kernels, unused, weights));
      Eigen::VectorXd bad = encoded;
      bad[1] = 13;
      EXPECT_FALSE(br::FoldRolloutTask::decode(bad, dofs, kernels, unused, weights));
      bad[1] = NAN;
      EXPECT_FALSE(br::FoldRolloutTask::decode(bad, dofs, kernels, unused, weights));
    }
  }
  std::vector<Eigen::MatrixXd> unused;
  Eigen::VectorXd weights;
  EXPECT_FALSE(br::FoldRolloutTask::decode(Eigen::VectorXd(), dofs, kernels, unused, weights));
}

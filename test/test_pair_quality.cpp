// The pair quality of thesis Sec. 3.2.3: the factors (3.42)–(3.45) against hand-computed values, the placement
// quality (3.41) through the spatial index against the sum over every pair, its independence of the number of
// threads, and its invariance to moving both arms together.
#include "bimanual_skills/workspace/pair_quality.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace bw = bimanual_skills::workspace;

namespace {

bw::WorkspacePoint point(const Eigen::Vector3d& position, const Eigen::Vector3d& axis, double angle, double ratio,
                         double manipulability, double condition) {
  bw::WorkspacePoint p;
  p.position = position;
  p.tool.axis = axis.normalized();
  p.tool.angle = angle;
  p.solution_ratio = ratio;
  p.manipulability = manipulability;
  p.condition = condition;
  return p;
}

/// `n` points in a 1.2 m cube with random cones (angles up to 120°) and factors.
bw::WorkspacePoints randomPoints(int n, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0), coordinate(-0.6, 0.6);
  std::normal_distribution<double> normal;
  bw::WorkspacePoints w;
  w.resolution = 0.1;
  w.voxel_volume = 1e-3;
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3d position(coordinate(rng), coordinate(rng), coordinate(rng));
    const Eigen::Vector3d axis(normal(rng), normal(rng), normal(rng));
    w.points.push_back(point(position, axis, unit(rng) * 2.1, unit(rng), 0.2 * unit(rng), 1.0 + 20.0 * unit(rng)));
  }
  return w;
}

Eigen::Isometry3d pose(double x, double y, double z, double angle, const Eigen::Vector3d& axis) {
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  t.translate(Eigen::Vector3d(x, y, z));
  t.rotate(Eigen::AngleAxisd(angle, axis.normalized()));
  return t;
}

}  // namespace

TEST(PairQuality, FactorsMatchHandComputedValues) {
  const bw::PairQualitySettings s;  // L = 0.4, δ = 0.1, K = 2, OF_min = 0.1
  const double deg = M_PI / 180.0;
  // P2 0.4 m along x; cone 1 points at P2 (a1 = 0, α1 = 60°), cone 2 is 30° off the way back (a2 = 30°, α2 = 60°).
  const bw::WorkspacePoint p1 = point(Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitX(), 60 * deg, 0.5, 0.1, 2.0);
  const bw::WorkspacePoint p2 =
      point(Eigen::Vector3d(0.4, 0.0, 0.0), Eigen::Vector3d(-std::cos(30 * deg), std::sin(30 * deg), 0.0), 60 * deg,
            0.8, 0.2, 4.0);
  const bw::PairFactors f = bw::pairFactors(p1, p2, s);
  EXPECT_EQ(f.df, 1.0);
  EXPECT_NEAR(f.a1, 0.0, 1e-7);  // the angles come from a polynomial acos (within 2e-8 rad)
  EXPECT_NEAR(f.a2, 30 * deg, 1e-7);
  EXPECT_DOUBLE_EQ(f.sdf, 0.4);
  EXPECT_NEAR(f.of, 1.0 + std::log(0.5) / 2.0, 1e-7);  // 0.6534
  EXPECT_DOUBLE_EQ(f.mf, 0.02);
  EXPECT_DOUBLE_EQ(f.cf, 0.125);  // 1/2 · 1/4
  EXPECT_NEAR(f.product(), 0.4 * (1.0 + std::log(0.5) / 2.0) * 0.02 * 0.125, 1e-9);

  // Both directions 55° into 60° cones: ln((5/60)²)/2 = −2.48, so OF is held at OF_min.
  const bw::WorkspacePoint q1 = point(
      Eigen::Vector3d::Zero(), Eigen::Vector3d(std::cos(55 * deg), std::sin(55 * deg), 0), 60 * deg, 1.0, 1.0, 1.0);
  const bw::WorkspacePoint q2 =
      point(Eigen::Vector3d(0.4, 0.0, 0.0), Eigen::Vector3d(-std::cos(55 * deg), std::sin(55 * deg), 0), 60 * deg, 1.0,
            1.0, 1.0);
  EXPECT_DOUBLE_EQ(bw::pairFactors(q1, q2, s).of, 0.1);

  // DF = 0: too near, too far, or the line outside a cone (a2 = 30° > α2 = 20°).
  bw::WorkspacePoint near = p2, far = p2, narrow = p2;
  near.position.x() = 0.29;
  far.position.x() = 0.51;
  narrow.tool.angle = 20 * deg;
  for (const bw::WorkspacePoint& other : {near, far, narrow}) {
    const bw::PairFactors zero = bw::pairFactors(p1, other, s);
    EXPECT_EQ(zero.df, 0.0);
    EXPECT_EQ(zero.product(), 0.0);
  }
  bw::PairQualitySettings bad;
  bad.tolerance = 0.5;
  EXPECT_THROW(bw::pairFactors(p1, p2, bad), std::invalid_argument);
}

TEST(PairQuality, TheAnglesAreWithin1e7OfTheExactOnes) {
  // a1 for directions 0°…179.5° off cone 1's axis (a cone of 180° takes every one), against atan2.
  const bw::PairQualitySettings s;
  const bw::WorkspacePoint p1 = point(Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitX(), M_PI, 1.0, 1.0, 1.0);
  for (double degrees = 0.0; degrees < 180.0; degrees += 0.5) {
    const double angle = degrees * M_PI / 180.0;
    const Eigen::Vector3d direction(std::cos(angle), std::sin(angle), 0.0);
    const bw::WorkspacePoint p2 = point(0.4 * direction, -direction, M_PI, 1.0, 1.0, 1.0);
    const bw::PairFactors f = bw::pairFactors(p1, p2, s);
    ASSERT_EQ(f.df, 1.0) << degrees;
    EXPECT_NEAR(f.a1, std::atan2(std::sin(angle), std::cos(angle)), 1e-7) << degrees;
    EXPECT_NEAR(f.a2, 0.0, 1e-7) << degrees;
  }
}

TEST(PairQuality, TheIndexVisitsEveryPairInTheShellAndThreadsDoNotMatter) {
  const bw::WorkspacePoints first = randomPoints(600, 1), second = randomPoints(500, 2);
  bw::PairQualitySettings s;
  for (const Eigen::Isometry3d& second_base :
       {pose(0.3, 0.1, 0.0, 0.0, Eigen::Vector3d::UnitZ()), pose(0.5, -0.2, 0.4, 2.0, Eigen::Vector3d(1, 2, 3))}) {
    s.threads = 1;
    const bw::PlacementQuality indexed =
        bw::placementQuality(first, Eigen::Isometry3d::Identity(), second, second_base, s);
    const bw::PlacementQuality all =
        bw::bruteForcePlacementQuality(first, Eigen::Isometry3d::Identity(), second, second_base, s);
    ASSERT_GT(indexed.pairs, 100u);
    EXPECT_EQ(indexed.pairs, all.pairs);
    EXPECT_EQ(indexed.distance_pairs, all.distance_pairs);
    EXPECT_NEAR(indexed.pair_sum, all.pair_sum, 1e-12 * all.pair_sum);
    EXPECT_EQ(indexed.volume, all.volume);
    EXPECT_LT(indexed.visited, all.visited / 2) << "the index must skip most pairs";
    s.threads = 3;
    const bw::PlacementQuality threaded =
        bw::placementQuality(first, Eigen::Isometry3d::Identity(), second, second_base, s);
    EXPECT_EQ(threaded.pair_sum, indexed.pair_sum) << "bit for bit on any number of threads";
    EXPECT_EQ(threaded.quality, indexed.quality);
  }
}

TEST(PairQuality, MovingBothArmsTogetherChangesNothing) {
  const bw::WorkspacePoints first = randomPoints(400, 3), second = randomPoints(400, 4);
  const bw::PairQualitySettings s;
  const Eigen::Isometry3d a = pose(0.1, 0.0, 0.2, 0.3, Eigen::Vector3d::UnitY());
  const Eigen::Isometry3d b = pose(0.6, 0.2, 0.0, 1.5707963, Eigen::Vector3d::UnitX());
  const bw::PlacementQuality reference = bw::placementQuality(first, a, second, b, s);
  ASSERT_GT(reference.pairs, 0u);
  const Eigen::Isometry3d move = pose(-2.0, 5.0, 1.0, 2.5, Eigen::Vector3d(0.3, -1.0, 0.7));
  const bw::PlacementQuality moved = bw::placementQuality(first, move * a, second, move * b, s);
  EXPECT_EQ(moved.pairs, reference.pairs);
  EXPECT_NEAR(moved.pair_sum, reference.pair_sum, 1e-9 * reference.pair_sum);
  EXPECT_NEAR(moved.quality, reference.quality, 1e-9 * reference.quality);
  EXPECT_EQ(moved.volume, reference.volume);
}

TEST(PairQuality, TheVolumeIsTheUnionOfBothWorkspaces) {
  bw::WorkspacePoints w;
  w.resolution = 0.1;
  w.voxel_volume = 1e-3;
  for (int i = 0; i < 10; ++i) {
    w.points.push_back(point(Eigen::Vector3d(0.1 * i, 0, 0), Eigen::Vector3d::UnitZ(), 1.0, 1.0, 0.1, 1.0));
  }
  const bw::PairQualitySettings s;
  // The second arm shifted by 4 voxels along x: 6 of its 10 voxels coincide with the first's.
  const bw::PlacementQuality q =
      bw::placementQuality(w, Eigen::Isometry3d::Identity(), w, pose(0.4, 0, 0, 0, Eigen::Vector3d::UnitZ()), s);
  EXPECT_NEAR(q.volume, 14e-3, 1e-15);
  bw::WorkspacePoints broken = w;
  broken.points[3].condition = 0.5;
  EXPECT_THROW(bw::placementQuality(broken, Eigen::Isometry3d::Identity(), w, Eigen::Isometry3d::Identity(), s),
               std::invalid_argument);
}

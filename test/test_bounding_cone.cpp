// The minimal bounding cone (workspace/bounding_cone.hpp): it encloses every direction and is minimal, against
// the brute force over all cones through two or three directions on random sets (inside a hemisphere and not), and
// on sets with known answers (one direction, two, a ring around an axis, antipodes, the octahedron's six axes).
#include "bimanual_skills/workspace/bounding_cone.hpp"

#include <gtest/gtest.h>

#include <Eigen/Geometry>

#include <cmath>
#include <random>
#include <stdexcept>

namespace bw = bimanual_skills::workspace;

namespace {

/// `n` random directions within `spread` [rad] of `axis` (uniform on the cap).
std::vector<Eigen::Vector3d> cap(const Eigen::Vector3d& axis, double spread, int n, std::mt19937& rng) {
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  const Eigen::Quaterniond to_axis = Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitZ(), axis);
  std::vector<Eigen::Vector3d> out;
  for (int i = 0; i < n; ++i) {
    const double z = 1.0 - uniform(rng) * (1.0 - std::cos(spread)), phi = 2.0 * M_PI * uniform(rng);
    const double r = std::sqrt(std::max(0.0, 1.0 - z * z));
    out.push_back(to_axis * Eigen::Vector3d(r * std::cos(phi), r * std::sin(phi), z) * (0.5 + uniform(rng)));
  }
  return out;
}

void expectEncloses(const bw::BoundingCone& cone, const std::vector<Eigen::Vector3d>& directions) {
  EXPECT_NEAR(cone.axis.norm(), 1.0, 1e-12);
  for (const Eigen::Vector3d& d : directions) EXPECT_TRUE(cone.contains(d, 1e-9)) << d.transpose();
}

}  // namespace

TEST(BoundingCone, KnownSets) {
  const bw::BoundingCone one = bw::minimalBoundingCone({Eigen::Vector3d(0, 2, 0)});
  EXPECT_NEAR(one.angle, 0.0, 1e-12);
  EXPECT_NEAR((one.axis - Eigen::Vector3d::UnitY()).norm(), 0.0, 1e-12);

  const bw::BoundingCone two = bw::minimalBoundingCone({Eigen::Vector3d(1, 0, 0), Eigen::Vector3d(0, 1, 0)});
  EXPECT_NEAR(two.angle, M_PI / 4, 1e-12);
  EXPECT_NEAR((two.axis - Eigen::Vector3d(1, 1, 0).normalized()).norm(), 0.0, 1e-12);

  // A ring of directions at 40° around an axis, and the axis itself: the cone is the ring's.
  const Eigen::Vector3d axis = Eigen::Vector3d(1, -2, 0.5).normalized();
  const Eigen::Vector3d side = axis.unitOrthogonal(), third = axis.cross(side);
  std::vector<Eigen::Vector3d> ring = {axis};
  for (int k = 0; k < 12; ++k) {
    const double phi = 2.0 * M_PI * k / 12;
    ring.push_back(std::cos(0.7) * axis + std::sin(0.7) * (std::cos(phi) * side + std::sin(phi) * third));
  }
  const bw::BoundingCone r = bw::minimalBoundingCone(ring);
  EXPECT_NEAR(r.angle, 0.7, 1e-9);
  EXPECT_NEAR((r.axis - axis).norm(), 0.0, 1e-9);

  // Antipodes: a half-space. The octahedron's axes: no hemisphere holds them; by symmetry the cone is around a
  // diagonal, reaching the three negative axes at acos(−1/√3).
  EXPECT_NEAR(bw::minimalBoundingCone({Eigen::Vector3d::UnitX(), -Eigen::Vector3d::UnitX()}).angle, M_PI / 2, 1e-9);
  const std::vector<Eigen::Vector3d> octahedron = {Eigen::Vector3d::UnitX(), -Eigen::Vector3d::UnitX(),
                                                   Eigen::Vector3d::UnitY(), -Eigen::Vector3d::UnitY(),
                                                   Eigen::Vector3d::UnitZ(), -Eigen::Vector3d::UnitZ()};
  const bw::BoundingCone o = bw::minimalBoundingCone(octahedron);
  EXPECT_NEAR(o.angle, std::acos(-1.0 / std::sqrt(3.0)), 1e-9);
  expectEncloses(o, octahedron);
}

TEST(BoundingCone, EnclosesAllAndIsMinimalAgainstTheBruteForce) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> spread(0.05, 2.6);
  std::normal_distribution<double> normal;
  int wide = 0;
  for (int trial = 0; trial < 300; ++trial) {
    const Eigen::Vector3d axis = Eigen::Vector3d(normal(rng), normal(rng), normal(rng)).normalized();
    const double s = spread(rng);
    const std::vector<Eigen::Vector3d> d = cap(axis, s, 2 + trial % 14, rng);
    const bw::BoundingCone fast = bw::minimalBoundingCone(d, static_cast<std::uint32_t>(trial));
    const bw::BoundingCone slow = bw::bruteForceBoundingCone(d);
    expectEncloses(fast, d);
    expectEncloses(slow, d);
    EXPECT_NEAR(fast.angle, slow.angle, 1e-9) << "trial " << trial;
    EXPECT_LE(fast.angle, s + 1e-9) << "no wider than the cap the directions were drawn from";
    if (s < M_PI / 2 - 0.01) {  // inside a hemisphere: Welzl's algorithm alone is exact
      const bw::BoundingCone welzl = bw::welzlBoundingCone(d, static_cast<std::uint32_t>(trial));
      expectEncloses(welzl, d);
      EXPECT_NEAR(welzl.angle, slow.angle, 1e-9) << "trial " << trial;
    }
    wide += fast.angle > M_PI / 2 ? 1 : 0;
  }
  EXPECT_GT(wide, 10) << "the sets outside every hemisphere are exercised";
}

TEST(BoundingCone, BadInput) {
  EXPECT_THROW(bw::minimalBoundingCone({}), std::invalid_argument);
  EXPECT_THROW(bw::minimalBoundingCone({Eigen::Vector3d::Zero()}), std::invalid_argument);
  EXPECT_THROW(bw::minimalBoundingCone({Eigen::Vector3d(NAN, 0, 1)}), std::invalid_argument);
  EXPECT_THROW(bw::bruteForceBoundingCone({}), std::invalid_argument);
}

// The workspace map (workspace/workspace_map.hpp) on the WAM, coarse: the spherical shoulder and wrist are found,
// the wrist-centre test never rules out a pose the arm reaches (2000 random configurations within the limits) and
// rules out one beyond reach, every voxel's numbers are consistent (ratio, cones, pruned + solved ≤ M), a voxel at a
// reached tool position is reachable, the map is the same on one thread and on three, and the same with and without
// the wrist-centre test (it only saves IK calls that would fail); the cache file gives back the same map, only for
// the same arm and settings, and a damaged file is built again.
#include "bimanual_skills/kinematics/chain_kinematics.hpp"
#include "bimanual_skills/workspace/workspace_map.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>
#include <stdexcept>

namespace bk = bimanual_skills::kinematics;
namespace bw = bimanual_skills::workspace;

namespace {

bk::ChainModel wam() {
  return bk::ChainModel::fromUrdfFile(std::string(BIMANUAL_SKILLS_SOURCE_DIR) + "/urdf/wam.urdf", "wam_base",
                                      "wam_tool");
}

bw::WorkspaceMapSettings coarse(int threads) {
  bw::WorkspaceMapSettings s;
  s.resolution = 0.3;
  s.orientations = 6;
  s.threads = threads;
  s.seed = 4;
  return s;
}

}  // namespace

TEST(WorkspaceMap, TheWristCentreTestNeverRulesOutAReachedPose) {
  const bk::ChainModel model = wam();
  const bw::WorkspaceMap map = bw::WorkspaceMap::build(model, coarse(2));
  ASSERT_TRUE(map.sphericalWrist());
  EXPECT_GT(map.reach(), 0.8);
  EXPECT_LT(map.reach(), 1.3);
  bk::ChainData data(model);
  std::mt19937 rng(3);
  for (int k = 0; k < 2000; ++k) {
    Eigen::VectorXd q(7);
    for (int i = 0; i < 7; ++i) {
      q[i] = std::uniform_real_distribution<double>(model.lowerLimits()[i], model.upperLimits()[i])(rng);
    }
    ASSERT_EQ(bk::forwardKinematics(model, data, q), bk::KinematicsStatus::Success);
    EXPECT_TRUE(map.mayReach(data.tipPose())) << q.transpose();
  }
  Eigen::Isometry3d far = Eigen::Isometry3d::Identity();
  far.translation() = Eigen::Vector3d(2.0, 0.0, 0.5);
  EXPECT_FALSE(map.mayReach(far));
}

TEST(WorkspaceMap, VoxelsAreConsistentAndTheSameOnAnyNumberOfThreads) {
  const bk::ChainModel model = wam();
  const bw::WorkspaceMap one = bw::WorkspaceMap::build(model, coarse(1));
  const bw::WorkspaceMap three = bw::WorkspaceMap::build(model, coarse(3));
  ASSERT_EQ(one.voxels().size(), three.voxels().size());
  ASSERT_GT(one.reachable(), 10u);
  const double wrist = std::max(std::abs(model.lowerLimits()[5]), std::abs(model.upperLimits()[5]));
  for (std::size_t i = 0; i < one.voxels().size(); ++i) {
    const bw::WorkspaceVoxel& a = one.voxels()[i];
    const bw::WorkspaceVoxel& b = three.voxels()[i];
    EXPECT_EQ(a.solved, b.solved);
    EXPECT_EQ(a.pruned, b.pruned);
    EXPECT_EQ(a.manipulability, b.manipulability);
    EXPECT_EQ(a.forearm.angle, b.forearm.angle);
    EXPECT_LE(a.solved + a.pruned, 6);
    EXPECT_DOUBLE_EQ(a.solution_ratio, a.solved / 6.0);
    if (a.solved > 0) {
      EXPECT_GT(a.manipulability, 0.0);
      EXPECT_GE(a.condition, 1.0);
      EXPECT_NEAR(a.tool.angle, std::min(M_PI, a.forearm.angle + wrist), 1e-12);
    }
  }
  // Where the arm puts its tool, the voxel there is reachable (the wrist can take many orientations at mid reach).
  bk::ChainData data(model);
  Eigen::VectorXd q(7);
  q << 0.0, 0.6, 0.0, 1.6, 0.0, 0.4, 0.0;
  ASSERT_EQ(bk::forwardKinematics(model, data, q), bk::KinematicsStatus::Success);
  const bw::WorkspaceVoxel* nearest = &one.voxels().front();
  for (const bw::WorkspaceVoxel& v : one.voxels()) {
    if ((v.centre - data.tipPose().translation()).norm() < (nearest->centre - data.tipPose().translation()).norm()) {
      nearest = &v;
    }
  }
  EXPECT_GT(nearest->solved, 0);
}

TEST(WorkspaceMap, TheWristCentreTestLosesNoSolution) {
  const bk::ChainModel model = wam();
  bw::WorkspaceMapSettings with = coarse(2), without = coarse(2);
  with.resolution = without.resolution = 0.2;
  without.wrist_test = false;
  const bw::WorkspaceMap a = bw::WorkspaceMap::build(model, with), b = bw::WorkspaceMap::build(model, without);
  ASSERT_EQ(a.voxels().size(), b.voxels().size());
  int pruned = 0;
  for (std::size_t i = 0; i < a.voxels().size(); ++i) {
    EXPECT_EQ(a.voxels()[i].solved, b.voxels()[i].solved) << "voxel " << i;
    EXPECT_EQ(a.voxels()[i].manipulability, b.voxels()[i].manipulability);
    EXPECT_EQ(b.voxels()[i].pruned, 0);
    pruned += a.voxels()[i].pruned;
  }
  EXPECT_GT(pruned, 100) << "the test rules out poses";
}

TEST(WorkspaceMap, BadSettings) {
  bw::WorkspaceMapSettings s = coarse(1);
  s.resolution = 0.0;
  EXPECT_THROW(bw::WorkspaceMap::build(wam(), s), std::invalid_argument);
  s = coarse(1);
  s.orientations = 0;
  EXPECT_THROW(bw::WorkspaceMap::build(wam(), s), std::invalid_argument);
  s = coarse(1);
  s.forearm_joint = 9;
  EXPECT_THROW(bw::WorkspaceMap::build(wam(), s), std::invalid_argument);
}

TEST(WorkspaceMap, TheCacheGivesBackTheSameMapAndOnlyForItsKey) {
  const bk::ChainModel model = wam();
  const std::string directory = testing::TempDir() + "/workspace_cache_test";
  std::filesystem::remove_all(directory);
  bool from_cache = true;
  const bw::WorkspaceMap built = bw::WorkspaceMap::cached(model, coarse(2), directory, {}, &from_cache);
  EXPECT_FALSE(from_cache);
  const bw::WorkspaceMap loaded = bw::WorkspaceMap::cached(model, coarse(1), directory, {}, &from_cache);
  EXPECT_TRUE(from_cache) << "the same model and settings but threads";
  ASSERT_EQ(loaded.voxels().size(), built.voxels().size());
  for (std::size_t i = 0; i < built.voxels().size(); ++i) {
    const bw::WorkspaceVoxel& a = built.voxels()[i];
    const bw::WorkspaceVoxel& b = loaded.voxels()[i];
    EXPECT_EQ(a.centre, b.centre);
    EXPECT_EQ(a.solved, b.solved);
    EXPECT_EQ(a.pruned, b.pruned);
    EXPECT_EQ(a.condition, b.condition);
    EXPECT_EQ(a.manipulability, b.manipulability);
    EXPECT_EQ(a.tool.axis, b.tool.axis);
    EXPECT_EQ(a.tool.angle, b.tool.angle);
    EXPECT_EQ(a.forearm.axis, b.forearm.axis);
    EXPECT_EQ(a.forearm.angle, b.forearm.angle);
    EXPECT_EQ(a.solution_ratio, b.solution_ratio);
  }
  EXPECT_EQ(loaded.reach(), built.reach());
  EXPECT_EQ(loaded.sphericalWrist(), built.sphericalWrist());
  EXPECT_EQ(loaded.settings().seed, 4u);
  Eigen::Isometry3d far = Eigen::Isometry3d::Identity();
  far.translation() = Eigen::Vector3d(3.0, 0.0, 0.0);
  EXPECT_FALSE(loaded.mayReach(far)) << "the wrist-centre test survives the file";

  // Other settings or another arm: another key.
  bw::WorkspaceMapSettings other = coarse(2);
  other.seed = 5;
  EXPECT_NE(bw::WorkspaceMap::key(model, other), bw::WorkspaceMap::key(model, coarse(2)));
  other = coarse(2);
  other.orientations = 7;
  EXPECT_NE(bw::WorkspaceMap::key(model, other), bw::WorkspaceMap::key(model, coarse(2)));
  EXPECT_EQ(bw::WorkspaceMap::key(model, coarse(1)), bw::WorkspaceMap::key(model, coarse(3)));
  const bk::ChainModel shorter =
      bk::ChainModel::fromUrdfFile(std::string(BIMANUAL_SKILLS_SOURCE_DIR) + "/urdf/wam.urdf", "wam_base", "wam_link6");
  EXPECT_NE(bw::WorkspaceMap::key(shorter, coarse(2)), bw::WorkspaceMap::key(model, coarse(2)));

  // A file under another key, a truncated file and garbage are not maps: the caller builds again.
  const std::string path = bw::WorkspaceMap::cachePath(directory, model, coarse(2));
  EXPECT_FALSE(bw::WorkspaceMap::load(path, bw::WorkspaceMap::key(model, coarse(2)) + 1).has_value());
  const auto size = std::filesystem::file_size(path);
  std::filesystem::resize_file(path, size - 9);
  EXPECT_FALSE(bw::WorkspaceMap::load(path, bw::WorkspaceMap::key(model, coarse(2))).has_value());
  {
    std::ofstream garbage(path, std::ios::binary | std::ios::trunc);
    garbage << "not a map";
  }
  EXPECT_FALSE(bw::WorkspaceMap::load(path, bw::WorkspaceMap::key(model, coarse(2))).has_value());
  EXPECT_FALSE(bw::WorkspaceMap::load(directory + "/missing.map", 1).has_value());
  bw::WorkspaceMap::cached(model, coarse(2), directory, {}, &from_cache);
  EXPECT_FALSE(from_cache) << "a damaged file is built again";
  EXPECT_TRUE(bw::WorkspaceMap::load(path, bw::WorkspaceMap::key(model, coarse(2))).has_value()) << "and rewritten";
  std::filesystem::remove_all(directory);
}

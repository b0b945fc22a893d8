// workspace_markers: an arm's workspace map (workspace/workspace_map.hpp, thesis Sec. 3.2.1) in rviz. A thin shell:
// the map is built by the library (or read from its cache file) and published once, latched.
#include "bimanual_skills/ros_layer/parameters.hpp"
#include "bimanual_skills/sim/robot_file.hpp"
#include "bimanual_skills/workspace/workspace_map.hpp"
#include "cli/pinned_numerics.hpp"
#include "node_cli.hpp"
#include "scene_markers.hpp"

#include <ros/package.h>
#include <ros/ros.h>
#include <visualization_msgs/MarkerArray.h>

#include <algorithm>
#include <cmath>
#include <string>

namespace bs = bimanual_skills;
namespace bw = bimanual_skills::workspace;

namespace {

const char* kUsage =
    "usage: rosrun bimanual_skills workspace_markers [_robot:=FILE] [_arm:=NAME] [_resolution:=M]\n"
    "                                                [_orientations:=N] [_seed:=S] [_cache:=DIR] [_slice_y:=M]\n"
    "\n"
    "An arm's workspace map by inverse sampling (thesis Sec. 3.2.1, Fig. 3.7) in rviz: the map is built, or read\n"
    "from the cache directory where workspace_benchmark and this node keep maps (one file per arm and settings),\n"
    "then published once, latched, in the frame of the base link.\n"
    "\n"
    "Parameters (private):\n"
    "  ~robot         the robot file (default: the package's config/robots/wam.yaml): its URDF and arms\n"
    "  ~arm           the arm mapped (default the robot file's first); the map is in its base link's frame\n"
    "  ~resolution    voxel edge [m] (default 0.1)\n"
    "  ~orientations  tool orientations tried per voxel (default 50)\n"
    "  ~seed          of the orientations and IK restarts (default 1)\n"
    "  ~cache         map files directory (default ~/.cache/bimanual_skills/workspace; \"\": build only)\n"
    "  ~slice_y       the plane y = slice_y [m] whose tool cones are drawn (default 0)\n"
    "  ~cutaway       draw only the voxels up to the slice, so that it shows (default true)\n"
    "\n"
    "Topics:\n"
    "  ~map    visualization_msgs/MarkerArray: the reachable voxels (up to the slice with ~cutaway) as cubes,\n"
    "          coloured by the ratio of orientations solved (blue: few, red: all)\n"
    "  ~cones  visualization_msgs/MarkerArray: in the slice, each reachable voxel's cone of feasible tool z axes\n"
    "          as an arrow along its axis, coloured by the cone's half-angle (blue: narrow, red: 180 degrees)\n";

/// Blue → green → red for t in [0, 1].
std_msgs::ColorRGBA heat(double t) {
  t = std::clamp(t, 0.0, 1.0);
  std_msgs::ColorRGBA c;
  c.r = static_cast<float>(std::clamp(2.0 * t - 1.0, 0.0, 1.0));
  c.g = static_cast<float>(1.0 - std::abs(2.0 * t - 1.0));
  c.b = static_cast<float>(std::clamp(1.0 - 2.0 * t, 0.0, 1.0));
  c.a = 1.0f;
  return c;
}

}  // namespace

int main(int argc, char** argv) {
  bimanual_skills::cli::pinNumerics(argv);
  bs::nodes::handleCommandLine(argc, argv, kUsage);
  ros::init(argc, argv, "workspace_markers");
  ros::NodeHandle private_node("~");
  try {
    bs::ros_layer::ParameterReader p(private_node, "workspace_markers");
    const bs::sim::RobotFile robot = bs::sim::RobotFile::fromYamlFile(
        p.text("robot", ros::package::getPath("bimanual_skills") + "/config/robots/wam.yaml"));
    const std::string arm_name = p.text("arm", robot.arms.front().name);
    const bs::sim::RobotArm* arm = robot.arm(arm_name);
    if (arm == nullptr) throw std::invalid_argument("the robot file " + robot.path + " has no arm '" + arm_name + "'");
    const std::string& urdf = robot.urdf_path;
    const std::string& base = arm->base_link;
    const std::string& tip = arm->tip_link;
    const std::string cache = p.text("cache", bw::WorkspaceMap::defaultCacheDirectory());
    bw::WorkspaceMapSettings settings;
    settings.resolution = p.number("resolution", 0.1, 1e-3, 10.0);
    settings.orientations = p.integer("orientations", 50, 1, 100000);
    settings.seed = static_cast<std::uint32_t>(p.integer("seed", 1, 0));
    const double slice = p.number("slice_y", 0.0, -100.0, 100.0);
    const bool cutaway = p.boolean("cutaway", true);
    p.warnUnknown();
    const bs::kinematics::ChainModel model = bs::kinematics::ChainModel::fromUrdfFile(urdf, base, tip);

    ROS_INFO("workspace_markers: the map of %s (%s -> %s), %.3f m voxels, %d orientations, seed %u", urdf.c_str(),
             base.c_str(), tip.c_str(), settings.resolution, settings.orientations, settings.seed);
    bool from_cache = false;
    const ros::WallTime start = ros::WallTime::now();
    const bw::WorkspaceMap map = bw::WorkspaceMap::cached(
        model, settings, cache,
        [](std::size_t done, std::size_t total) { ROS_INFO("workspace_markers: %zu/%zu voxels", done, total); },
        &from_cache);
    ROS_INFO("workspace_markers: %zu reachable voxels of %zu, %s in %.1f s", map.reachable(), map.voxels().size(),
             from_cache ? "read from the cache" : "built", (ros::WallTime::now() - start).toSec());

    const double h = settings.resolution;
    visualization_msgs::MarkerArray voxels;
    visualization_msgs::Marker cubes =
        bs::nodes::marker(base, "workspace", 0, visualization_msgs::Marker::CUBE_LIST, ros::Time(0));
    cubes.scale.x = cubes.scale.y = cubes.scale.z = 0.9 * h;
    visualization_msgs::MarkerArray cones;
    int id = 0;
    for (const bw::WorkspaceVoxel& v : map.voxels()) {
      if (v.solved == 0 || (cutaway && v.centre.y() > slice + 0.5 * h)) continue;
      cubes.points.push_back(bs::nodes::toPoint(v.centre));
      std_msgs::ColorRGBA c = heat(v.solution_ratio);
      c.a = 0.6f;
      cubes.colors.push_back(c);
      if (std::abs(v.centre.y() - slice) > 0.5 * h) continue;
      visualization_msgs::Marker arrow =
          bs::nodes::marker(base, "tool_cones", id++, visualization_msgs::Marker::ARROW, ros::Time(0));
      arrow.points = {bs::nodes::toPoint(v.centre), bs::nodes::toPoint(v.centre + 0.8 * h * v.tool.axis)};
      arrow.scale.x = 0.08 * h;
      arrow.scale.y = 0.2 * h;
      arrow.scale.z = 0.3 * h;
      arrow.color = heat(v.tool.angle / M_PI);
      cones.markers.push_back(arrow);
    }
    voxels.markers.push_back(cubes);
    ros::Publisher map_publisher = private_node.advertise<visualization_msgs::MarkerArray>("map", 1, true);
    ros::Publisher cone_publisher = private_node.advertise<visualization_msgs::MarkerArray>("cones", 1, true);
    map_publisher.publish(voxels);
    cone_publisher.publish(cones);
    ROS_INFO("workspace_markers: published %zu voxels on %s and %zu cones (y = %.2f m) on %s", cubes.points.size(),
             map_publisher.getTopic().c_str(), cones.markers.size(), slice, cone_publisher.getTopic().c_str());
    ros::spin();
  } catch (const std::exception& e) {
    ROS_FATAL("workspace_markers: %s", e.what());
    return 1;
  }
  return 0;
}

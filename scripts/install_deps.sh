#!/usr/bin/env bash
# Installs the Debian packages bimanual_skills needs. Idempotent: packages already present are skipped,
# and apt-get is not called at all when everything is there.
set -euo pipefail

PACKAGES=(
  # ROS 1 (Debian's ros_comm) and the command-line tools users run
  ros-base-dev catkin rosbash python3-roslaunch python3-rosservice python3-rostopic python3-rosnode
  python3-rosparam python3-rosmaster python3-rostest librostest-dev ros-message-generation ros-message-runtime libroscpp-dev
  # messages, with their Python modules for rosservice/rostopic from the shell
  libsensor-msgs-dev libgeometry-msgs-dev libtrajectory-msgs-dev libvisualization-msgs-dev libstd-srvs-dev
  libstd-msgs-dev libdiagnostic-msgs-dev libros-rosgraph-msgs-dev libroslib-dev python3-diagnostic-msgs
  python3-sensor-msgs python3-geometry-msgs python3-trajectory-msgs python3-visualization-msgs python3-std-srvs
  # robot model and transforms
  libtf2-ros-dev libtf2-eigen-dev libkdl-parser-dev liborocos-kdl-dev liburdf-dev liburdfdom-dev
  ros-robot-state-publisher joint-state-publisher topic-tools
  # rviz, and headless snapshots of it (scripts/rviz_snapshot.sh)
  rviz xvfb xauth imagemagick
  # numerics
  libeigen3-dev libnlopt-cxx-dev libyaml-cpp-dev nlohmann-json3-dev
  # physics simulator (sim/): Bullet, with its double-precision build and pkg-config files
  libbullet-dev libbullet-extras-dev pkg-config
  # vision (vision/): rendered camera images and the image terms of the folding reward
  libopencv-dev libcv-bridge-dev librosbag-dev python3-rosbag
  # trajectory actions (actionlib), with the Python modules for rostopic/axclient
  libactionlib-dev libactionlib-msgs-dev python3-actionlib python3-actionlib-msgs
  # teaching by hand: rviz interactive markers (teach_demonstration)
  libinteractive-markers-dev
  # object tracking: the object's true motion (nav_msgs/Odometry), colour and depth images in step (message_filters)
  libnav-msgs-dev python3-nav-msgs libmessage-filters-dev
  # build and test
  cmake g++ make colcon python3-colcon-ros python3-colcon-cmake python3-colcon-test-result python3-colcon-bash
  # the Python module (python/bindings.cpp) and its tests
  pybind11-dev python3-pybind11 python3-dev python3-pytest
  libgtest-dev googletest libbenchmark-dev
  # plots and formatting
  python3-matplotlib python3-numpy python3-pil python3-scipy python3-yaml clang-format
)

missing=()
for p in "${PACKAGES[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q 'install ok installed'; then
    missing+=("$p")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "install_deps: all ${#PACKAGES[@]} Debian packages already installed"
  exit 0
fi

echo "install_deps: installing ${#missing[@]} missing packages: ${missing[*]}"
SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -q
$SUDO apt-get install -y -q --no-install-recommends "${missing[@]}"

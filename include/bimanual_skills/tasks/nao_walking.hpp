/// \file
/// Walks of a NAO's legs for the DR-ProMP experiment of thesis Sec. 7.1 (Figs. 7.3–7.4: 13 walks of 12 leg joints
/// "obtained by controlling the Zero Moment Point"). The thesis' recordings are not available; these walks are
/// generated: a footstep plan (alternating footholds `step_length` apart along a path that turns by `turn` per
/// step, feet `foot_separation` apart, the last step closing the feet), the ZMP reference on the stance foot during
/// single support and moving to the next one during double support, the centre of mass from ZMP preview control of
/// the cart-table model at the torso's height (control/zmp_preview.hpp, Kajita et al. 2003), the swing foot lifted
/// by `foot_lift` on a cosine profile, the torso upright at `torso_height` above the ground with the mean of the
/// feet's headings, and the 12 joints from inverse kinematics of urdf/nao_legs.urdf (NAO H25 V5). On a NAO the two
/// HipYawPitch joints are one motor: the left leg's six joints reach its foot's pose, the right leg takes the same
/// HipYawPitch and reaches its foot's position and flatness with the other five (its heading follows; the walk
/// records how far it is from the plan). Offline: allocates and throws.
#pragma once

#include "bimanual_skills/kinematics/chain_kinematics.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <string>
#include <vector>

namespace bimanual_skills::tasks {

struct NaoWalkParameters {
  double step_length = 0.04;      ///< Between consecutive footholds along the path [m].
  double step_period = 0.5;       ///< One step [s].
  double double_support = 0.2;    ///< Share of a step with both feet down.
  double foot_lift = 0.02;        ///< The swing foot's highest point [m].
  double torso_height = 0.30;     ///< The torso frame above the ground, the cart-table's height [m].
  double foot_separation = 0.10;  ///< Between the feet's centres sideways [m].
  double turn = 0.0;              ///< The path's heading change per step [rad].
  int steps = 8;                  ///< Steps; the last brings the feet together.
  double period = 0.01;           ///< Sampling and control period [s].
  double rest = 1.0;              ///< Standing before the first step and after the last [s].
  double preview = 1.6;           ///< Preview horizon [s] (Kajita's).

  /// \throws std::invalid_argument naming the first value out of range.
  void validate() const;
};

/// The two legs of urdf/nao_legs.urdf: torso → l_sole and torso → r_sole, joints HipYawPitch, HipRoll, HipPitch,
/// KneePitch, AnklePitch, AnkleRoll.
struct NaoLegs {
  kinematics::ChainModel left, right;
  /// \throws std::invalid_argument if the file is not a NAO's legs (two 6-joint chains from torso).
  static NaoLegs fromUrdfFile(const std::string& path);
};

/// The 12 joints' names in the thesis' order: the left leg's six, then the right leg's.
std::vector<std::string> naoLegJointNames();

struct NaoWalk {
  NaoWalkParameters parameters;
  Eigen::VectorXd time;                   ///< Sample times [s] (rows of the matrices below).
  Eigen::MatrixXd joints;                 ///< samples × 12 [rad], naoLegJointNames()'s order.
  Eigen::MatrixXd com;                    ///< samples × 2: the centre of mass (x, y) in the world [m].
  Eigen::MatrixXd zmp;                    ///< samples × 2: the cart-table's ZMP C x [m].
  Eigen::MatrixXd zmp_reference;          ///< samples × 2 [m].
  Eigen::MatrixXd left_foot, right_foot;  ///< samples × 4: the sole's x, y, z [m] and heading [rad] as planned.
  Eigen::MatrixXd torso;                  ///< samples × 4: x, y, z [m] and heading [rad].
  std::vector<double> step_starts;        ///< Each step's start (its double support's) [s].
  double right_heading_error = 0.0;       ///< Largest |heading of the right sole − plan| over the walk [rad].
};

/// Generates a walk (file comment). \throws std::invalid_argument for invalid parameters or a walk the legs cannot
/// follow (naming the leg, the time and why: out of reach or out of a joint's limits).
NaoWalk generateNaoWalk(const NaoLegs& legs, const NaoWalkParameters& parameters);

/// Steps `first` and `first` + 1 (each foot swings once: one stride) of a walk, resampled linearly to `samples`
/// rows on a normalised time. \throws std::invalid_argument when the walk has no such steps or samples < 2.
Eigen::MatrixXd naoStride(const NaoWalk& walk, int first, int samples);

/// Inverse kinematics of one leg: from `q` (warm start, 6 joints) to the sole's pose `target` in the torso frame,
/// by damped Gauss–Newton on the pose error. `fixed_first`: HipYawPitch stays as given and the sole's heading is free.
/// Returns "" or why it failed (no convergence, out of the joints' limits).
std::string solveNaoLeg(const kinematics::ChainModel& leg, kinematics::ChainData& data, const Eigen::Isometry3d& target,
                        bool fixed_first, Eigen::Ref<Eigen::VectorXd> q);

}  // namespace bimanual_skills::tasks

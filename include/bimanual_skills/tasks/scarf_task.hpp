/// \file
/// The scarf-placing task of thesis Sec. 4.3.1 on the simulated WAM: one arm holds a scarf and moves it by a joint-
/// space DMP (25 kernels per joint) tracked by the computed-torque controller with its friction model, while the
/// other arm holds still; the arm's disturbance observer estimates the interaction torques. After the motion the
/// tool lets go, the scarf settles on the mannequin and a colour camera 1 m from it scores the result.
///
/// Cost (thesis): C = Σ_t c_t + c_T, c_t a quadratic form of the DMP's commanded accelerations, c_T = c_cam +
/// c_torque with c_cam from the camera (tasks/scarf.hpp) and c_torque the mean absolute estimated interaction torque
/// over the motion. The scarf mesh's ground truth (wrapped, hanging right and not left) is kept beside it for the
/// experimenter; the cost never uses it. Target bimanual_skills_tasks.
#pragma once

#include "bimanual_skills/primitives/dr_dmp.hpp"
#include "bimanual_skills/realtime/cycle_probe.hpp"
#include "bimanual_skills/sim/sim_config.hpp"
#include "bimanual_skills/tasks/cloth_fold.hpp"
#include "bimanual_skills/tasks/scarf.hpp"
#include "bimanual_skills/vision/perspective_camera.hpp"

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace bimanual_skills::tasks {

struct ScarfTaskConfig {
  std::string sim_config;  ///< A simulation file with the mannequin and a scarf (config/scarf_sim.yaml).
  /// bullet_sim's overrides of the scene (config/scarf_start.yaml): `initial_positions: {ARM: [...]}` (the holding
  /// arm's start, where its tool holds the scarf), `rgbd_eye` and `rgbd_target` (the camera). One file for both
  /// backends.
  std::string start;
  std::string arm = "left";  ///< The arm that holds the scarf; the others hold their start.
  int kernels = 25;          ///< DMP kernels per joint (thesis: 25).
  double duration = 5.0;     ///< Of the motion [s].
  /// Before the motion the scarf, grasped at the start, comes to hang; after it the tool waits, lets go (`release`)
  /// and the scarf settles [s].
  double hold_before = 1.0, hold_after = 0.3, settle = 2.0;
  bool release = true;
  /// A camera that sees the arm (a robot's): from the release on, while the scarf settles, the tool rises 0.15 m,
  /// then the arm goes to `clear_posture` (its joints, within its limits), in `clear_time` [s] (0.1 s to settle; a
  /// quarter of it the lift, at rest between), so that the image at the end of `settle` shows the scarf, not the arm.
  /// The motion before the release is the same with it as without; both backends run it on the same timeline
  /// (ScarfPlan). Empty (and clear_time 0): the arm stays where it lets go.
  Eigen::VectorXd clear_posture;
  double clear_time = 0.0;
  static constexpr double kMinClearTime = 0.1;  ///< The shortest clear_time [s] with a posture.
  /// The demonstration: the tool's positions [m, world] after its start with the start's orientation, each solved by
  /// global IK closest to the one before, reached in equal times (minimum jerk in joint space). Deliberately not
  /// achieving the task.
  std::vector<Eigen::Vector3d> demo_waypoints;
  double max_tracking_error = 0.3;  ///< Joint tracking error beyond which the rollout fails [rad].
  /// The controllers' velocity monitor [rad/s] on every joint of every arm (the robot path's ArmController runs
  /// them; a joint faster than this stops the rollout as ControllerFailed); <= 0: the robot's velocity limits, as
  /// `ctc_controller`'s `~velocity_limit` defaults.
  double velocity_limit = 0.0;
  double path_rate = 50.0;  ///< Samples per second of the recorded tool and joint paths.
  double cloth_rate = 0.0;  ///< Scarf meshes recorded per second (ScarfRollout::cloth_frames); 0: none.

  ScarfCameraConfig camera;
  /// camera.d_ref and camera.hanging_level from the start file's camera (referenceDistance(), hangingLevel())
  /// instead of their values.
  bool from_camera = true;
  /// c_t = acceleration_weight ‖q̈_ref‖² dt per period (summed: [rad²/s³]); c_torque = torque_weight × the mean over
  /// the motion of the mean over the joints of |τ̂_ext| [N m] (0: the cost without the observer's term).
  double acceleration_weight = 0.01, torque_weight = 1.0;
  double failure_cost = 30.0;  ///< The cost of a rollout that failed (above any c_cam of a seen scene).

  /// \throws std::invalid_argument naming the entry out of range.
  void validate() const;
};

struct ScarfRollout {
  FoldOutcome outcome = FoldOutcome::Ok;
  std::string reason;
  /// The cost and its terms: cost = c_acceleration + c_cam + c_torque (failure_cost when not Ok).
  double cost = 0.0, c_acceleration = 0.0, c_cam = 0.0, c_torque = 0.0;
  double acceleration = 0.0;     ///< Σ ‖q̈_ref‖² dt over the motion [rad²/s³].
  double mean_abs_torque = 0.0;  ///< Mean over the motion and the joints of |τ̂_ext| (the observer) [N m].
  double peak_abs_torque = 0.0;  ///< Largest |τ̂_ext,i| over the motion [N m].
  /// The simulator's truth over the motion: mean and peak force of the scarf on the tool [N].
  double mean_tool_force = 0.0, peak_tool_force = 0.0;
  /// The observer's estimate as a force on the tool, F̂ = (J Jᵀ + λ² I)⁻¹ J τ̂ (the wrench whose Jᵀ F best gives
  /// τ̂, damped λ = 0.1), against the scarf's force on the tool: mean and largest |F̂ − F| over the motion [N]. Other
  /// contacts (the arm against the mannequin) are in F̂ and not in F.
  double mean_force_error = 0.0, max_force_error = 0.0;
  double max_tracking_error = 0.0;  ///< [rad]
  int grasped_nodes = 0;
  std::size_t control_allocations = 0;  ///< What run()'s probe counted in the control parts.
  ScarfCameraTerms camera;
  ScarfTruth truth;
  Eigen::MatrixXd joint_path;  ///< Measured joint positions of the holding arm (7 × samples).
  Eigen::Matrix3Xd tool_path;  ///< Its tool's positions (world).
  Eigen::VectorXd path_times;  ///< [s]
  std::vector<Eigen::Matrix3Xd> cloth_frames;
  Eigen::VectorXd cloth_times;
  Eigen::Matrix3Xd cloth_vertices;  ///< The final scarf (world).
  cv::Mat bgr;                      ///< The camera's final colour image (what c_cam scored).
  double simulated_seconds = 0.0, wall_seconds = 0.0;
  double cloth_wall_seconds = 0.0;  ///< Of wall_seconds, inside the scarf's steps (sim::ClothTimings).
};

/// A policy's joint references as a robot runs them (ScarfOnRobotTask), on the simulation's step dt from the
/// rollout's start: the hold (hold_before) at the start, the DMP's motion, then its last point held.
struct ScarfPlan {
  FoldOutcome outcome = FoldOutcome::Ok;
  std::string reason;
  double dt = 0.001;
  /// Steps of the motion's start, its end, the release, the end of the move out of the camera's view
  /// (ScarfTaskConfig::clear_posture; the release without one) and the images (the settled scarf).
  int move_start = 0, move_end = 0, release = 0, clear_end = 0, end = 0;
  /// With clear_posture: the step the tool is up (a quarter of the way to clear_end) and the posture there, the tool
  /// 0.15 m above where it let go (global IK closest to the last reference; that reference where the lift would
  /// take a joint more than 1 rad).
  int lift_end = 0;
  Eigen::VectorXd lifted;
  /// The DMP's references over the motion: column j is the reference of step move_start + j.
  Eigen::MatrixXd position, velocity, acceleration;
  double acceleration_cost = 0.0;  ///< Σ ‖q̈_ref‖² dt over the motion [rad²/s³] (ScarfRollout::acceleration).
};

/// The cost's terms of a rollout from its measures (acceleration, mean_abs_torque, camera, outcome), as run()
/// computes them: c_acceleration, c_torque, c_cam and cost.
void scoreScarfRollout(const ScarfTaskConfig& config, ScarfRollout& rollout);

/// The scarf's scene placed for another pair: the turn about the vertical and the shift that take the holding arm's
/// base on the simulation file's robot to its base on `robot` (a robot file). Applied to the mannequin, the scarf,
/// the camera and the demonstration's waypoints, they stand to that arm as they stand to the simulation file's.
struct ScarfPlacement {
  double yaw = 0.0;                                 ///< [rad] about world z
  Eigen::Vector3d shift = Eigen::Vector3d::Zero();  ///< [m, world], after the turn
  Eigen::Vector3d apply(const Eigen::Vector3d& point) const;
};
/// \throws std::invalid_argument when `robot` has no such arm or its base is tilted against the other's.
ScarfPlacement scarfPlacementOn(const ScarfTaskConfig& config, const std::string& robot);

/// The holding arm's start on `robot` with the scene placed by scarfPlacementOn: its tool where the placed start
/// file puts the tool of the simulation file's robot, pointing as `robot`'s start does, solved by global IK
/// (sim::postureFromToolPose). \throws std::invalid_argument when that pose is out of the arm's reach.
Eigen::VectorXd scarfStartOn(const ScarfTaskConfig& config, const std::string& robot);

/// The task. Construction builds the simulation, controllers, camera and demonstration (allocates, throws
/// std::invalid_argument with the reason); run() starts every rollout from a new simulation. One object per thread.
class ScarfTask {
 public:
  explicit ScarfTask(const ScarfTaskConfig& config);
  ~ScarfTask();
  ScarfTask(const ScarfTask&) = delete;
  ScarfTask& operator=(const ScarfTask&) = delete;

  /// Joints of the holding arm: the DMP's DoF.
  int dofs() const noexcept;
  /// The DR-DMP parameters of the policy with `matrices` coordination matrices (kernels, no goal offsets).
  primitives::DrDmpParameters forcingParameters(int matrices) const;
  /// The demonstration's joint path (samples × dofs, every demonstrationStep()): what the DMP is fitted to.
  const Eigen::MatrixXd& demonstrationTrajectory() const noexcept;
  double demonstrationStep() const noexcept;
  /// The demonstration's standard DMP (Ω = I): its latent weights, dofs × kernels, joint by joint.
  Eigen::VectorXd demonstrationWeights() const;

  /// One rollout of a coordinated policy f = Ω^t W g(x) (primitives::DrDmp) from the demonstration's start to its
  /// goal, with the simulation's and the camera's noise seeded by `seed`. Sizes that do not fit or non-finite
  /// values: InvalidPolicy. `probe`, if any, brackets the control part of every period (the DMP's step, each arm's
  /// state, controller, observer and torque), its counts summed in ScarfRollout::control_allocations.
  ScarfRollout run(const std::vector<Eigen::MatrixXd>& coordination, const Eigen::VectorXd& latent_weights,
                   std::uint32_t seed, realtime::CycleProbe* probe = nullptr);

  /// The references run() would give its controller, without simulating: InvalidPolicy or OutOfLimits (with the
  /// reason) when the DMP's references are not finite or leave the joint limits.
  ScarfPlan plan(const std::vector<Eigen::MatrixXd>& coordination, const Eigen::VectorXd& latent_weights) const;
  /// The scarf's ground truth of a final mesh (its nodes, as ScarfRollout numbers them). \throws
  /// std::invalid_argument for a mesh of another size.
  ScarfTruth truthOf(const Eigen::Matrix3Xd& vertices) const;

  const ScarfTaskConfig& config() const noexcept;
  const sim::SimConfig& simConfig() const noexcept;
  const Mannequin& mannequin() const noexcept;
  const vision::PinholeCamera& camera() const noexcept;
  /// The holding arm's chain (its joint limits and velocity limits).
  const kinematics::ChainModel& armModel() const noexcept;
  /// The holding arm's base frame in the world.
  const Eigen::Isometry3d& basePose() const noexcept;
  /// The holding arm's start (joint positions).
  const Eigen::VectorXd& startPosition() const noexcept;
  /// The holding arm's index; every arm's start and joint names (as the robot file gives them).
  int arm() const noexcept;
  const std::vector<Eigen::VectorXd>& starts() const noexcept;
  const std::vector<std::vector<std::string>>& jointNames() const noexcept;
  /// The scarf's triangles (indices into its nodes, as ScarfRollout's meshes number them).
  const Eigen::Matrix3Xi& scarfTriangles() const noexcept;
  /// The camera's colour image of the scene with the scarf as `vertices` (no sensor noise): pictures of a rollout.
  /// \throws std::invalid_argument for a mesh of another size.
  cv::Mat cameraImage(const Eigen::Matrix3Xd& vertices);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace bimanual_skills::tasks

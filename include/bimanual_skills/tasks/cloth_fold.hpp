/// \file
/// The cloth-folding task of thesis Sec. 7.2.3 on the simulated pair of WAMs: a 12-D Cartesian DMP (both tools'
/// positions and the 3-D quaternion-vector orientation relative to the start; 20 weights per DoF, 240 parameters)
/// is turned on line into joint references by CLIK and tracked by the computed-torque controllers (friction model,
/// observer) on the simulated plant, which folds the cloth. One rollout = reset, grasp, move, release, settle.
/// Target bimanual_skills_tasks (tasks floor: uses sim, control, primitives, kinematics).
#pragma once

#include "bimanual_skills/kinematics/clik.hpp"
#include "bimanual_skills/primitives/cartesian_dmp.hpp"
#include "bimanual_skills/primitives/dr_dmp.hpp"
#include "bimanual_skills/sim/sim_config.hpp"
#include "bimanual_skills/tasks/fold_quality.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <opencv2/core.hpp>

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace bimanual_skills::tasks {

/// What the fold's policy parameters are: the thesis' forcing-term weights alone (the DMPs end where the
/// demonstration ends), or also a goal offset per latent DoF through the same coordination matrices
/// (primitives::DrDmpParameters::goal_offsets), so that learning can move where the tools put the cloth down.
enum class FoldPolicy { Weights, WeightsAndGoals };
/// "weights" (the thesis) and "goals".
const char* toString(FoldPolicy policy) noexcept;
/// The inverse of toString(). \throws std::invalid_argument naming `where` for an unknown name.
FoldPolicy foldPolicyFromString(const std::string& text, const std::string& where);

/// The robot's repeatability, drawn for every rollout from its seed: how far the same policy's folds differ on a robot
/// (the thesis, Sec. 7.2.3: 20 runs of its demonstration gave R_depth 0.473 ± 0.029 and R_color 0.799 ± 0.088). The
/// simulated rollout is otherwise the same every time but for the camera's pixel noise, which the image terms average
/// out (R ± 0.002). Each draw is normal and cut at 3 σ.
struct FoldNoise {
  std::string setting = "none";  ///< The named setting it came from (foldNoiseSetting()), or "custom".
  double cloth_position = 0.0;   ///< σ of where the cloth lies after the reset, in x and in y [m].
  double cloth_yaw = 0.0;        ///< σ of its turn about the vertical through its centre [rad].
  double release_time = 0.0;     ///< σ of each gripper's opening, arm by arm, about the planned moment [s].
  bool any() const noexcept { return cloth_position > 0.0 || cloth_yaw > 0.0 || release_time > 0.0; }
  /// \throws std::invalid_argument naming `where` for a negative or non-finite σ, or one beyond 5 cm, 0.2 rad, 0.2 s.
  void validate(const std::string& where) const;
};
/// A named setting: "none" (every σ 0) or "robot" (σ 1.0 cm, 0.035 rad, 0.05 s: the thesis' repeatability, as
/// docs/RESULTS.md measures it). \throws std::invalid_argument naming `where` for another name.
FoldNoise foldNoiseSetting(const std::string& name, const std::string& where);

/// One rollout's draw of a FoldNoise: the cloth's placement offset and each gripper's release offset.
struct FoldNoiseDraw {
  double cloth_x = 0.0, cloth_y = 0.0, cloth_yaw = 0.0;  ///< [m], [m], [rad]
  double release[2] = {0.0, 0.0};                        ///< Left, right [s]; > 0: later than planned.
};
/// The draw of rollout seed `seed` (its own stream: the camera's and the sensors' noise of the same seed unchanged).
FoldNoiseDraw drawFoldNoise(const FoldNoise& noise, std::uint32_t seed);

struct ClothFoldConfig {
  std::string sim_config;  ///< Simulation file with a cloth (config/sim.yaml).
  std::string robot;      ///< A robot file replacing the simulation file's (sim::SimConfig::fromYamlFile); "": its own.
  int kernels = 20;       ///< DMP weights per DoF.
  double duration = 4.0;  ///< Of the fold movement [s].
  double hold_before = 0.2, hold_after = 0.3, settle = 1.0;  ///< Around the movement [s].
  /// The reward's images are of the cloth this long after the settle time [s] (q stays the cloth's at the settle
  /// time): a robot whose camera sees the arms takes them once the arms are out of its view (the robot path's
  /// clear_view), and the cloth slides on meanwhile; the same delay in-process puts both on one timeline.
  double image_delay = 0.0;
  /// Computed-torque gains per joint (low, as in Ch. 4); empty: the robot file's.
  Eigen::VectorXd kp, kv;
  /// Friction model files per arm for the controllers and observers ("" = no friction compensation); empty: the
  /// robot file's.
  std::vector<std::string> friction_files;
  std::string ik_method = "ED";     ///< CLIK method (a thesis name, e.g. "CTP+SD+SVF").
  double max_ik_error = 0.05;       ///< Task error of the CLIK references beyond which the rollout fails [m].
  double max_tracking_error = 0.3;  ///< Joint tracking error beyond which the rollout fails [rad].
  /// The controllers' velocity monitor [rad/s] (the robot path's ArmController runs every arm; a joint faster than
  /// this stops the rollout as ControllerFailed): one entry for every joint or one per joint; empty: the robot's
  /// velocity limits, as `ctc_controller`'s `~velocity_limit` defaults.
  Eigen::VectorXd velocity_limit;
  /// A stepped rollout's (ClothFoldTask::step) reference reaches its commanded velocity at most at this rate
  /// [rad/s², > 0] (TargetFollower's default): a velocity step would ask the computed-torque law for q̈ = Δq̇/dt.
  double step_acceleration = 4.0;
  double path_rate = 50.0;  ///< Samples per second of the recorded tool and joint paths.
  double cloth_rate = 0.0;  ///< Cloth meshes recorded per second (FoldRollout::cloth_frames); 0: none.
  /// The scripted demonstration (deliberately imperfect, as a first kinesthetic attempt would be): the far corners
  /// are carried on arcs of radius `demo_reach` × the cloth's half length and put down `demo_drop` above the table.
  double demo_reach = 0.85, demo_lift = 0.6, demo_drop = 0.06;
  /// The right arm's lag in the scripted demonstration, a fraction of `duration` in [0, 0.9): it starts that much
  /// later and makes the same arc in the time left (0: both arms together).
  double demo_lag = 0.0;
  /// How much of its arc the right arm makes, in [0, 1] (0: it holds its corner where it took it and one arm folds).
  double demo_right_arc = 1.0;
  /// The arcs' ends moved towards the cloth's centre line by this fraction of its half width, in [0, 0.9]: the far
  /// corners meet inwards, a diagonal, triangular fold.
  double demo_inward = 0.0;
  FoldPolicy policy = FoldPolicy::WeightsAndGoals;
  /// The robot's repeatability in simulation (none by default). The robot path has its robot's own.
  FoldNoise noise;
  /// Instead of the scripted demonstration: one Cartesian DMP file per arm (left, right; primitives/dmp_yaml.hpp,
  /// quaternion-vector encoding, `kernels` kernels), e.g. those saveDemonstration() wrote, run over `duration`.
  std::vector<std::string> demonstration_files;
};

/// Why a rollout ended.
enum class FoldOutcome {
  Ok,
  InvalidPolicy,       ///< Wrong size or NaN/Inf parameters.
  GraspFailed,         ///< A tool started with no cloth node within the grasp radius.
  IkFailed,            ///< The CLIK references could not follow the DMP (task error beyond max_ik_error).
  ControllerFailed,    ///< Tracking error beyond max_tracking_error (or an invalid controller input).
  SimulationDiverged,  ///< The arms or the cloth left their bounds (NaN, speeds, stretch).
  RobotFailed,         ///< A robot interface failed or did not answer in time (a service, an action, a topic).
  OutOfLimits,         ///< The joint references leave the URDF's position or velocity limits (checked as planned).
};
const char* toString(FoldOutcome outcome) noexcept;
/// The inverse of toString(). \throws std::invalid_argument naming `where` for an unknown name.
FoldOutcome foldOutcomeFromString(const std::string& text, const std::string& where);

struct FoldRollout {
  FoldOutcome outcome = FoldOutcome::Ok;
  std::string reason;               ///< Empty when Ok.
  double acceleration_cost = 0.0;   ///< ∫ ‖q̈_ref‖² dt over both arms [rad²/s³] (R_acceleration's raw value).
  double max_tracking_error = 0.0;  ///< [rad]
  double max_ik_error = 0.0;        ///< [m]
  double max_edge_stretch = 1.0;    ///< Largest structural-edge stretch of the cloth over the rollout (Cloth).
  int grasped_nodes[2] = {0, 0};
  std::vector<Eigen::Matrix3Xd> commanded_path, actual_path;  ///< Tool positions (world) per arm, at path_rate.
  std::vector<Eigen::MatrixXd> joint_path;                    ///< Measured joint positions per arm (7 × samples).
  Eigen::VectorXd path_times;                                 ///< Simulated time of each path sample [s].
  std::vector<Eigen::Matrix3Xd> cloth_frames;                 ///< Cloth meshes at cloth_rate (world frame).
  Eigen::VectorXd cloth_times;                                ///< Simulated time of each cloth frame [s].
  Eigen::Matrix3Xd cloth_vertices;                            ///< The cloth mesh at the settle time (world frame): q's.
  /// The cloth mesh the reward's images show, image_delay after the settle time (empty: cloth_vertices').
  Eigen::Matrix3Xd cloth_image_vertices;
  Eigen::Matrix3Xi cloth_triangles;
  Eigen::Matrix3Xd cloth_rest_vertices;
  /// A robot's rollout: the images its camera sent at moments of the rollout (colour bgr8, depth 32FC1 [m]), the last
  /// the ones the reward scored, and their times [s since the grasp]. Empty for a simulated rollout, whose images are
  /// rendered from its meshes.
  std::vector<cv::Mat> camera_colour, camera_depth;
  Eigen::VectorXd camera_times;
  FoldQuality fold;     ///< The final cloth's fold quality (ground truth, fold_quality.hpp).
  FoldNoiseDraw noise;  ///< The robot's noise this rollout drew (ClothFoldConfig::noise; zeros without it).
  double simulated_seconds = 0.0, wall_seconds = 0.0;
  double cloth_wall_seconds = 0.0;  ///< Of wall_seconds, inside the cloth's steps (sim::ClothTimings).
};

/// A rollout's joint references computed before it runs (ClothFoldTask::plan): what run() computes period by
/// period, for a robot that takes whole trajectories. Column k of each matrix is the reference of period k
/// (t = k dt after the grasp), over the hold, the movement, the hold, the release and the settling.
struct FoldPlan {
  FoldOutcome outcome = FoldOutcome::Ok;  ///< Ok, InvalidPolicy, IkFailed or OutOfLimits.
  std::string reason;
  double dt = 0.0;                  ///< [s]
  int move_start = 0, release = 0;  ///< Periods at which the movement starts, the grippers open.
  std::vector<Eigen::MatrixXd> position, velocity, acceleration;  ///< Per arm, 7 × periods (up to a failure).
  double acceleration_cost = 0.0;                                 ///< As FoldRollout::acceleration_cost.
  double max_ik_error = 0.0;                                      ///< [m]
};

/// The task. Construction builds the simulation, controllers and the demonstration (allocates, throws
/// std::invalid_argument with the reason); run() resets and reuses them. One object per thread.
class ClothFoldTask {
 public:
  explicit ClothFoldTask(const ClothFoldConfig& config);
  ~ClothFoldTask();
  ClothFoldTask(const ClothFoldTask&) = delete;
  ClothFoldTask& operator=(const ClothFoldTask&) = delete;

  /// Policy parameters of run(theta): per arm (left, right), per DoF (position x, y, z, then orientation vector),
  /// policyBasisSize() values each: the kernels' weights, then (FoldPolicy::WeightsAndGoals) the goal's weight.
  int parameterCount() const noexcept;
  /// Policy weights per (latent) DoF: kernels, plus one goal weight with FoldPolicy::WeightsAndGoals.
  int policyBasisSize() const noexcept;
  /// The DR-DMP parameters of the policy's forcing terms with `matrices` coordination matrices (the DMPs' kernels
  /// and transformation system, goal offsets as config().policy says).
  primitives::DrDmpParameters forcingParameters(int matrices) const;
  /// Writes the demonstration's DMPs as DMP files (primitives/dmp_yaml.hpp), `prefix` + "left.yaml" and
  /// + "right.yaml"; ClothFoldConfig::demonstration_files reads them back. \throws std::invalid_argument.
  void saveDemonstration(const std::string& prefix) const;
  /// The demonstration's two Cartesian DMPs (world frame) and their parameter vector.
  const std::vector<primitives::CartesianDmp>& demonstration() const noexcept;
  Eigen::VectorXd demonstrationParameters() const;
  /// The two DMPs with the demonstration's start and duration, the weights `theta`, and the goal theta's goal weights
  /// move it to (position + w_g / (α_z β_z), orientation vector likewise): where run(theta) takes the tools in the
  /// end (run() moves the goal there gradually, primitives::DrDmpParameters::goal_offsets).
  /// \throws std::invalid_argument for a wrong size.
  std::vector<primitives::CartesianDmp> dmps(const Eigen::VectorXd& theta) const;

  /// One rollout of the policy `theta` (same theta, same result: the simulation and its noise are reset).
  FoldRollout run(const Eigen::VectorXd& theta);
  /// One rollout of a coordinated policy (DR-DMP, thesis 7.24 and 7.39): the 12 forcing terms (per arm: position,
  /// then orientation vector) are f(x_t) = Ω^t W g(x_t) on the DMPs' phase and kernels, Ω^t blending the N_s
  /// matrices `coordination` (12 × r each) in time, W the r × kernels latent weights `latent_weights` (latent DoF
  /// by latent DoF). run(theta) is this with Ω = I. Sizes that do not fit, or non-finite values: InvalidPolicy.
  FoldRollout run(const std::vector<Eigen::MatrixXd>& coordination, const Eigen::VectorXd& latent_weights);
  /// As above with the simulation's sensor noise seeded by `seed` instead of the simulation file's seed (a rollout
  /// seed: the same policy and seed give the same rollout).
  FoldRollout run(const std::vector<Eigen::MatrixXd>& coordination, const Eigen::VectorXd& latent_weights,
                  std::uint32_t seed);

  /// Stepped rollouts, for step-by-step policies at the control rate (the Gymnasium joint-space environment):
  /// beginSteps(seed) builds rollout `seed` as run() does (its noise, the arms at startPositions(), the grasp:
  /// Ok or GraspFailed); each step() drives one control period; finishSteps() runs the rest (the driven periods
  /// left, the settling) with the references coming to rest at config().step_acceleration, scores the fold and ends
  /// it. The grippers open when run()'s would: at the planned release moved by the seed's noise, which may fall
  /// within the last driven periods (FoldNoise::release_time). run() ends a stepped rollout in progress. Not
  /// real-time (it records the rollout as run() does).
  FoldOutcome beginSteps(std::uint32_t seed);
  /// The periods a policy drives, hold_before + duration + hold_after at the simulation's step (run()'s release).
  int steppedPeriods() const;
  /// Whether step() may be called: a stepped rollout began, is Ok and has driven periods left.
  bool stepping() const noexcept;
  /// The next stepped period's index (periods run so far).
  int steppedPeriod() const noexcept;
  /// One period with both arms' commanded joint velocities `velocity` (left arm's 7, then the right's) [rad/s]: the
  /// reference's velocity moves towards them at most at config().step_acceleration, slowed so that it can stop at a
  /// position limit, and sets the next period's reference q + q̇ dt (never beyond a limit), which the controller
  /// tracks from then on (a streamed reference's one-period latency; the first period holds the start). Returns Ok or
  /// why the rollout ended: InvalidPolicy (wrong size, NaN/Inf), OutOfLimits (a velocity beyond the URDF's limit), or a
  /// failure of the period (ControllerFailed, SimulationDiverged). \throws std::logic_error without a stepped
  /// rollout or after its driven periods.
  FoldOutcome step(const Eigen::Ref<const Eigen::VectorXd>& velocity);
  /// Arm `arm`'s reference of the next stepped period. \throws std::out_of_range.
  const Eigen::VectorXd& steppedReference(int arm) const;
  /// Arm `arm`'s joint state as its controller measured it in the last stepped period, before that period's
  /// simulation step (the start, at rest, before the first): a period older than toolPosition() and
  /// clothVertices(), which are the simulation's now. \throws std::out_of_range.
  void measuredState(int arm, Eigen::VectorXd& position, Eigen::VectorXd& velocity) const;
  /// Arm `arm`'s tool position (world) and the cloth's mesh (world) in the simulation now.
  Eigen::Vector3d toolPosition(int arm) const;
  const Eigen::Matrix3Xd& clothVertices() const;
  /// The stepped rollout's end, as run() returns it (acceleration_cost of its references; no IK error).
  /// \throws std::logic_error without a stepped rollout.
  FoldRollout finishSteps();

  /// The joint references run() would follow for this policy (same values), without simulating: for a robot that
  /// executes the rollout through its own interfaces.
  FoldPlan plan(const std::vector<Eigen::MatrixXd>& coordination, const Eigen::VectorXd& latent_weights) const;
  /// Each arm's joint positions at the start of the fold (the tools at the cloth's far corners).
  const std::vector<Eigen::VectorXd>& startPositions() const noexcept;
  /// Arm `arm`'s kinematic model and its base in the world (0 left, 1 right): the model is the simulation's, valid
  /// until the next run() or beginSteps() builds a new one. \throws std::out_of_range.
  const kinematics::ChainModel& armModel(int arm) const;
  Eigen::Isometry3d basePose(int arm) const;
  /// The fold quality of a cloth mesh of this task's cloth (world frame, its nodes in the simulation's order).
  FoldQuality foldQualityOf(const Eigen::Matrix3Xd& vertices) const;
  /// The ideal fold of this task's cloth (idealFold(), world frame) and the cloth's triangles: the goal image's mesh.
  Eigen::Matrix3Xd idealFoldVertices() const;
  const Eigen::Matrix3Xi& clothTriangles() const;
  /// The flat cloth at rest (world frame) in the last rollout's simulation (before any, the simulation file's
  /// placement): what foldQualityOf() measures against.
  const Eigen::Matrix3Xd& clothRestVertices() const;
  /// The flat cloth at rest where rollout `seed` lays it (the simulation file's placement moved by
  /// drawFoldNoise(config().noise, seed)): that rollout's start, before it runs.
  Eigen::Matrix3Xd clothStartVertices(std::uint32_t seed) const;

  /// The DoF of the policy's forcing terms: 2 arms × (position + orientation vector).
  static constexpr int kDofs = 12;
  /// The DMPs' kernels and transformation system.
  const primitives::DmpParameters& dmpParameters() const noexcept;
  /// The demonstration in the DMPs' coordinates: samples × 12 (per arm the tool position, then
  /// vec(q_s⁻¹ ∗ q), thesis Sec. 7.2.3), every demonstrationStep() seconds; what a DR-DMP is fitted to.
  Eigen::MatrixXd demonstrationTrajectory() const;
  double demonstrationStep() const noexcept;

  const ClothFoldConfig& config() const noexcept;
  /// The simulation file's contents (table, cloth, arms).
  const sim::SimConfig& simConfig() const noexcept;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace bimanual_skills::tasks

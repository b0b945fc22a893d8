/// \file
/// The thesis' Chapter 4 experiments on the simulated plant (sim_benchmark --experiment friction|payload), and what
/// they share: a one-arm simulation of config/sim.yaml's left WAM with its true plant, the controller's model of it,
/// seeded excitation trajectories, logging them into a dynamics::FrictionLog and identifying friction from it with
/// the code of fit_friction.
#pragma once

#include "bimanual_skills/control/computed_torque_controller.hpp"
#include "bimanual_skills/dynamics/friction_identification.hpp"
#include "bimanual_skills/sim/bimanual_simulation.hpp"
#include "experiment_cli.hpp"

#include <Eigen/Core>

#include <string>
#include <vector>

namespace bimanual_skills::bench::sim_experiments {

using Rows = std::vector<JsonRow>;

/// Table 4.1 and the tracking comparison (thesis Sec. 4.2). Writes DIR/friction_errors.csv, friction_tracking.csv,
/// friction_example.csv and friction_<model>.yaml; appends its rows to `rows`.
void friction(const ExperimentOptions& options, Rows& rows);

/// Fig. 4.2: the vertical tool force estimated by our observer and KDL's ChainExternalWrenchEstimator for loads of
/// 0–2 kg. Writes DIR/payload.csv and payload_summary.csv; appends its rows to `rows`.
void payload(const ExperimentOptions& options, Rows& rows);

// ---- Shared by the two experiments ----

/// Control and observer rate of the thesis' WAM (500 Hz); the simulation runs at config/sim.yaml's 1 kHz.
constexpr double kControlPeriod = 0.002;

/// config/sim.yaml with only the left arm (no table, no cloth), its true plant from config/plant.yaml (or the file
/// given to usePlantFile), seeded; the arm of the robot file given to useRobotFile instead of the WAM's.
sim::SimConfig oneArmConfig(const ExperimentOptions& options);

/// Makes the friction experiment identify another robot's arm (sim_benchmark --robot FILE): its plant, gains and
/// excitation then come from its robot file and model (excitationRanges, loggerGains). Empty: the WAM of
/// config/sim.yaml with the thesis' settings.
void useRobotFile(const std::string& path);
/// That file ("" for the WAM).
std::string& robotFile();
/// Where the friction experiment also writes its advanced model (sim_benchmark --friction-out FILE, e.g. the file a
/// robot file's arm names); "" for nowhere else.
std::string& frictionOut();

/// Makes the friction and payload experiments use another true plant (sim_benchmark --plant FILE), e.g. to find
/// out which of the plant's effects the models miss. Empty: config/plant.yaml.
void usePlantFile(const std::string& path);
/// The arm of config/sim.yaml the friction and payload experiments simulate (default "left").
void useArm(const std::string& name);
/// Its name.
std::string& armName();

/// What the controllers know of the arm: the simulation's rigid-body model with the data-sheet reflected rotor
/// inertias (no friction: that is identified). The robot file's plant's rotor inertias stand for the data sheet's
/// (for the WAM those of shared/reference/wam.md), whatever plant --plant gives the simulation.
kinematics::ChainModel controllerModel(const sim::BimanualSimulation& simulation);

/// Computed-torque gains of the low-gain (compliant) controller of Sec. 4.2: the robot file's (the WAM's are about a
/// tenth of libbarrett's stiff position gains 900, 2500, 600, 500, 50, 50, 8, as in test_control).
control::ComputedTorqueGains lowGains(const sim::SimConfig& config);

/// Gains of the controller that logs the excitation: stiff, as the thesis logged under the WAM's PID. The WAM's
/// (400, 400, 200, 150, 30, 30, 6; 40, 40, 15, 10, 1.5, 1.5, 0.2); another robot's: 3 kp and √3 kv of its
/// robot file (√3 times its bandwidth at the same damping ratio).
control::ComputedTorqueGains loggerGains(const sim::SimConfig& config);

/// Where the excitation swings each joint: centres drawn in [centre_low, centre_high], amplitudes up to
/// `amplitude` [rad]; `pairs` the cable-coupled joints (0-based; the plant's differentials), each excited together.
struct ExcitationRanges {
  Eigen::VectorXd centre_low, centre_high, amplitude;
  std::vector<std::pair<int, int>> pairs;
};
/// The WAM's ranges (within its limits, away from self-collisions) unless useRobotFile named another robot, whose
/// ranges come from its joint limits: amplitude a = min(1.2, 0.2 r) of the range r, centres at least 0.15 r + a from
/// either limit (the middle when the range is too short).
ExcitationRanges excitationRanges(const sim::SimConfig& config);

/// Excitation of the identification (thesis Sec. 4.2.2, "oscillation movements at different speeds, moving joints
/// individually at different positions and also with coupled movements"): every joint i follows
/// q_i = c_i + a_i ρ(t) sin(2π f_i t + φ_i), ρ a one-second (1 − cos)/2 ramp in and out so that the motion starts and
/// ends at rest. In a `joint` trajectory that joint swings widely and fast while the others swing less and slower; in a
/// `coupled` trajectory both joints of a cable pair (2–3 or 5–6) swing at speeds whose ratio crosses 1, so the pair's
/// fast joint changes; in `all` every joint swings widely.
struct ExcitationTrajectory {
  Eigen::VectorXd centre, amplitude, frequency, phase;  ///< c [rad], a [rad], f [Hz], φ [rad] per joint.
  double length = 10.0;                                 ///< [s]
  std::string kind;                                     ///< "joint 3", "coupled 2-3", "all".
  std::vector<int> excited;                             ///< Joints (0-based) this trajectory excites.

  /// q_d, q̇_d, q̈_d at time t ∈ [0, length] (at rest outside).
  void evaluate(double t, Eigen::VectorXd& q, Eigen::VectorXd& qd, Eigen::VectorXd& qdd) const;
};

/// The seeded excitation set: for each joint one `joint` trajectory, one `coupled` per cable pair and one `all`,
/// `repeats` times with fresh draws (centres, amplitudes, speeds) within `ranges`.
std::vector<ExcitationTrajectory> excitationSet(std::uint32_t seed, int repeats, double length,
                                                const ExcitationRanges& ranges);

/// Identification data: a log of excitation runs, the friction observed in it (2.12) and sign(q̈).
struct IdentificationData {
  dynamics::FrictionLog log;
  Eigen::MatrixXd friction, signs;         ///< observedFriction(controller model, log), accelerationSigns(log, logged).
  std::vector<int> first_sample;           ///< Index of each trajectory's first sample, plus the end.
  int train_end = 0;                       ///< Samples before it are training data, from it validation data.
  std::vector<std::pair<int, int>> pairs;  ///< The arm's cable-coupled joints (ExcitationRanges::pairs).
};

/// Runs the training and then the validation trajectories one after the other on the arm (reset to each start at
/// rest) under a stiff computed-torque controller without friction compensation, logging every control period the
/// measured q, q̇ and the applied torque. q̈ comes offline from the zero-phase low-passed q̇ (8 Hz), and q, q̇, τ go
/// through the same filter, as a logger would process a real arm's data; the first and last 0.25 s of each run are
/// dropped (filter ends). Prints a progress line per run.
IdentificationData logExcitation(const ExperimentOptions& options, const std::vector<ExcitationTrajectory>& training,
                                 const std::vector<ExcitationTrajectory>& validation);

/// fitFriction as fit_friction runs it (the arm's coupled pairs, 2-3 and 5-6 on the WAM, ε = 0.05, sign of the logged
/// q̈), fitted on the training samples; fit.test holds the errors over all validation samples.
dynamics::FrictionFit identifyFriction(const IdentificationData& data, dynamics::FrictionModelType type,
                                       std::uint32_t seed, bool quick);

/// The advanced model (4.16) identified for this seed and mode: the friction experiment's when it ran in this
/// process (it calls rememberAdvancedFriction), otherwise identified here from the same training runs.
dynamics::FrictionModel advancedFriction(const ExperimentOptions& options);
void rememberAdvancedFriction(const ExperimentOptions& options, const dynamics::FrictionModel& model);

/// The excitation of the friction experiment: 3 training sets and 2 validation sets (fresh draws) of 15 s runs;
/// --quick: one of each, 4 s runs.
std::vector<ExcitationTrajectory> trainingRuns(const ExperimentOptions& options);
std::vector<ExcitationTrajectory> validationRuns(const ExperimentOptions& options);

}  // namespace bimanual_skills::bench::sim_experiments

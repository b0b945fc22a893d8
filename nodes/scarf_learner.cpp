// scarf_learner: the simulated WAM learns to put a scarf round a mannequin's neck (thesis Sec. 4.3.1) while rviz
// watches. A thin shell over rollout::DmpLearner and rollout::ScarfRolloutTask: it runs the learning (on threads
// here or on rollout workers), publishes each rollout (scarf, tool path, camera image), prints the progress, and
// writes the results and the pictures of Figs. 4.7-4.9.
#include "bimanual_skills/rollout/scarf_learning.hpp"
#include "bimanual_skills/ros_layer/camera_messages.hpp"
#include "bimanual_skills/ros_layer/parameters.hpp"
#include "bimanual_skills/ros_layer/robot/scarf_on_robot.hpp"
#include "cli/pinned_numerics.hpp"
#include "io/summary_json.hpp"
#include "io/yaml_io.hpp"
#include "learner_shell.hpp"
#include "node_cli.hpp"
#include "scene_markers.hpp"

#include <ros/package.h>
#include <ros/ros.h>
#include <sensor_msgs/JointState.h>
#include <tf2_ros/static_transform_broadcaster.h>
#include <visualization_msgs/MarkerArray.h>
#include <yaml-cpp/yaml.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <string>
#include <vector>

namespace bs = bimanual_skills;
namespace br = bimanual_skills::rollout;
namespace bt = bimanual_skills::tasks;

namespace {

const char* const kUsage =
    "usage: rosrun bimanual_skills scarf_learner [_config:=FILE] [_out:=DIR] [_jobs:=N] [_runs:=N] [_updates:=N]\n"
    "                                           [_rollouts:=N] [_seed:=S] [_torque_weight:=W]\n"
    "                                           [_replay_best:=true|false] [_backend:=sim|ros [robot parameters]]\n"
    "                                           [_worker_namespace:=NS | _workers:=NAME,NAME,...] "
    "[_worker_timeout:=S]\n"
    "\n"
    "The simulated WAM learns to put a scarf round a mannequin's neck (thesis Sec. 4.3.1, Figs. 4.7-4.9): a\n"
    "joint-space DMP (25 kernels per joint) fitted to a poor demonstration, run by the computed-torque controllers\n"
    "with the friction model, costed by the DMP's accelerations, the disturbance observer's interaction torques and a\n"
    "colour camera (HSV segmentation of scarf and nose mark), learned by PI2-CMA on a second layer of Gaussians (the\n"
    "thesis' setting; REPS/IDR-DMP and CMA-ES beside it). The scarf mesh's ground truth (wound round the neck,\n"
    "hanging right and not left) is recorded beside the cost and never learned from. Rollouts run in parallel, are\n"
    "written to DIR as they finish, and a restarted run resumes where it stopped.\n"
    "\n"
    "Parameters (private):\n"
    "  ~config       learning file (default: the package's config/scarf_learning.yaml)\n"
    "  ~out          results directory (default: scarf_learning in the working directory)\n"
    "  ~jobs, ~runs, ~updates, ~rollouts, ~seed, ~algorithms  instead of the learning file's (a list of\n"
    "                algorithms, e.g. rosparam set scarf_learner/algorithms \"[PI2-CMA, IDR-DMP_CMU]\")\n"
    "  ~torque_weight  weight of the observer's term c_torque instead of the file's (0: the cost without it)\n"
    "  ~write_scarf_files PREFIX  with ~robot (a robot file): write the learning files of the scarf on that pair\n"
    "                and exit: PREFIX_scarf_learning.yaml, _scarf_sim.yaml, _scarf_start.yaml and _mannequin.yaml,\n"
    "                ~config's with the scene (mannequin, scarf, camera, demonstration) turned and shifted to stand\n"
    "                to the holding arm as it stands to the WAM's, and the arm's start solved by global IK\n"
    "                (tasks::scarfPlacementOn, scarfStartOn); config/robots/offset_wrist_scarf_*.yaml come from it\n"
    "  ~replay_best  after learning, replay the best final policy on the topics in a loop until shut down\n"
    "                (default false: exit when done)\n"
    "  ~worker_namespace, ~workers  run the rollouts on rollout workers (task scarf; they read ~config on their\n"
    "                host); ~worker_timeout [s] (default 60). Not with ~torque_weight (set it in the file)\n"
    "  ~backend      sim (default): the rollouts run in this process's own simulation (or on rollout workers);\n"
    "                ros: one at a time on a robot through its ROS interfaces only: bullet_sim's scarf scene\n"
    "                (roslaunch bimanual_skills scarf.launch backend:=ros) or a real arm. Each rollout: "
    "~reset_service\n"
    "                (the arm at the start file's posture, the scarf in its tool), the policy as one\n"
    "                ARM/follow_joint_trajectory goal, ~grasp_service opens the tool at the planned instant, the\n"
    "                scarf settles; c_torque from ARM/estimated_external_torque (the arm's controller's observer),\n"
    "                c_cam from ~camera's colour image (its CameraInfo and pose on tf must be the start file's\n"
    "                camera). A failure is a failed rollout with its reason; a robot's is retried (robot_faults.csv).\n"
    "  robot parameters (with ~backend ros): ~reset_service (default bullet_sim/reset), ~grasp_service\n"
    "                (bullet_sim/grasp), ~pause_service, ~step_service (bullet_sim/pause, /step; \"\" on a robot),\n"
    "                ~arm_namespace (left), ~camera (rgbd; raw images rectified with their camera_info's D, R, P),\n"
    "                ~camera_depth (depth or depth_registered), ~register_depth (false), ~cloth_topic\n"
    "                (bullet_sim/cloth: the scarf's truth; \"\":\n"
    "                none), ~world_digest_param, ~world_frame (world), ~trajectory_rate (100 Hz), ~start_delay\n"
    "                (0.5 s), ~move_time (2 s), ~move_before_reset (false; true for a robot whose reset leaves the\n"
    "                arm where it is: it moves to the start first and the reset lays the scarf in its tool),\n"
    "                ~robot_timeout (30 s: every wait, service calls included),\n"
    "                ~reset_timeout (660 s)\n"
    "\n"
    "Writes into DIR: rollouts.csv, rollout_parameters.csv (every rollout as it finishes), epochs.csv, "
    "robot_faults.csv,\n"
    "summary.json (one row per algorithm, run and epoch), camera.csv (the camera's measures of the pictures),\n"
    "initial.png (the demonstration's final camera image), final_runs/ALGORITHM_run_K.png (every run's final\n"
    "policy), filmstrip.png (the best final policy, every second of the motion; not with _backend:=ros, whose\n"
    "pictures are the robot camera's: robot_images/ALGORITHM_run_K_epoch_E.png of every noise-free policy); plot with\n"
    "scripts/plot_scarf_learning.py DIR (learning_curve.png, Fig. 4.8; camera_views.png, Fig. 4.7).\n"
    "\n"
    "Topics: /joint_states (sensor_msgs/JointState: the last rollout's final pose, or the replay; not with\n"
    "  _backend:=ros, whose robot publishes its own), ~scene\n"
    "  (visualization_msgs/MarkerArray: the mannequin), ~scarf (Marker TRIANGLE_LIST: the last\n"
    "  rollout's final scarf), ~tool_paths (MarkerArray: the last rollouts' tool paths, red = worst to green = best),\n"
    "  ~camera/image_raw with ~camera/camera_info (the last rollout's final colour image; frame scarf_camera on\n"
    "  /tf_static), ~camera/depth/image_raw.\n";

constexpr const char* kCameraFrame = "scarf_camera";
constexpr std::size_t kPathsShown = 12;

class ScarfLearnerNode {
 public:
  ScarfLearnerNode() : private_node_("~"), parameters_(private_node_, "scarf_learner") {
    const std::string package = ros::package::getPath("bimanual_skills");
    config_path_ = parameters_.text("config", package + "/config/scarf_learning.yaml");
    out_ = parameters_.text("out", "scarf_learning");
    replay_best_ = parameters_.boolean("replay_best", false);
    config_ = br::ScarfLearningConfig::fromYamlFile(config_path_);
    br::DmpLearningConfig& l = config_.learning;
    bs::nodes::readLearningParameters(parameters_, l);
    const bool reweighted = parameters_.has("torque_weight");
    config_.task.torque_weight = parameters_.number("torque_weight", config_.task.torque_weight, 0.0, 1e6);
    task_ = std::make_unique<br::ScarfRolloutTask>(config_.task);
    l.validate(task_->task().dofs());
    std::string workers;
    std::unique_ptr<br::Evaluator> evaluator =
        bs::nodes::workerDispatcher(parameters_, private_node_, "scarf", config_path_,
                                    br::ScarfRolloutTask::names().size(), "scarf_learner", workers);
    if (evaluator && reweighted) {
      throw std::invalid_argument(
          "~torque_weight is not for rollout workers: they read the learning file, set it there");
    }
    if (parameters_.text("backend", "sim", {"sim", "ros"}) == "ros") {
      if (evaluator) throw std::invalid_argument("~backend ros runs the rollouts on the robot, not on workers");
      evaluator = makeRobotBackend();
    }
    parameters_.warnUnknown();
    if (!evaluator) {
      evaluator = std::make_unique<br::ParallelEvaluator>(
          [this] { return std::make_unique<br::ScarfRolloutTask>(config_.task); }, l.jobs);
    }
    scene_publisher_ = private_node_.advertise<visualization_msgs::MarkerArray>("scene", 1, true);
    scarf_publisher_ = private_node_.advertise<visualization_msgs::Marker>("scarf", 1, true);
    path_publisher_ = private_node_.advertise<visualization_msgs::MarkerArray>("tool_paths", 1, true);
    camera_ = bs::ros_layer::RgbdPublisher(private_node_, true);
    if (!robot_backend_) joint_publisher_ = node_.advertise<sensor_msgs::JointState>("joint_states", 10, true);
    publishScene();

    br::DmpLearningObserver observer;
    observer.rollout = [this](const br::DmpRolloutRecord& record, br::RolloutTask* task) { onRollout(record, task); };
    observer.epoch = [this](const br::DmpEpochStats& s) { onEpoch(s); };
    observer.robot_fault = [](const br::DmpRolloutRecord& r, int attempt, const std::string& reason, bool retry) {
      ROS_WARN("scarf_learner: %s run %d epoch %d rollout %d failed on the robot (attempt %d): %s%s",
               r.algorithm.c_str(), r.run, r.epoch, r.index, attempt, reason.c_str(),
               retry ? "; running it again" : "");
    };
    observer.stop = [] { return !ros::ok(); };
    learner_ =
        std::make_unique<br::DmpLearner>(br::scarfTaskModel(task_->task()), l, out_, std::move(evaluator), observer);
  }

  void run() {
    const br::DmpLearningConfig& l = config_.learning;
    std::printf(
        "scarf_learner: %zu algorithm(s) x %d run(s) x %d updates x %d rollouts, seed %u, d_ref %.1f px, "
        "torque weight %g, into %s\n",
        l.algorithms.size(), l.runs, l.updates, l.rollouts, l.seed, task_->task().config().camera.d_ref,
        config_.task.torque_weight, out_.c_str());
    std::fflush(stdout);
    const br::DmpLearningResult result = learner_->learn();
    std::printf("scarf_learner: %d rollouts run, %d taken from %s, %d robot faults, %.0f s\n", result.ran,
                result.resumed, out_.c_str(), result.robot_faults, result.seconds);
    writeSummary(result);
    const br::DmpRolloutRecord* best = writePictures(result);
    if (replay_best_ && best != nullptr && !robot_backend_) replay(*best);
  }

 private:
  /// The rollouts on the robot through ROS, one at a time.
  std::unique_ptr<br::Evaluator> makeRobotBackend() {
    bs::ros_layer::ScarfRobotInterfaces robot;
    bs::nodes::readRobotInterfaces(parameters_, robot);
    robot.arms = {parameters_.text("arm_namespace", robot.arms.front())};
    robot.world_frame = parameters_.text("world_frame", robot.world_frame);
    robot.trajectory_rate = parameters_.number("trajectory_rate", robot.trajectory_rate, 1.0, 1000.0);
    robot.start_delay = parameters_.number("start_delay", robot.start_delay, 0.0, 10.0);
    robot.move_time = parameters_.number("move_time", robot.move_time, 0.1, 60.0);
    robot.move_before_reset = parameters_.boolean("move_before_reset", robot.move_before_reset);
    robot.validate();
    robot_backend_ = true;
    const bt::ScarfTaskConfig task = config_.task;
    return std::make_unique<br::ParallelEvaluator>(
        [task, robot] { return std::make_unique<bs::ros_layer::ScarfOnRobotTask>(task, robot); }, 1);
  }

  void publishScene() {
    visualization_msgs::MarkerArray scene;
    const std::vector<bs::sim::Obstacle>& obstacles = task_->task().simConfig().obstacles;
    for (std::size_t k = 0; k < obstacles.size(); ++k) {
      scene.markers.push_back(bs::nodes::obstacleMarker(obstacles[k], static_cast<int>(k), ros::Time()));
    }
    scene_publisher_.publish(scene);
    const bs::vision::PinholeCamera& camera = task_->task().camera();
    broadcaster_.sendTransform(bs::ros_layer::cameraTransform(camera, "world", kCameraFrame, ros::Time(0)));
  }

  void onRollout(const br::DmpRolloutRecord& record, br::RolloutTask* task) {
    if (record.result.trajectory.rows() == 3 && record.result.trajectory.cols() > 1) {
      paths_.push_back({record.result.reward, record.result.trajectory});
      if (paths_.size() > kPathsShown) paths_.erase(paths_.begin());
      publishPaths();
    }
    const auto* scarf = dynamic_cast<br::RecordedScarfTask*>(task);
    if (scarf == nullptr) return;
    const bt::ScarfRollout& r = scarf->lastRollout();
    if (robot_backend_ && record.kind == br::RolloutKind::Policy && !r.bgr.empty()) {
      // The robot camera's image of every noise-free policy: the run's pictures.
      const std::string name = "robot_images/" + bs::nodes::fileName(record.algorithm) + "_run_" +
                               std::to_string(record.run) + "_epoch_" + std::to_string(record.epoch) + ".png";
      std::filesystem::create_directories(out_ + "/robot_images");
      cv::imwrite(out_ + "/" + name, r.bgr);
    }
    if (r.cloth_vertices.cols() > 0) {
      scarf_publisher_.publish(bs::nodes::clothMarker(r.cloth_vertices, task_->task().scarfTriangles(), ros::Time()));
    }
    // The robot publishes its own joint states.
    if (r.joint_path.cols() > 0 && !robot_backend_) publishJoints(r.joint_path.col(r.joint_path.cols() - 1));
    if (!r.bgr.empty()) {
      std_msgs::Header header;
      header.stamp = ros::Time::now();
      header.frame_id = kCameraFrame;
      const cv::Mat depth(r.bgr.rows, r.bgr.cols, CV_32FC1, cv::Scalar(std::numeric_limits<float>::quiet_NaN()));
      camera_.publish(
          bs::ros_layer::RgbdFrame(header, r.bgr, depth, bs::ros_layer::cameraInfo(task_->task().camera(), header)));
    }
  }

  /// The holding arm at `q`, the others at their start.
  void publishJoints(const Eigen::VectorXd& q) {
    const bt::ScarfTask& task = task_->task();
    sensor_msgs::JointState state;
    state.header.stamp = ros::Time::now();
    for (std::size_t a = 0; a < task.jointNames().size(); ++a) {
      const Eigen::VectorXd& position = static_cast<int>(a) == task.arm() ? q : task.starts()[a];
      for (std::size_t j = 0; j < task.jointNames()[a].size(); ++j) {
        state.name.push_back(task.jointNames()[a][j]);
        state.position.push_back(position[static_cast<Eigen::Index>(j)]);
      }
    }
    joint_publisher_.publish(state);
  }

  /// The best final policy again with the scarf recorded at 10 Hz, played on the topics until shut down.
  void replay(const br::DmpRolloutRecord& best) {
    bt::ScarfTaskConfig config = config_.task;
    config.cloth_rate = 10.0;
    bt::ScarfTask task(config);
    const bt::ScarfRollout r = task.run(best.coordination, best.weights, best.seed);
    if (r.cloth_frames.empty() || r.path_times.size() == 0) return;
    std::printf("scarf_learner: replaying %s run %d's final policy (cost %.3f) until shut down\n",
                best.algorithm.c_str(), best.run, r.cost);
    std::fflush(stdout);
    ros::WallRate rate(10.0);
    while (ros::ok()) {
      for (std::size_t k = 0; k < r.cloth_frames.size() && ros::ok(); ++k) {
        const double t = r.cloth_times[static_cast<Eigen::Index>(k)];
        Eigen::Index sample = 0;
        while (sample + 1 < r.path_times.size() && r.path_times[sample + 1] <= t) ++sample;
        publishJoints(r.joint_path.col(sample));
        scarf_publisher_.publish(bs::nodes::clothMarker(r.cloth_frames[k], task.scarfTriangles(), ros::Time()));
        rate.sleep();
      }
      ros::WallDuration(1.0).sleep();
    }
  }

  void publishPaths() { path_publisher_.publish(bs::nodes::rankedPathMarkers(paths_, 0.004, 0.8f, ros::Time())); }

  void onEpoch(const br::DmpEpochStats& s) {
    const br::DmpLearningConfig& l = config_.learning;
    std::printf(
        "scarf_learner: %s run %d/%d epoch %d/%d: noise-free policy cost %.3f%s%s; rollouts %.3f +- %.3f, "
        "%d/%d wound and hanging right, %d failed\n",
        s.algorithm.c_str(), s.run + 1, l.runs, s.epoch, l.updates, -s.policy_reward,
        s.policy_failed ? " (failed)" : "", s.policy_success ? " (wound, hanging right)" : "", -s.mean_reward,
        s.std_reward, s.successes, l.rollouts, s.failures);
    std::fflush(stdout);
  }

  void writeSummary(const br::DmpLearningResult& result) const {
    const std::vector<bs::io::JsonRow> rows =
        bs::nodes::epochRows(result, br::ScarfRolloutTask::names(), {"cost", "policy_success", "rollout_successes"});
    bs::io::writeSummaryJson(out_ + "/summary.json",
                             {"scarf_learner", "scarf", config_.learning.seed, false, bs::cli::numericsState()}, rows);
  }

  /// The demonstration's and every run's final policy again (the same rollouts: same policy, same seed), with the
  /// scarf recorded for the filmstrip of the best.
  const br::DmpRolloutRecord* writePictures(const br::DmpLearningResult& result) {
    if (result.runs.empty()) return nullptr;
    if (robot_backend_) {
      writeRobotPictures(result);
      return nullptr;
    }
    bt::ScarfTaskConfig pictures = config_.task;
    pictures.cloth_rate = 1.0;
    bt::ScarfTask task(pictures);
    std::filesystem::create_directories(out_ + "/final_runs");
    std::ofstream csv(out_ + "/camera.csv");
    csv << "picture,algorithm,run,cost,d,d_ref,hanging,right_pixels,left_pixels,c_cam,nose_u,nose_v,success\n";
    const auto shoot = [&](const br::DmpRolloutRecord& record, const std::string& name) {
      const bt::ScarfRollout r = task.run(record.coordination, record.weights, record.seed);
      if (!r.bgr.empty()) cv::imwrite(out_ + "/" + name, r.bgr);
      csv << name << ',' << record.algorithm << ',' << record.run << ',' << r.cost << ',' << r.camera.d << ','
          << task.config().camera.d_ref << ',' << r.camera.hanging << ',' << r.camera.right_pixels << ','
          << r.camera.left_pixels << ',' << r.camera.c_cam << ',' << r.camera.nose_u << ',' << r.camera.nose_v << ','
          << (r.truth.success ? 1 : 0) << '\n';
      return r;
    };
    shoot(result.runs.front().initial_policy, "initial.png");
    const br::DmpRunResult* best = nullptr;
    for (const br::DmpRunResult& run : result.runs) {
      shoot(run.final_policy,
            "final_runs/" + bs::nodes::fileName(run.algorithm) + "_run_" + std::to_string(run.run) + ".png");
      if (best == nullptr || run.final_policy.result.reward > best->final_policy.result.reward) best = &run;
    }
    // The best final policy's filmstrip (Fig. 4.9): the camera's view every second, cut to the mannequin and scarf
    // (the image's middle half across, the lower five sixths).
    const bt::ScarfRollout film =
        task.run(best->final_policy.coordination, best->final_policy.weights, best->final_policy.seed);
    std::vector<cv::Mat> frames;
    for (const Eigen::Matrix3Xd& vertices : film.cloth_frames) {
      const cv::Mat image = task.cameraImage(vertices);
      cv::Mat frame = image(cv::Rect(image.cols / 4, image.rows / 6, image.cols / 2, image.rows * 5 / 6)).clone();
      cv::putText(frame, "t = " + std::to_string(static_cast<int>(frames.size())) + " s", cv::Point(10, 28),
                  cv::FONT_HERSHEY_SIMPLEX, 0.7, cv::Scalar(255, 255, 255), 2);
      frames.push_back(frame);
    }
    if (!frames.empty()) {
      const std::size_t columns = 6;
      while (frames.size() % columns != 0) frames.push_back(cv::Mat::zeros(frames.front().size(), CV_8UC3));
      std::vector<cv::Mat> rows;
      for (std::size_t k = 0; k < frames.size(); k += columns) {
        cv::Mat row;
        cv::hconcat(std::vector<cv::Mat>(frames.begin() + static_cast<long>(k),
                                         frames.begin() + static_cast<long>(k + columns)),
                    row);
        rows.push_back(row);
      }
      cv::Mat strip;
      cv::vconcat(rows, strip);
      cv::imwrite(out_ + "/filmstrip.png", strip);
    }
    std::printf("scarf_learner: pictures in %s (initial.png, final_runs/, filmstrip.png of %s run %d, camera.csv)\n",
                out_.c_str(), best->algorithm.c_str(), best->run);
    return &best->final_policy;
  }

  /// With the robot backend: initial.png and final_runs/ are the robot camera's images of those policies (as
  /// taken, from robot_images/), camera.csv their camera measures.
  void writeRobotPictures(const br::DmpLearningResult& result) const {
    std::filesystem::create_directories(out_ + "/final_runs");
    std::ofstream csv(out_ + "/camera.csv");
    csv << "picture,algorithm,run,cost,d,d_ref,hanging,right_pixels,left_pixels,c_cam,nose_u,nose_v,success\n";
    const std::vector<std::string> terms = br::ScarfRolloutTask::names();
    const auto success = std::find(terms.begin(), terms.end(), "success") - terms.begin();
    const auto copy = [&](const br::DmpRolloutRecord& record, const std::string& name) {
      const std::string taken = out_ + "/robot_images/" + bs::nodes::fileName(record.algorithm) + "_run_" +
                                std::to_string(record.run) + "_epoch_" + std::to_string(record.epoch) + ".png";
      const cv::Mat bgr = cv::imread(taken);
      if (bgr.empty()) {
        ROS_WARN("scarf_learner: no robot image %s (a resumed rollout's, or a failed one's)", taken.c_str());
        return;
      }
      cv::imwrite(out_ + "/" + name, bgr);
      const bt::ScarfCameraConfig& camera = task_->task().config().camera;  // d_ref and the level of this camera
      const bt::ScarfCameraTerms c = bt::scarfCameraTerms(bgr, camera);
      csv << name << ',' << record.algorithm << ',' << record.run << ',' << -record.result.reward << ',' << c.d << ','
          << camera.d_ref << ',' << c.hanging << ',' << c.right_pixels << ',' << c.left_pixels << ',' << c.c_cam << ','
          << c.nose_u << ',' << c.nose_v << ','
          << (success < record.result.terms.size() ? record.result.terms[success] : 0.0) << '\n';
    };
    copy(result.runs.front().initial_policy, "initial.png");
    for (const br::DmpRunResult& run : result.runs) {
      copy(run.final_policy,
           "final_runs/" + bs::nodes::fileName(run.algorithm) + "_run_" + std::to_string(run.run) + ".png");
    }
    std::printf(
        "scarf_learner: the robot camera's pictures in %s (initial.png, final_runs/, robot_images/, camera.csv)\n",
        out_.c_str());
  }

  ros::NodeHandle node_, private_node_;
  bs::ros_layer::ParameterReader parameters_;
  std::string config_path_, out_;
  bool replay_best_ = false, robot_backend_ = false;
  br::ScarfLearningConfig config_;
  std::unique_ptr<br::ScarfRolloutTask> task_;
  std::unique_ptr<br::DmpLearner> learner_;
  ros::Publisher scene_publisher_, scarf_publisher_, path_publisher_, joint_publisher_;
  bs::ros_layer::RgbdPublisher camera_;
  tf2_ros::StaticTransformBroadcaster broadcaster_;
  std::vector<std::pair<double, Eigen::Matrix3Xd>> paths_;
};

}  // namespace

/// ~write_scarf_files PREFIX: the learning files of ~config placed for ~robot (see the usage).
void writeScarfFiles(const std::string& prefix) {
  bs::ros_layer::ParameterReader parameters(ros::NodeHandle("~"), "scarf_learner");
  const std::string config_path =
      parameters.text("config", ros::package::getPath("bimanual_skills") + "/config/scarf_learning.yaml");
  const br::ScarfLearningConfig config = br::ScarfLearningConfig::fromYamlFile(config_path);
  if (!parameters.has("robot")) throw std::invalid_argument("~write_scarf_files needs ~robot (a robot file)");
  const std::string robot = std::filesystem::absolute(parameters.text("robot", "")).string();
  const bt::ScarfPlacement placement = bt::scarfPlacementOn(config.task, robot);
  const Eigen::VectorXd start = bt::scarfStartOn(config.task, robot);

  const std::filesystem::path base = std::filesystem::absolute(prefix);
  const std::string stem = base.filename().string();
  const auto file = [&](const std::string& name) { return base.parent_path() / (stem + "_" + name + ".yaml"); };
  const auto number = [](double v) {
    char text[32];
    std::snprintf(text, sizeof text, "%.6f", std::abs(v) < 5e-7 ? 0.0 : v);
    return std::string(text);
  };
  const auto list = [&](const Eigen::Vector3d& v) {
    YAML::Node out(YAML::NodeType::Sequence);
    out.SetStyle(YAML::EmitterStyle::Flow);
    for (int i = 0; i < 3; ++i) out.push_back(number(v[i]));
    return out;
  };
  const auto vector = [](const YAML::Node& node) {
    return Eigen::Vector3d(node[0].as<double>(), node[1].as<double>(), node[2].as<double>());
  };
  // A body's pose ({xyz, rpy}) placed: its position moved, its yaw turned.
  const auto place = [&](YAML::Node body) {
    body["xyz"] = list(placement.apply(body["xyz"] ? vector(body["xyz"]) : Eigen::Vector3d::Zero()));
    Eigen::Vector3d rpy = body["rpy"] ? vector(body["rpy"]) : Eigen::Vector3d::Zero();
    rpy.z() += placement.yaw;
    body["rpy"] = list(rpy);
  };
  const auto write = [&](const std::filesystem::path& path, const std::string& what, const YAML::Node& node) {
    std::ofstream out(path);
    out << "# " << what << ": " << std::filesystem::path(config_path).filename().string() << " placed for "
        << std::filesystem::path(robot).filename().string() << "\n# (the scene turned by " << number(placement.yaw)
        << " rad about z and shifted by [" << number(placement.shift.x()) << ", " << number(placement.shift.y()) << ", "
        << number(placement.shift.z())
        << "] m,\n# so that it stands to the arm as to the WAM's). Written by scarf_learner _write_scarf_files:="
           "PREFIX _robot:=FILE.\n"
        << YAML::Dump(node) << "\n";
    if (!out.flush()) throw std::runtime_error("cannot write " + path.string());
    std::printf("scarf_learner: wrote %s\n", path.c_str());
  };

  const YAML::Node learning_in = YAML::LoadFile(config_path);
  const YAML::Node sim_in = YAML::LoadFile(config.task.sim_config);
  const std::string obstacles_name =
      sim_in["obstacles"] && sim_in["obstacles"].IsScalar() ? sim_in["obstacles"].as<std::string>() : std::string();
  YAML::Node obstacles =
      obstacles_name.empty()
          ? YAML::Clone(sim_in["obstacles"])
          : YAML::Clone(YAML::LoadFile(bs::io::resolvePath(config.task.sim_config, obstacles_name))["obstacles"]);
  for (YAML::Node o : obstacles) place(o);
  YAML::Node scene;
  scene["obstacles"] = obstacles;
  write(file("mannequin"), "The scarf's mannequin", scene);

  YAML::Node sim = YAML::Clone(sim_in);
  sim["robot"] = std::filesystem::path(robot).lexically_relative(base.parent_path()).string();
  sim["obstacles"] = stem + "_mannequin.yaml";
  if (sim["cloth"]) place(sim["cloth"]);
  write(file("scarf_sim"), "The scarf's scene", sim);

  YAML::Node start_file = YAML::Clone(YAML::LoadFile(config.task.start));
  YAML::Node posture(YAML::NodeType::Sequence);
  posture.SetStyle(YAML::EmitterStyle::Flow);
  for (Eigen::Index i = 0; i < start.size(); ++i) posture.push_back(number(start[i]));
  start_file["initial_positions"] = YAML::Node(YAML::NodeType::Map);
  start_file["initial_positions"][config.task.arm] = posture;
  for (const char* point : {"rgbd_eye", "rgbd_target"}) {
    if (start_file[point]) start_file[point] = list(placement.apply(vector(start_file[point])));
  }
  write(file("scarf_start"), "The scarf's start (bullet_sim overrides)", start_file);

  YAML::Node learning = YAML::Clone(learning_in);
  learning["sim"] = stem + "_scarf_sim.yaml";
  learning["start"] = stem + "_scarf_start.yaml";
  if (learning["task"] && learning["task"]["demo_waypoints"]) {
    YAML::Node waypoints(YAML::NodeType::Sequence);
    for (const Eigen::Vector3d& w : config.task.demo_waypoints) waypoints.push_back(list(placement.apply(w)));
    learning["task"]["demo_waypoints"] = waypoints;
  }
  write(file("scarf_learning"), "Learning the scarf", learning);
}

int main(int argc, char** argv) {
  bimanual_skills::cli::pinNumerics(argv);
  bs::nodes::handleCommandLine(argc, argv, kUsage);
  ros::init(argc, argv, "scarf_learner");
  const ros::NodeHandle keep_alive;
  try {
    if (std::string prefix; ros::param::get("~write_scarf_files", prefix)) {
      writeScarfFiles(prefix);
      return 0;
    }
    ScarfLearnerNode node;
    node.run();
  } catch (const std::exception& e) {
    if (!ros::ok() && std::string(e.what()) == "stopped") {
      ROS_WARN("scarf_learner: stopped; the finished rollouts are on disk, run again to resume");
      return 0;
    }
    ROS_FATAL("scarf_learner: %s", e.what());
    return 1;
  }
  return 0;
}

// The Python module bimanual_skills._core (python/bimanual_skills/__init__.py re-exports it): the rollout tasks of
// the task registry (rollout/task_registry.hpp) and the policy updates REPS and CMA-ES, NumPy in and out. A thin
// shell like nodes/: the logic is the library's. A rollout releases Python's lock, so Python threads run rollouts in
// parallel, one task object each; C++ exceptions arrive as Python exceptions with their reason (std::invalid_argument
// as ValueError, std::runtime_error as RuntimeError).
#include "bimanual_skills/learning/covariance_adaptation.hpp"
#include "bimanual_skills/learning/dual_reps.hpp"
#include "bimanual_skills/learning/pi2.hpp"
#include "bimanual_skills/learning/reps.hpp"
#include "bimanual_skills/primitives/dmp.hpp"
#include "bimanual_skills/primitives/promp.hpp"
#include "bimanual_skills/rollout/bottle_learning.hpp"
#include "bimanual_skills/rollout/dmp_learning.hpp"
#include "bimanual_skills/rollout/fold_learning.hpp"
#include "bimanual_skills/rollout/fold_rollout_task.hpp"
#include "bimanual_skills/rollout/parallel_evaluator.hpp"
#include "bimanual_skills/rollout/scarf_learning.hpp"
#include "bimanual_skills/rollout/task_registry.hpp"
#include "bimanual_skills/sim/sim_config.hpp"
#include "bimanual_skills/tasks/fold_quality.hpp"
#include "cli/pinned_numerics.hpp"

#include <pybind11/eigen.h>
#include <pybind11/functional.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>
#include <opencv2/core.hpp>

#include <atomic>
#include <chrono>
#include <cstdint>
#include <exception>
#include <future>
#include <memory>
#include <mutex>
#include <optional>
#include <random>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

namespace py = pybind11;
namespace br = bimanual_skills::rollout;
namespace bl = bimanual_skills::learning;
namespace tasks = bimanual_skills::tasks;
namespace bp = bimanual_skills::primitives;

namespace {

/// A rollout seed from Python: an integer in [0, 2^32).
std::uint32_t seedOf(long long seed) {
  if (seed < 0 || seed > 4294967295LL) {
    throw std::invalid_argument("a rollout seed is an integer in [0, 2^32), not " + std::to_string(seed));
  }
  return static_cast<std::uint32_t>(seed);
}

/// One task of the registry: one simulator, used from one thread at a time.
class Task {
 public:
  Task(std::string name, std::string config)
      : name_(std::move(name)), config_(std::move(config)), task_(br::makeRolloutTask(name_, config_)) {}

  const std::string& name() const { return name_; }
  const std::string& config() const { return config_; }
  std::vector<std::string> termNames() const { return task_->termNames(); }
  Eigen::VectorXd initialParameters() const { return task_->initialParameters(); }
  br::RolloutResult run(const Eigen::VectorXd& parameters, long long seed) {
    const std::uint32_t s = seedOf(seed);
    const py::gil_scoped_release unlocked;
    const std::unique_lock<std::mutex> lock(mutex_, std::try_to_lock);
    if (!lock.owns_lock()) {
      throw std::runtime_error("task '" + name_ + "' is running a rollout on another thread: one task per thread");
    }
    return task_->run(parameters, s);
  }

 private:
  std::string name_, config_;
  std::unique_ptr<br::RolloutTask> task_;
  std::mutex mutex_;  ///< Held while a rollout runs: a second thread is refused, not let into the simulator.
};

/// A DMP's path from its start, every dt for its duration (rows = samples, columns = DoF), by Dmp::step.
Eigen::MatrixXd dmpPath(const bp::Dmp& dmp, double dt) {
  if (!(dt > 0.0) || !std::isfinite(dt) || dmp.duration() / dt > 1e7) {
    throw std::invalid_argument("dt must be finite, > 0 and give at most 1e7 samples of the DMP's duration");
  }
  const auto samples = static_cast<Eigen::Index>(std::lround(dmp.duration() / dt)) + 1;
  Eigen::MatrixXd out(samples, dmp.dofs());
  bp::DmpState state = dmp.initialState();
  out.row(0) = state.y.transpose();
  for (Eigen::Index k = 1; k < samples; ++k) {
    if (dmp.step(state, dt) == bp::DmpStatus::InvalidInput) {
      throw std::invalid_argument("a DMP step of dt = " + std::to_string(dt) +
                                  " s is unstable for its duration and gains (DmpParameters::stableStep)");
    }
    out.row(k) = state.y.transpose();
  }
  return out;
}

/// A ProMP's mean positions and velocities and its positions' standard deviations at `samples` phases from 0 to 1
/// (rows = samples, columns = DoF), by ProMp::mean and ProMp::covariance.
py::tuple promPath(const bp::ProMp& promp, int samples) {
  if (samples < 2 || samples > 1000000) throw std::invalid_argument("samples in [2, 1e6]");
  bp::ProMpData data(promp);
  const int dofs = promp.dofs();
  Eigen::MatrixXd position(samples, dofs), velocity(samples, dofs), deviation(samples, dofs);
  Eigen::VectorXd q(dofs), qd(dofs);
  Eigen::MatrixXd covariance(dofs, dofs);
  for (int k = 0; k < samples; ++k) {
    const double z = static_cast<double>(k) / (samples - 1);
    if (promp.mean(data, z, q, qd) != bp::ProMpStatus::Success ||
        promp.covariance(data, z, covariance) != bp::ProMpStatus::Success) {
      throw std::logic_error("ProMP evaluation failed at z = " + std::to_string(z));
    }
    position.row(k) = q.transpose();
    velocity.row(k) = qd.transpose();
    deviation.row(k) = covariance.diagonal().cwiseMax(0.0).cwiseSqrt().transpose();
  }
  return py::make_tuple(position, velocity, deviation);
}

/// `image` (bgr8 or 32FC1) as a read-only NumPy view of its buffer, no copy: rows × columns (× channels). `owner`
/// (the object holding the image) lives as long as the view; the next rollout or render writes over it.
py::array imageView(const cv::Mat& image, const py::object& owner) {
  if (image.depth() != CV_8U && image.depth() != CV_32F) throw std::logic_error("an image neither 8U nor 32F");
  std::vector<py::ssize_t> shape{image.rows, image.cols};
  std::vector<py::ssize_t> strides{static_cast<py::ssize_t>(image.step[0]), static_cast<py::ssize_t>(image.elemSize())};
  if (image.channels() > 1) {
    shape.push_back(image.channels());
    strides.push_back(static_cast<py::ssize_t>(image.elemSize1()));
  }
  const py::dtype dtype = image.depth() == CV_8U ? py::dtype::of<std::uint8_t>() : py::dtype::of<float>();
  py::array view(dtype, shape, strides, image.data, owner);
  view.attr("flags").attr("writeable") = false;
  return view;
}

/// The cloth fold of a fold learning file with its images: what the Gymnasium environment
/// (bimanual_skills.gym_env.FoldEnv) runs. One simulator and camera, used from one thread at a time.
class FoldTask {
 public:
  FoldTask(const std::string& config, const std::string& noise)
      : config_(withNoise(br::withSimulationRenderer(br::FoldLearningConfig::fromYamlFile(config)), noise)),
        task_(config_.task, config_.reward) {}

  br::FoldRolloutTask& task() { return task_; }
  std::string noise() const { return config_.task.noise.setting; }
  /// The policy of the demonstration's latent weights moved by `offsets` (Ω = I).
  Eigen::VectorXd parametersFor(const Eigen::VectorXd& offsets) {
    const Eigen::VectorXd weights = task_.task().demonstrationParameters();
    if (offsets.size() != weights.size() || !offsets.allFinite()) {
      throw std::invalid_argument("the fold's policy has " + std::to_string(weights.size()) +
                                  " latent weights: offsets of that many finite values, not " +
                                  std::to_string(offsets.size()));
    }
    return br::encodeCoordinatedPolicy(
        {Eigen::MatrixXd::Identity(tasks::ClothFoldTask::kDofs, tasks::ClothFoldTask::kDofs)}, weights + offsets);
  }
  Eigen::VectorXd weightStddev() { return br::latentWeightStddev(config_, task_.task()); }
  br::RolloutResult run(const Eigen::VectorXd& parameters, long long seed) {
    const std::uint32_t s = seedOf(seed);
    const py::gil_scoped_release unlocked;
    const std::unique_lock<std::mutex> lock = own();
    return task_.run(parameters, s);
  }
  std::string renderStart(long long seed) {
    const std::uint32_t s = seedOf(seed);
    const py::gil_scoped_release unlocked;
    const std::unique_lock<std::mutex> lock = own();
    return bimanual_skills::vision::toString(task_.renderStart(s));
  }
  /// The references ClothFoldTask::run would follow for `parameters`, rows = periods, columns = both arms' joints.
  py::dict plan(const Eigen::VectorXd& parameters) {
    std::vector<Eigen::MatrixXd> coordination;
    Eigen::VectorXd weights;
    if (!br::decodeCoordinatedPolicy(parameters, tasks::ClothFoldTask::kDofs, task_.task().policyBasisSize(),
                                     coordination, weights)) {
      throw std::invalid_argument("the parameters do not encode a coordinated policy of the fold");
    }
    tasks::FoldPlan plan;
    {
      const py::gil_scoped_release unlocked;
      const std::unique_lock<std::mutex> lock = own();
      plan = task_.task().plan(coordination, weights);
    }
    py::dict d;
    d["outcome"] = tasks::toString(plan.outcome);
    d["reason"] = plan.reason;
    d["dt"] = plan.dt;
    d["move_start"] = plan.move_start;
    d["release"] = plan.release;
    // A failed plan has no references (its matrices stop at the failure, or were never made): None.
    const bool whole = plan.outcome == tasks::FoldOutcome::Ok && plan.position.size() == 2;
    const auto both = [whole](const std::vector<Eigen::MatrixXd>& arms) -> py::object {
      if (!whole) return py::none();
      Eigen::MatrixXd out(arms[0].cols(), arms[0].rows() + arms[1].rows());
      out << arms[0].transpose(), arms[1].transpose();
      return py::cast(out);
    };
    d["position"] = both(plan.position);
    d["velocity"] = both(plan.velocity);
    d["acceleration"] = both(plan.acceleration);
    return d;
  }
  std::string beginSteps(long long seed) {
    const std::uint32_t s = seedOf(seed);
    const py::gil_scoped_release unlocked;
    const std::unique_lock<std::mutex> lock = own();
    steps_seed_ = s;
    return tasks::toString(task_.task().beginSteps(s));
  }
  std::string step(const Eigen::Ref<const Eigen::VectorXd>& velocity) {
    const py::gil_scoped_release unlocked;
    const std::unique_lock<std::mutex> lock = own();
    return tasks::toString(task_.task().step(velocity));
  }
  br::RolloutResult finishSteps() {
    const py::gil_scoped_release unlocked;
    const std::unique_lock<std::mutex> lock = own();
    return task_.record(task_.task().finishSteps(), steps_seed_);
  }
  py::tuple jointState() {
    Eigen::VectorXd q(14), qd(14), arm_q, arm_qd;
    for (int arm = 0; arm < 2; ++arm) {
      task_.task().measuredState(arm, arm_q, arm_qd);
      q.segment<7>(7 * arm) = arm_q;
      qd.segment<7>(7 * arm) = arm_qd;
    }
    return py::make_tuple(q, qd);
  }
  py::dict jointLimits() {
    Eigen::VectorXd lower(14), upper(14), velocity(14);
    for (int arm = 0; arm < 2; ++arm) {
      const bimanual_skills::kinematics::ChainModel& model = task_.task().armModel(arm);
      lower.segment<7>(7 * arm) = model.lowerLimits();
      upper.segment<7>(7 * arm) = model.upperLimits();
      velocity.segment<7>(7 * arm) = model.velocityLimits();
    }
    py::dict d;
    d["lower"] = lower;
    d["upper"] = upper;
    d["velocity"] = velocity;
    return d;
  }
  Eigen::MatrixXd toolPositions() {
    Eigen::MatrixXd out(2, 3);
    for (int arm = 0; arm < 2; ++arm) out.row(arm) = task_.task().toolPosition(arm).transpose();
    return out;
  }
  py::dict startFold(long long seed) {
    // The start against itself: its own rest, as the rollout of `seed` measures its cloth.
    const Eigen::Matrix3Xd start = task_.task().clothStartVertices(seedOf(seed));
    const bimanual_skills::sim::ClothParameters& cloth = task_.task().simConfig().cloth;
    const tasks::FoldQuality f = tasks::foldQuality(start, start, cloth.nodes_x, cloth.nodes_y, cloth.thickness);
    py::dict d;
    d["q"] = f.q;
    d["distance"] = f.distance;
    d["displacement"] = f.displacement;
    return d;
  }

 private:
  static br::FoldLearningConfig withNoise(br::FoldLearningConfig c, const std::string& noise) {
    if (!noise.empty()) c.task.noise = tasks::foldNoiseSetting(noise, "FoldTask's noise");
    return c;
  }
  std::unique_lock<std::mutex> own() {
    std::unique_lock<std::mutex> lock(mutex_, std::try_to_lock);
    if (!lock.owns_lock()) throw std::runtime_error("this fold task is busy on another thread: one task per thread");
    return lock;
  }

  br::FoldLearningConfig config_;
  br::FoldRolloutTask task_;
  std::uint32_t steps_seed_ = 0;  ///< The stepped rollout's seed: its camera noise when it is scored.
  std::mutex mutex_;
};

/// A learner's Evaluator that hands each batch to Python: `evaluate(requests, done)` with requests a list of
/// (parameters, seed) and done(index, result) to be called as each rollout finishes (completion order, from the
/// thread that called evaluate), returning the results in request order (Ray's backend, bimanual_skills.ray_backend).
/// The learner runs without Python's lock; a batch takes it while Python works.
class PythonEvaluator : public br::Evaluator {
 public:
  explicit PythonEvaluator(py::object evaluate) : evaluate_(std::move(evaluate)) {}
  ~PythonEvaluator() override {
    const py::gil_scoped_acquire locked;
    evaluate_ = py::object();
  }

  std::vector<br::RolloutResult> evaluate(const std::vector<br::RolloutRequest>& batch, const Done& done,
                                          const std::function<bool()>& stop) override {
    if (stop && stop()) throw std::runtime_error("stopped");
    const py::gil_scoped_acquire locked;
    py::list requests;
    for (const br::RolloutRequest& r : batch) requests.append(py::make_tuple(r.parameters, r.seed));
    std::vector<bool> reported(batch.size(), false);
    const auto report = [&](std::size_t index, const br::RolloutResult& result) {
      if (index >= batch.size() || reported[index]) {
        throw std::invalid_argument(
            "the evaluator reported rollout " + std::to_string(index) +
            (index >= batch.size() ? " of a batch of " + std::to_string(batch.size()) : " twice"));
      }
      reported[index] = true;
      if (done) {
        const py::gil_scoped_release unlocked;  // the learner writes its record
        done(index, result, nullptr);
      }
      // Polled as each rollout finishes, so that a stop does not wait for the batch: the evaluator's Python gets
      // a RuntimeError from done().
      if (stop && stop()) throw std::runtime_error("stopped");
    };
    py::object answer;
    try {
      answer = evaluate_(requests, py::cpp_function(report));
    } catch (const py::error_already_set&) {
      if (stop && stop()) throw std::runtime_error("stopped");
      throw;
    }
    std::vector<br::RolloutResult> results = answer.cast<std::vector<br::RolloutResult>>();
    if (results.size() != batch.size()) {
      throw std::invalid_argument("the evaluator returned " + std::to_string(results.size()) + " results for " +
                                  std::to_string(batch.size()) + " rollouts");
    }
    for (std::size_t i = 0; i < batch.size(); ++i) {
      if (!reported[i]) report(i, results[i]);
    }
    return results;
  }

 private:
  py::object evaluate_;
};

/// `learn()` on a thread of its own while this one, holding no Python lock, watches Python's signals (CPython handles
/// them on the main thread only): a signal's exception (Ctrl-C's KeyboardInterrupt) sets `interrupted`, which the
/// learner polls as its stop between rollouts, and is raised here once it has stopped. A rollout that never ends
/// (an evaluator waiting on a lost cluster) holds the stop until it does; a second Ctrl-C changes nothing.
template <class Result>
Result learnWatchingSignals(const std::function<Result()>& learn, std::atomic<bool>& interrupted) {
  Result result;
  std::exception_ptr failure;
  std::optional<py::error_already_set> signal;
  {
    const py::gil_scoped_release unlocked;
    std::promise<void> finished;
    std::future<void> done = finished.get_future();
    std::thread learning([&] {
      try {
        result = learn();
      } catch (...) {
        failure = std::current_exception();
      }
      finished.set_value();
    });
    // Joined on every path, a throw below included: the learner stops at the flag.
    struct Joiner {
      std::thread& thread;
      std::atomic<bool>& stop;
      ~Joiner() {
        stop = true;
        thread.join();
      }
    } joiner{learning, interrupted};
    while (done.wait_for(std::chrono::milliseconds(50)) != std::future_status::ready) {
      if (interrupted) continue;
      const py::gil_scoped_acquire locked;
      if (PyErr_CheckSignals() != 0) {
        signal.emplace();
        interrupted = true;
      }
    }
  }
  if (signal) throw *signal;
  if (failure) std::rethrow_exception(failure);
  return result;
}

/// What a learning returns: per run its algorithm, index, what `per_run(run, dict)` adds and its seconds, then the
/// rollouts simulated now and resumed from disk, and the seconds.
template <class Result, class PerRun>
py::dict learningSummary(const Result& result, int simulated, PerRun&& per_run) {
  py::list runs;
  for (const auto& run : result.runs) {
    py::dict d;
    d["algorithm"] = run.algorithm;
    d["run"] = run.run;
    per_run(run, d);
    d["seconds"] = run.seconds;
    runs.append(d);
  }
  py::dict out;
  out["runs"] = runs;
  out["simulated"] = simulated;
  out["resumed"] = result.resumed;
  out["seconds"] = result.seconds;
  return out;
}

/// learn_dmp()'s: the noise-free policy's reward before, after and at best, and per epoch.
py::dict dmpSummary(const br::DmpLearningResult& result) {
  return learningSummary(result, result.ran, [](const br::DmpRunResult& run, py::dict& d) {
    d["initial_reward"] = run.initial_policy.result.reward;
    d["final_reward"] = run.final_policy.result.reward;
    d["best_reward"] = run.best.result.reward;
    py::list epochs;
    for (const br::DmpEpochStats& e : run.epochs) {
      py::dict epoch;
      epoch["epoch"] = e.epoch;
      epoch["mean_reward"] = e.mean_reward;
      epoch["policy_reward"] = e.policy_reward;
      epoch["successes"] = e.successes;
      epoch["failures"] = e.failures;
      epochs.append(epoch);
    }
    d["epochs"] = epochs;
  });
}

/// learn_fold()'s: the noise-free policy's reward and fold quality before and after, and per epoch (policy reward,
/// mean reward).
py::dict foldSummary(const br::FoldLearningResult& result) {
  return learningSummary(result, result.simulated, [](const br::FoldRunResult& run, py::dict& d) {
    d["initial_reward"] = run.initial_policy.terms.reward;
    d["initial_fold_quality"] = run.initial_policy.terms.fold_quality;
    d["final_reward"] = run.final_policy.terms.reward;
    d["final_fold_quality"] = run.final_policy.terms.fold_quality;
    py::list epochs;
    for (const br::FoldEpochStats& e : run.epochs) epochs.append(py::make_tuple(e.policy_reward, e.mean_reward));
    d["epochs"] = epochs;
  });
}

}  // namespace

PYBIND11_MODULE(_core, m) {
  m.doc() = "bimanual_skills' C++ core: rollout tasks and policy updates (see the package's docstring).";
  // Eigen blocks its products by the committed results' cache sizes, as the C++ programs do; libm and OpenCV take
  // their code at load time, which an imported module cannot change (pinned_environment()).
  Eigen::setCpuCacheSizes(bimanual_skills::cli::kEigenCaches[0], bimanual_skills::cli::kEigenCaches[1],
                          bimanual_skills::cli::kEigenCaches[2]);
  m.def("numerics", &bimanual_skills::cli::numericsState,
        "\"pinned\" when libm, OpenCV and Eigen run the code the C++ programs pin (one seed, one result on every "
        "x86-64 machine), else what is not.");
  m.def(
      "pinned_environment",
      [] {
        py::dict d;
        d["GLIBC_TUNABLES"] = std::string(bimanual_skills::cli::kHwcapsTunable) + bimanual_skills::cli::kLibmMask;
        const std::string mask = bimanual_skills::cli::openCvMask();
        if (!mask.empty()) d["OPENCV_CPU_DISABLE"] = mask;
        return d;
      },
      "The environment a Python process must start with for numerics() to be \"pinned\" (and its rollouts to "
      "equal the C++ programs' bit for bit): set these before starting Python.");

  m.def(
      "tasks",
      [] {
        std::vector<py::dict> out;
        for (const br::RolloutTaskInfo& info : br::rolloutTasks()) {
          py::dict d;
          d["name"] = info.name;
          d["config"] = info.config;
          d["description"] = info.description;
          out.push_back(d);
        }
        return out;
      },
      "Every task make_task() builds: name, what its configuration file is, and a line on it.");

  py::class_<br::RolloutResult>(m, "RolloutResult", "What one rollout returned (picklable: Ray carries it).")
      .def(py::pickle(
          [](const br::RolloutResult& r) {
            return py::make_tuple(r.reward, r.terms, r.ok, r.outcome, r.reason, r.wall_seconds, r.trajectory);
          },
          [](const py::tuple& t) {
            if (t.size() != 7) throw std::invalid_argument("a pickled RolloutResult has 7 fields");
            br::RolloutResult r;
            r.reward = t[0].cast<double>();
            r.terms = t[1].cast<Eigen::VectorXd>();
            r.ok = t[2].cast<bool>();
            r.outcome = t[3].cast<std::string>();
            r.reason = t[4].cast<std::string>();
            r.wall_seconds = t[5].cast<double>();
            r.trajectory = t[6].cast<Eigen::MatrixXd>();
            return r;
          }))
      .def_readonly("reward", &br::RolloutResult::reward)
      .def_readonly("terms", &br::RolloutResult::terms, "The reward's terms, named by Task.term_names().")
      .def_readonly("ok", &br::RolloutResult::ok, "False when the rollout failed (reward: the task's failure reward).")
      .def_readonly("outcome", &br::RolloutResult::outcome)
      .def_readonly("reason", &br::RolloutResult::reason, "Why it failed; empty when ok.")
      .def_readonly("wall_seconds", &br::RolloutResult::wall_seconds)
      .def_readonly("trajectory", &br::RolloutResult::trajectory,
                    "A summary of the rollout's trajectory, one column per sample (the fold: both tools' paths).")
      .def("__repr__", [](const br::RolloutResult& r) {
        return "RolloutResult(reward=" + std::to_string(r.reward) + ", outcome='" + r.outcome + "')";
      });

  py::class_<Task>(m, "Task", "A rollout task: one simulator; one object per thread.")
      .def(py::init<std::string, std::string>(), py::arg("name"), py::arg("config") = "")
      .def_property_readonly("name", &Task::name)
      .def_property_readonly("config", &Task::config)
      .def("term_names", &Task::termNames)
      .def("initial_parameters", &Task::initialParameters, "The task's starting policy (its demonstration).")
      .def("run", &Task::run, py::arg("parameters"), py::arg("seed"),
           "One rollout of the policy `parameters` with the noise of `seed` (same parameters and seed, same result). "
           "Releases Python's lock while it runs. A failed rollout is a result with ok False, not an exception.");
  py::class_<FoldTask>(m, "FoldTask",
                       "The cloth fold of a fold learning file with the camera's images as NumPy arrays (the "
                       "Gymnasium environment's core). One simulator; one object per thread.")
      .def(py::init<std::string, std::string>(), py::arg("config"), py::arg("noise") = "",
           "`config`: a fold learning file (config/fold_demo.yaml); `noise`: the robot's repeatability setting, "
           "\"none\" or \"robot\" (\"\": the file's). ValueError for a bad file or setting.")
      .def_property_readonly("noise", &FoldTask::noise)
      .def("term_names", [](const FoldTask&) { return br::FoldRolloutTask::names(); })
      .def(
          "initial_parameters", [](FoldTask& t) { return t.task().initialParameters(); },
          "The demonstration's policy (Ω = I and its latent weights).")
      .def("parameters_for", &FoldTask::parametersFor, py::arg("offsets"),
           "The policy whose latent weights are the demonstration's plus `offsets` (Ω = I).")
      .def("latent_weight_stddev", &FoldTask::weightStddev,
           "The learning file's starting exploration per latent weight (kernel weights initial_stddev, goal "
           "weights the forcing that moves the goal by goal_stddev), in parameters_for()'s order.")
      .def_property_readonly(
          "thickness", [](FoldTask& t) { return t.task().task().simConfig().cloth.thickness; },
          "The cloth's thickness [m]: an ideal fold's halves lie this far apart.")
      .def("run", &FoldTask::run, py::arg("parameters"), py::arg("seed"),
           "One rollout, as Task.run (releases Python's lock); its final images are images() until the next.")
      .def("render_start", &FoldTask::renderStart, py::arg("seed"),
           "The camera's picture of rollout `seed`'s start (the flat cloth where that rollout's noise lays it): "
           "start_images() until the next call. Returns the vision status (\"Ok\").")
      .def(
          "images",
          [](py::object self) {
            FoldTask& t = self.cast<FoldTask&>();
            return py::make_tuple(imageView(t.task().reward().bgr(), self), imageView(t.task().reward().depth(), self));
          },
          "The last rollout's final images as the reward scored them: (bgr uint8 H x W x 3, depth float32 H x W "
          "[m]), read-only views of the task's buffers (no copy; the next rollout writes over them).")
      .def(
          "start_images",
          [](py::object self) {
            FoldTask& t = self.cast<FoldTask&>();
            return py::make_tuple(imageView(t.task().startBgr(), self), imageView(t.task().startDepth(), self));
          },
          "The last render_start()'s images, as images() (views, no copy).")
      .def("plan", &FoldTask::plan, py::arg("parameters"),
           "The joint references run(parameters, ...) follows, computed without simulating: a dict of outcome, "
           "reason, dt [s], move_start and release (periods), and position, velocity, acceleration (periods x 14: "
           "the left arm's 7 joints, then the right's; row k is period k's reference; None when the plan failed).")
      .def("begin_steps", &FoldTask::beginSteps, py::arg("seed"),
           "Begins a stepped rollout of `seed` (the joint-space environment's episode): the simulation as run() "
           "builds it, the arms at the start, the grasp. Returns the outcome (\"Ok\" or \"GraspFailed\").")
      .def_property_readonly(
          "stepped_periods", [](FoldTask& t) { return t.task().task().steppedPeriods(); },
          "The periods a stepped rollout's policy drives (up to the grippers' planned release).")
      .def_property_readonly(
          "stepping", [](FoldTask& t) { return t.task().task().stepping(); },
          "Whether step() may be called (a stepped rollout is Ok with driven periods left).")
      .def_property_readonly(
          "stepped_period", [](FoldTask& t) { return t.task().task().steppedPeriod(); },
          "The periods the stepped rollout has run.")
      .def_property_readonly(
          "dt", [](FoldTask& t) { return t.task().task().simConfig().step; },
          "The control period [s] (the simulation's step).")
      .def("step", &FoldTask::step, py::arg("velocity"),
           "One control period of the stepped rollout: `velocity` (14 joint velocities [rad/s], left arm then "
           "right) sets the next period's reference, which the controllers track from then on. Returns the "
           "outcome: \"Ok\", or why the rollout ended (InvalidPolicy, OutOfLimits, ControllerFailed, ...). "
           "Releases Python's lock. RuntimeError without begin_steps() or after the driven periods.")
      .def("finish_steps", &FoldTask::finishSteps,
           "Ends the stepped rollout (through the rest and the settling the references come to rest at "
           "step_acceleration and hold) and scores it as run() "
           "does: its result; its images are images().")
      .def("joint_state", &FoldTask::jointState,
           "Both arms' joint positions and velocities as the controllers measured them in the last stepped "
           "period (the start, at rest, before the first): (q, qd), 14 each.")
      .def_property_readonly(
          "step_acceleration", [](FoldTask& t) { return t.task().task().config().step_acceleration; },
          "How fast a stepped rollout's reference reaches its commanded velocity [rad/s^2].")
      .def("joint_limits", &FoldTask::jointLimits,
           "Both arms' URDF limits, 14 values each (left arm, then right): lower and upper [rad], velocity [rad/s].")
      .def("tool_positions", &FoldTask::toolPositions, "Both tools' positions now (2 x 3, world) [m].")
      .def(
          "cloth_vertices", [](FoldTask& t) { return Eigen::Matrix3Xd(t.task().task().clothVertices()); },
          "The cloth's mesh now (3 x nodes, world) [m].")
      .def_property_readonly(
          "cloth_nodes",
          [](FoldTask& t) {
            const bimanual_skills::sim::ClothParameters& c = t.task().task().simConfig().cloth;
            return py::make_tuple(c.nodes_x, c.nodes_y);
          },
          "The cloth mesh's nodes along its length and its width, (nodes_x, nodes_y): node (i, j) is column "
          "i + nodes_x j of cloth_vertices().")
      .def("start_fold", &FoldTask::startFold, py::arg("seed"),
           "The fold quality of rollout `seed`'s start (q 0: the flat cloth): q, distance, displacement [m].");
  m.def(
      "make_task",
      [](const std::string& name, const std::string& config) { return std::make_unique<Task>(name, config); },
      py::arg("name"), py::arg("config") = "",
      "A new task `name` (see tasks()) configured by the file `config` (\"\": the task's defaults, where it has "
      "them). ValueError for an unknown name or a bad configuration.");

  m.def(
      "learn_fold",
      [](const std::string& config, const std::string& out, const py::object& evaluator, int runs, int updates,
         int rollouts, long long seed, int jobs) {
        br::FoldLearningConfig c = br::FoldLearningConfig::fromYamlFile(config);
        if (runs > 0) c.runs = runs;
        if (updates > 0) c.updates = updates;
        if (rollouts > 0) c.rollouts = rollouts;
        if (seed >= 0) c.seed = seedOf(seed);
        c.jobs = jobs;
        std::unique_ptr<br::Evaluator> backend;
        if (!evaluator.is_none()) backend = std::make_unique<PythonEvaluator>(evaluator);
        std::atomic<bool> interrupted{false};
        br::FoldLearningObserver observer;
        observer.stop = [&interrupted] { return interrupted.load(); };
        br::FoldLearner learner(c, out, observer, std::move(backend));
        const br::FoldLearningResult result =
            learnWatchingSignals<br::FoldLearningResult>([&learner] { return learner.learn(); }, interrupted);
        return foldSummary(result);
      },
      py::arg("config"), py::arg("out"), py::arg("evaluator") = py::none(), py::arg("runs") = 0, py::arg("updates") = 0,
      py::arg("rollouts") = 0, py::arg("seed") = -1, py::arg("jobs") = 0,
      "The fold learning of a learning file (fold_learner's, in process), into the run directory `out` (resumed "
      "from the rollouts already there). runs, updates, rollouts, seed override the file's (0 / -1: the file's). "
      "Rollouts on `jobs` threads here, or, with `evaluator`, wherever it runs them: evaluator(requests, done) gets "
      "a list of (parameters, seed) of the task \"fold\" of this file, calls done(index, result) as each finishes "
      "and returns the results in order (bimanual_skills.ray_backend.RayEvaluator). Same seed, same results. "
      "Ctrl-C (KeyboardInterrupt) stops it between rollouts; what finished is on disk and is resumed.");

  m.def(
      "learn_dmp",
      [](const std::string& task, const std::string& config, const std::string& out, const py::object& evaluator,
         int runs, int updates, int rollouts, long long seed, int jobs) {
        br::DmpLearningConfig learning;
        br::DmpTaskModel model;
        std::function<std::unique_ptr<br::RolloutTask>()> make;
        int dofs = 0;
        if (task == "scarf") {
          const br::ScarfLearningConfig c = br::ScarfLearningConfig::fromYamlFile(config);
          br::ScarfRolloutTask t(c.task);
          model = br::scarfTaskModel(t.task());
          learning = c.learning;
          dofs = t.task().dofs();
          make = [settings = c.task] { return std::make_unique<br::ScarfRolloutTask>(settings); };
        } else if (task == "bottles_learning") {
          const br::BottleLearningConfig c = br::BottleLearningConfig::fromYamlFile(config);
          br::BottleRolloutTask t(c.task);
          model = br::bottleTaskModel(t.task());
          learning = c.learning;
          dofs = 2;
          make = [settings = c.task] { return std::make_unique<br::BottleRolloutTask>(settings); };
        } else {
          throw std::invalid_argument("learn_dmp: task 'scarf' or 'bottles_learning', not '" + task + "'");
        }
        if (runs > 0) learning.runs = runs;
        if (updates > 0) learning.updates = updates;
        if (rollouts > 0) learning.rollouts = rollouts;
        if (seed >= 0) learning.seed = seedOf(seed);
        learning.jobs = jobs;
        learning.validate(dofs);
        std::unique_ptr<br::Evaluator> backend;
        if (evaluator.is_none()) {
          backend = std::make_unique<br::ParallelEvaluator>(make, learning.jobs);
        } else {
          backend = std::make_unique<PythonEvaluator>(evaluator);
        }
        std::atomic<bool> interrupted{false};
        br::DmpLearningObserver observer;
        observer.stop = [&interrupted] { return interrupted.load(); };
        br::DmpLearner learner(model, learning, out, std::move(backend), observer);
        return dmpSummary(
            learnWatchingSignals<br::DmpLearningResult>([&learner] { return learner.learn(); }, interrupted));
      },
      py::arg("task"), py::arg("config"), py::arg("out"), py::arg("evaluator") = py::none(), py::arg("runs") = 0,
      py::arg("updates") = 0, py::arg("rollouts") = 0, py::arg("seed") = -1, py::arg("jobs") = 0,
      "The DR-DMP learning of task \"scarf\" (a scarf learning file, scarf_learner's) or \"bottles_learning\" (a "
      "bottles learning file, bottles_learner's), in process, into the run directory `out` (resumed from the "
      "rollouts already there). runs, updates, rollouts, seed override the file's (0 / -1: the file's). Rollouts "
      "on `jobs` threads here, or with `evaluator` wherever it runs them, as learn_fold's (RayEvaluator(task, "
      "config)). Same seed, same results; Ctrl-C stops it between rollouts.");

  py::class_<bl::RepsUpdate>(m, "RepsUpdate")
      .def_readonly("mean", &bl::RepsUpdate::mean)
      .def_readonly("covariance", &bl::RepsUpdate::covariance)
      .def_readonly("weights", &bl::RepsUpdate::weights)
      .def_readonly("eta", &bl::RepsUpdate::eta)
      .def_readonly("kl", &bl::RepsUpdate::kl);
  py::class_<bl::Reps>(m, "Reps", "REPS (thesis Sec. 5.2.2): the new Gaussian from rollouts reweighted exp(r / eta).")
      .def(py::init([](double epsilon, int reuse, bool normalise_rewards) {
             bl::RepsParameters p;
             p.epsilon = epsilon;
             p.reuse = reuse;
             p.normalise_rewards = normalise_rewards;
             p.validate();
             return bl::Reps(p);
           }),
           py::arg("epsilon") = 0.5, py::arg("reuse") = 0, py::arg("normalise_rewards") = true)
      .def("update", &bl::Reps::update, py::arg("samples"), py::arg("rewards"),
           "One update from rollouts (rows of `samples`) and their rewards (higher is better).");

  py::class_<bl::DualRepsCluster>(m, "DualRepsCluster")
      .def_readonly("mean", &bl::DualRepsCluster::mean)
      .def_readonly("covariance", &bl::DualRepsCluster::covariance)
      .def_readonly("attractive", &bl::DualRepsCluster::attractive)
      .def_readonly("size", &bl::DualRepsCluster::size)
      .def_readonly("multiplier", &bl::DualRepsCluster::multiplier);
  py::class_<bl::DualRepsUpdate>(m, "DualRepsUpdate")
      .def_readonly("policy", &bl::DualRepsUpdate::policy, "The new Gaussian (a RepsUpdate).")
      .def_readonly("clusters", &bl::DualRepsUpdate::clusters)
      .def_readonly("repairs", &bl::DualRepsUpdate::repairs)
      .def_readonly("repulsion_dropped", &bl::DualRepsUpdate::repulsion_dropped)
      .def_readonly("plain_reps", &bl::DualRepsUpdate::plain_reps);
  py::class_<bl::DualReps>(m, "DualReps",
                           "Dual REPS (thesis Alg. 6.2): REPS with attractive and repulsive clusters of the rollouts, "
                           "for multimodal rewards. DualReps(epsilon, reuse) has the thesis' DREPS settings (c = 5, "
                           "xi = 5, chi = 2 epsilon); clusters=0 makes every update the REPS one.")
      .def(py::init([](double epsilon, int reuse, int clusters) {
             bl::DualRepsParameters p = bl::thesisDreps(epsilon, reuse);
             p.clusters = clusters;
             p.validate();
             return bl::DualReps(p);
           }),
           py::arg("epsilon") = 0.5, py::arg("reuse") = 0, py::arg("clusters") = 5)
      .def("update", &bl::DualReps::update, py::arg("mean"), py::arg("covariance"), py::arg("samples"),
           py::arg("rewards"),
           "One update from rollouts (rows of `samples`) drawn from N(mean, covariance) and their rewards (higher is "
           "better).");
  m.def(
      "pi2_update",
      [](const Eigen::VectorXd& mean, const Eigen::MatrixXd& covariance, const Eigen::MatrixXd& samples,
         const Eigen::MatrixXd& costs, const Eigen::MatrixXd& basis, double h, double control_cost,
         bool covariance_adaptation) {
        bl::Pi2Parameters p;
        p.h = h;
        p.control_cost = control_cost;
        p.covariance_adaptation = covariance_adaptation;
        p.validate();
        const bl::Pi2Update u = bl::pi2Update(p, mean, covariance, samples, costs, basis);
        return py::make_tuple(u.mean, u.covariance, u.probabilities);
      },
      py::arg("mean"), py::arg("covariance"), py::arg("samples"), py::arg("costs"), py::arg("basis"),
      py::arg("h") = 10.0, py::arg("control_cost") = 0.0, py::arg("covariance_adaptation") = false,
      "One PI2 update (thesis eqs. 5.8-5.13; PI2-CMA with covariance_adaptation) of a policy linear in `basis` "
      "(time steps x B, shared by the D DoF of mean's D*B weights): samples K x D*B, costs K x time steps (lower is "
      "better). Returns (mean, covariance, probabilities).");

  py::class_<bp::Dmp>(m, "Dmp",
                      "A discrete DMP (thesis (5.14)-(5.15)): weights (DoF x kernels), start, goal, duration.")
      .def(py::init([](const Eigen::MatrixXd& weights, const Eigen::VectorXd& start, const Eigen::VectorXd& goal,
                       double duration) {
             bp::DmpParameters p;
             p.kernels = static_cast<int>(weights.cols());
             p.validate();
             return bp::Dmp(p, weights, start, goal, duration);
           }),
           py::arg("weights"), py::arg("start"), py::arg("goal"), py::arg("duration"))
      .def_static(
          "fit",
          [](const Eigen::MatrixXd& positions, double dt, int kernels, double smoothing_hz) {
            bp::DmpParameters p;
            p.kernels = kernels;
            p.validate();
            return bp::Dmp::fit(p, positions, dt, smoothing_hz);
          },
          py::arg("positions"), py::arg("dt"), py::arg("kernels") = 25, py::arg("smoothing_hz") = 20.0,
          "The least-squares DMP of a demonstration (rows = samples every dt, columns = DoF).")
      .def_property_readonly("weights", &bp::Dmp::weights)
      .def_property_readonly("start", &bp::Dmp::start)
      .def_property_readonly("goal", &bp::Dmp::goal)
      .def_property_readonly("duration", &bp::Dmp::duration)
      .def("with_weights", &bp::Dmp::withWeights, py::arg("weights"), "A copy with other weights (a policy sample).")
      .def("path", &dmpPath, py::arg("dt"),
           "The DMP's positions from its start every dt for its duration (rows = samples, columns = DoF).");

  m.def(
      "robot",
      [](const std::string& sim_file, const std::string& robot_file) {
        const bimanual_skills::sim::SimConfig c = bimanual_skills::sim::SimConfig::fromYamlFile(sim_file, robot_file);
        py::list arms;
        for (const bimanual_skills::sim::ArmConfig& a : c.arms) {
          py::dict d;
          d["name"] = a.name;
          d["base_link"] = a.base_link;
          d["tip_link"] = a.tip_link;
          d["start"] = a.start;
          d["ik_seed"] = a.ik_seed;
          d["friction_file"] = a.friction_file;
          arms.append(d);
        }
        py::dict out;
        out["arms"] = arms;
        out["urdf"] = c.urdf_path;
        out["plant"] = c.plant_path;
        out["robot_file"] = c.robot_path;
        out["kp"] = c.kp;
        out["kv"] = c.kv;
        out["step"] = c.step;
        out["has_cloth"] = c.has_cloth;
        return out;
      },
      py::arg("sim_file"), py::arg("robot_file") = "",
      "What a simulation file and a robot file (config/robots/*.yaml, \"\": the one the simulation file names) say "
      "the pair is, as bullet_sim reads them: each arm's name, base and tip links, start posture, IK seed and "
      "friction model, the URDF, the plant, the gains, the step. ValueError for a bad file, naming it.");

  py::class_<bp::ProMp>(m, "ProMp",
                        "A probabilistic movement primitive (thesis (5.16)-(5.18)): weights ~ N(mean, covariance) of "
                        "a normalised Gaussian basis per DoF over the phase z = t / duration.")
      .def_static(
          "fit",
          [](const std::vector<Eigen::MatrixXd>& demonstrations, double duration, int kernels) {
            bp::ProMpParameters p;
            p.kernels = kernels;
            p.validate();
            return bp::ProMp::fit(p, demonstrations, duration);
          },
          py::arg("demonstrations"), py::arg("duration"), py::arg("kernels") = 20,
          "The maximum-likelihood ProMP of demonstrations (each samples x DoF, spread over its own duration; "
          "`duration` [s] their mean length).")
      .def_property_readonly("dofs", &bp::ProMp::dofs)
      .def_property_readonly("kernels", &bp::ProMp::kernels)
      .def_property_readonly("duration", &bp::ProMp::duration)
      .def_property_readonly("weight_mean", &bp::ProMp::weightMean)
      .def_property_readonly("weight_covariance", &bp::ProMp::weightCovariance)
      .def_property_readonly("observation_variance", &bp::ProMp::observationVariance)
      .def("with_mean", &bp::ProMp::withMean, py::arg("mean"), "The same ProMP with another weight mean.")
      .def(
          "sample",
          [](const bp::ProMp& promp, long long seed) {
            std::mt19937 rng(seedOf(seed));
            return promp.sample(rng);
          },
          py::arg("seed"), "Weights drawn from N(mean, covariance) with a generator seeded by `seed`.")
      .def(
          "conditioned",
          [](const bp::ProMp& promp, double z, const Eigen::VectorXd& position, const Eigen::MatrixXd& covariance,
             const Eigen::VectorXd& velocity) { return promp.conditioned(z, position, covariance, velocity); },
          py::arg("z"), py::arg("position"), py::arg("observation_covariance"), py::arg("velocity") = Eigen::VectorXd(),
          "The ProMP conditioned on passing through `position` (and `velocity`) at phase z (a via-point).")
      .def("path", &promPath, py::arg("samples") = 101,
           "(mean positions, mean velocities, positions' standard deviations) at `samples` phases from 0 to 1.");

  py::class_<bl::CovarianceAdaptation>(m, "CmaEs",
                                       "CMA-ES (Hansen 2006): the search distribution N(m, sigma^2 C), rewards "
                                       "maximised; step() is one generation.")
      .def(py::init(&bl::CovarianceAdaptation::start), py::arg("covariance"))
      .def_readonly("step_size", &bl::CovarianceAdaptation::step_size)
      .def_readonly("generations", &bl::CovarianceAdaptation::generations)
      .def_property_readonly("covariance", &bl::CovarianceAdaptation::covariance, "sigma^2 C: where to sample next.")
      .def(
          "step",
          [](bl::CovarianceAdaptation& a, const Eigen::VectorXd& mean, const Eigen::MatrixXd& samples,
             const Eigen::VectorXd& rewards) { return bl::cmaEsStep(mean, a, samples, rewards); },
          py::arg("mean"), py::arg("samples"), py::arg("rewards"),
          "One generation from the samples (rows) drawn around `mean`: returns the new mean.");
}

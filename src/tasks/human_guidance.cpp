#include "bimanual_skills/tasks/human_guidance.hpp"

#include "bimanual_skills/tasks/policy_search_tasks.hpp"

#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>
#include <string>

namespace bimanual_skills::tasks {

namespace {

[[noreturn]] void fail(const std::string& what) {
  throw std::invalid_argument("human guidance: " + what);
}

void range(const char* name, double low, double high, double min, double max) {
  if (!(std::isfinite(low) && std::isfinite(high) && low <= high && low >= min && high <= max)) {
    fail(std::string(name) + " [" + std::to_string(low) + ", " + std::to_string(high) + "] is not a range within [" +
         std::to_string(min) + ", " + std::to_string(max) + "]");
  }
}

void positive(const char* name, double value, double max) {
  if (!(value > 0.0 && value <= max)) {
    fail(std::string(name) + " " + std::to_string(value) + " is not in (0, " + std::to_string(max) + "]");
  }
}

void nonNegative(const char* name, double value, double max) {
  if (!(value >= 0.0 && value <= max)) {
    fail(std::string(name) + " " + std::to_string(value) + " is not in [0, " + std::to_string(max) + "]");
  }
}

double uniform(std::mt19937& rng, double low, double high) {
  return low + (high - low) * std::uniform_real_distribution<double>(0.0, 1.0)(rng);
}

}  // namespace

void PersonConfig::validate() const {
  range("take", take_min, take_max, 0.0, 1.0);
  range("release", release_min, release_max, 0.0, 1.0);
  if (!(release_min > take_max)) fail("the release range must lie beyond the take range");
  range("amplitude", amplitude_min, amplitude_max, 0.0, 1.0);
  range("guided seconds", guided_min, guided_max, 0.1, 60.0);
  if (!(pace_unevenness >= 0.0 && pace_unevenness < 1.0)) fail("pace_unevenness must be in [0, 1)");
  nonNegative("tremor", tremor, 0.05);
  positive("tremor_frequency", tremor_frequency, 100.0);
  positive("camera_rate", camera_rate, 1000.0);
  nonNegative("camera_noise", camera_noise, 0.05);
}

ScriptedPerson::ScriptedPerson(const PersonConfig& config, double line_length, std::uint32_t seed)
    : config_(config), length_(line_length) {
  config.validate();
  if (!(line_length > 0.0) || !std::isfinite(line_length)) fail("the line's length must be positive");
  std::mt19937 rng(seed);
  take_ = uniform(rng, config.take_min, config.take_max);
  release_ = uniform(rng, config.release_min, config.release_max);
  amplitude_ = uniform(rng, config.amplitude_min, config.amplitude_max);
  guided_ = uniform(rng, config.guided_min, config.guided_max);
  pace_ = uniform(rng, -config.pace_unevenness, config.pace_unevenness);
  tremor_phase_x_ = uniform(rng, 0.0, 2.0 * M_PI);
  tremor_phase_y_ = uniform(rng, 0.0, 2.0 * M_PI);
  std::normal_distribution<double> noise(0.0, config.camera_noise / line_length);
  const int count = static_cast<int>(std::floor(guided_ * config.camera_rate)) + 1;
  points_.reserve(static_cast<std::size_t>(count));
  const double w = 2.0 * M_PI * config.tremor_frequency, a = config.tremor / line_length;
  for (int i = 0; i < count; ++i) {
    const double t = i / config.camera_rate;
    Eigen::Vector2d p = intended(t);
    p.x() += a * std::sin(w * t + tremor_phase_x_) + noise(rng);
    p.y() += a * std::sin(w * t + tremor_phase_y_) + noise(rng);
    points_.push_back({t, p});
  }
}

Eigen::Vector2d ScriptedPerson::intended(double t) const noexcept {
  const double sigma = std::clamp(t / guided_, 0.0, 1.0);
  const double progress = sigma + pace_ * std::sin(2.0 * M_PI * sigma) / (2.0 * M_PI);
  const double x = take_ + (release_ - take_) * progress;
  // The same S every time: the first bottle left on the hand's left (the tool passes it on the line's right).
  return {x, -amplitude_ * std::sin(2.0 * M_PI * progress)};
}

void GuidanceConfig::validate() const {
  positive("line_speed", line_speed, 10.0);
  positive("lag", lag, 10.0);
  positive("max_speed", max_speed, 100.0);
  positive("max_seconds", max_seconds, 600.0);
}

GuidedReference guidedReference(const ScriptedPerson& person, const GuidanceConfig& config, double step) {
  config.validate();
  if (!(step > 0.0 && step <= 0.1)) fail("the step " + std::to_string(step) + " s is not in (0, 0.1]");
  const std::vector<HandPoint>& points = person.cameraPoints();
  const double omega = 1.0 / config.lag, tolerance = 1e-6;
  const long limit = std::lround(config.max_seconds / step);
  GuidedReference out;
  std::vector<Eigen::Vector2d> path{Eigen::Vector2d::Zero()};
  Eigen::Vector2d x = Eigen::Vector2d::Zero(), v = Eigen::Vector2d::Zero(), target = Eigen::Vector2d::Zero();
  enum class Phase { Line, Guided, Back } phase = Phase::Line;
  double phase_start = 0.0, back_from = 0.0;
  for (long k = 1;; ++k) {
    if (k > limit) fail("the reference did not reach the goal within " + std::to_string(config.max_seconds) + " s");
    const double t = static_cast<double>(k) * step;
    if (phase == Phase::Line) {
      target = {std::min(config.line_speed * t, person.take()), 0.0};
      if (config.line_speed * t >= person.take()) {
        phase = Phase::Guided;
        phase_start = t;
        out.take = static_cast<int>(k);
      }
    } else if (phase == Phase::Guided) {
      const double since = t - phase_start;
      const auto latest = std::upper_bound(points.begin(), points.end(), since,
                                           [](double s, const HandPoint& p) { return s < p.time; });
      target = std::prev(latest)->point;
      if (since >= person.guidedSeconds()) {
        phase = Phase::Back;
        phase_start = t;
        back_from = x.x();
        out.release = static_cast<int>(k);
      }
    }
    if (phase == Phase::Back) target = {std::min(back_from + config.line_speed * (t - phase_start), 1.0), 0.0};
    const Eigen::Vector2d a = omega * omega * (target - x) - 2.0 * omega * v;
    v += a * step;
    if (v.norm() > config.max_speed) v *= config.max_speed / v.norm();
    x += v * step;
    path.push_back(x);
    if (phase == Phase::Back && target.x() >= 1.0 && (x - target).norm() < tolerance &&
        v.norm() < tolerance / config.lag) {
      path.back() = target;
      break;
    }
  }
  out.path.resize(2, static_cast<Eigen::Index>(path.size()));
  for (std::size_t i = 0; i < path.size(); ++i) out.path.col(static_cast<Eigen::Index>(i)) = path[i];
  return out;
}

void GuidedLearningConfig::validate() const {
  person.validate();
  guidance.validate();
  if (runs < 2 || runs > 1000) fail("runs " + std::to_string(runs) + " is not in [2, 1000]");
  if (!(h >= 0.0 && h <= 1000.0)) fail("h " + std::to_string(h) + " is not in [0, 1000]");
  alignment.validate();
}

namespace {

/// The first path sample at or after `seconds` from the motion's start.
Eigen::Index sampleAt(const Eigen::VectorXd& times, double seconds) {
  const auto* it = std::lower_bound(times.data(), times.data() + times.size(), seconds - 1e-9);
  return std::min<Eigen::Index>(it - times.data(), times.size() - 1);
}

}  // namespace

GuidedLearning learnFromGuidance(WamBottleTask& task, const GuidedLearningConfig& config, std::uint32_t seed) {
  config.validate();
  const double step = task.simConfig().step;
  GuidedLearning out;
  out.runs.reserve(static_cast<std::size_t>(config.runs));
  std::array<std::vector<Eigen::MatrixXd>, 3> parts;
  std::vector<double> rewards;
  std::array<std::vector<double>, 3> seconds;
  for (int r = 0; r < config.runs; ++r) {
    const std::uint32_t s = seed + static_cast<std::uint32_t>(r);
    GuidedRun run{s, ScriptedPerson(config.person, task.lineLength(), s), {}, {}, {}, {}};
    run.reference = guidedReference(run.person, config.guidance, step);
    run.rollout = task.runPath(run.reference.path, s);
    if (run.rollout.outcome == FoldOutcome::Ok) {
      ++out.ok_runs;
      out.satisfactory_runs += run.rollout.satisfactory ? 1 : 0;
      const Eigen::VectorXd& times = run.rollout.path_times;
      const double end = static_cast<double>(run.reference.path.cols() - 1) * step;
      const std::array<Eigen::Index, 4> at = {0, sampleAt(times, run.reference.take * step),
                                              sampleAt(times, run.reference.release * step), sampleAt(times, end)};
      for (int p = 0; p < 3; ++p) {
        const Eigen::Index rows = at[p + 1] - at[p] + 1;
        if (rows < 2) fail("guided run " + std::to_string(s) + ": part " + std::to_string(p + 1) + " is empty");
        run.parts[p].resize(rows, 2);
        for (Eigen::Index i = 0; i < rows; ++i) {
          run.parts[p].row(i) = task.toLine(run.rollout.tool_path.col(at[p] + i)).transpose();
        }
        run.seconds[p] = times[at[p + 1]] - times[at[p]];
        parts[p].push_back(run.parts[p]);
        seconds[p].push_back(run.seconds[p]);
      }
      rewards.push_back(run.rollout.reward);
    }
    out.runs.push_back(std::move(run));
  }
  if (out.ok_runs < 2) {
    fail("only " + std::to_string(out.ok_runs) + " of " + std::to_string(config.runs) +
         " guided runs ran on the arm: nothing to average");
  }
  out.weights = learning::rewardWeights(Eigen::Map<const Eigen::VectorXd>(rewards.data(), out.ok_runs), config.h);
  const int n = config.alignment.samples;
  out.average.resize(3 * n - 2, 2);
  out.average_times.resize(3 * n - 2);
  double start = 0.0;
  Eigen::Index row = 0;
  for (int p = 0; p < 3; ++p) {
    out.alignment[p] = learning::alignCurves(parts[p], config.alignment);
    Eigen::MatrixXd mean = Eigen::MatrixXd::Zero(n, 2);
    double duration = 0.0;
    for (int k = 0; k < out.ok_runs; ++k) {
      mean += out.weights[k] * out.alignment[p].aligned[static_cast<std::size_t>(k)];
      duration += out.weights[k] * seconds[p][static_cast<std::size_t>(k)];
    }
    for (int i = p == 0 ? 0 : 1; i < n; ++i, ++row) {
      out.average.row(row) = mean.row(i);
      out.average_times[row] = start + duration * i / (n - 1);
    }
    start += duration;
  }
  // The task's DMP (10 kernels per DoF over its demonstration's 101 samples) fitted to the average in its own time.
  const Eigen::MatrixXd demonstration = BottleTask::demonstration();
  Eigen::MatrixXd resampled(demonstration.rows(), 2);
  for (Eigen::Index i = 0; i < resampled.rows(); ++i) {
    const double t = start * static_cast<double>(i) / static_cast<double>(resampled.rows() - 1);
    const Eigen::Index j = std::clamp<Eigen::Index>(
        std::upper_bound(out.average_times.data(), out.average_times.data() + out.average_times.size(), t) -
            out.average_times.data() - 1,
        0, out.average_times.size() - 2);
    const double f =
        std::clamp((t - out.average_times[j]) / (out.average_times[j + 1] - out.average_times[j]), 0.0, 1.0);
    resampled.row(i) = (1.0 - f) * out.average.row(j) + f * out.average.row(j + 1);
  }
  out.theta = DmpRollout::fit(resampled, BottleTask::kDemonstrationStep, task.kernels()).parameters();
  out.policy = task.run(out.theta, 0);
  return out;
}

}  // namespace bimanual_skills::tasks

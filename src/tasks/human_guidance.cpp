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

GuidanceFollower::GuidanceFollower(const GuidanceConfig& config) : config_(config) {
  config.validate();
}

void GuidanceFollower::reset() noexcept {
  phase_ = Phase::Line;
  x_.setZero();
  v_.setZero();
  target_.setZero();
  line_x_ = 0.0;
}

GuidanceFollower::Phase GuidanceFollower::step(double dt, bool raised, const Eigen::Vector2d& hand) noexcept {
  if (!(dt > 0.0) || phase_ == Phase::Arrived) return phase_;
  if (phase_ == Phase::Line && raised && hand.allFinite()) {
    phase_ = Phase::Guided;
  } else if (phase_ == Phase::Guided && !raised) {
    phase_ = Phase::Back;
    line_x_ = std::clamp(x_.x(), 0.0, 1.0);
  } else if (phase_ != Phase::Guided) {
    line_x_ = std::min(line_x_ + config_.line_speed * dt, 1.0);
  }
  if (phase_ == Phase::Guided) {
    if (hand.allFinite()) target_ = hand;  // a bad point: keep the last one
  } else {
    target_ = {line_x_, 0.0};
  }
  const double omega = 1.0 / config_.lag;
  v_ += (omega * omega * (target_ - x_) - 2.0 * omega * v_) * dt;
  const double speed = v_.norm();
  if (speed > config_.max_speed) v_ *= config_.max_speed / speed;
  x_ += v_ * dt;
  const double tolerance = 1e-6;
  if (phase_ != Phase::Guided && line_x_ >= 1.0 && (x_ - target_).norm() < tolerance &&
      v_.norm() < tolerance / config_.lag) {
    phase_ = Phase::Arrived;
    x_ = target_;
    v_.setZero();
  }
  return phase_;
}

GuidedReference guidedReference(const ScriptedPerson& person, const GuidanceConfig& config, double step) {
  config.validate();
  if (!(step > 0.0 && step <= 0.1)) fail("the step " + std::to_string(step) + " s is not in (0, 0.1]");
  const std::vector<HandPoint>& points = person.cameraPoints();
  const long limit = std::lround(config.max_seconds / step);
  GuidanceFollower follower(config);
  GuidedReference out;
  std::vector<Eigen::Vector2d> path{Eigen::Vector2d::Zero()};
  double take_time = -1.0;
  for (long k = 1; follower.phase() != GuidanceFollower::Phase::Arrived; ++k) {
    if (k > limit) fail("the reference did not reach the goal within " + std::to_string(config.max_seconds) + " s");
    const double t = static_cast<double>(k) * step;
    // The person raises the hand once the robot's line target passes the take, for the guided seconds.
    if (take_time < 0.0 && follower.phase() == GuidanceFollower::Phase::Line &&
        follower.target().x() + config.line_speed * step >= person.take()) {
      take_time = t;
    }
    const double since = take_time < 0.0 ? -1.0 : t - take_time;
    const bool raised = since >= 0.0 && since < person.guidedSeconds();
    Eigen::Vector2d hand = Eigen::Vector2d::Zero();
    if (raised) {
      const auto latest = std::upper_bound(points.begin(), points.end(), since,
                                           [](double s, const HandPoint& p) { return s < p.time; });
      hand = std::prev(latest)->point;
    }
    const GuidanceFollower::Phase before = follower.phase();
    const GuidanceFollower::Phase now = follower.step(step, raised, hand);
    if (before == GuidanceFollower::Phase::Line && now == GuidanceFollower::Phase::Guided) {
      out.take = static_cast<int>(k);
    }
    if (before == GuidanceFollower::Phase::Guided && now == GuidanceFollower::Phase::Back) {
      out.release = static_cast<int>(k);
    }
    path.push_back(follower.position());
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

std::array<Eigen::MatrixXd, 3> splitGuidedPath(const WamBottleTask& task, const Eigen::Matrix3Xd& tool,
                                               const Eigen::VectorXd& times, double take, double release, double end,
                                               std::array<double, 3>& seconds) {
  if (tool.cols() != times.size() || tool.cols() < 2) fail("a guided path needs as many times as samples, >= 2");
  const std::array<Eigen::Index, 4> at = {0, sampleAt(times, take), sampleAt(times, release), sampleAt(times, end)};
  std::array<Eigen::MatrixXd, 3> parts;
  for (int p = 0; p < 3; ++p) {
    const Eigen::Index rows = at[p + 1] - at[p] + 1;
    if (rows < 2) {
      fail("part " + std::to_string(p + 1) + " of a guided path (take " + std::to_string(take) + " s, release " +
           std::to_string(release) + " s, end " + std::to_string(end) + " s) has fewer than two samples");
    }
    parts[p].resize(rows, 2);
    for (Eigen::Index i = 0; i < rows; ++i) parts[p].row(i) = task.toLine(tool.col(at[p] + i)).transpose();
    seconds[p] = times[at[p + 1]] - times[at[p]];
  }
  return parts;
}

GuidedAverage averageGuidedRuns(const std::vector<std::array<Eigen::MatrixXd, 3>>& parts,
                                const std::vector<std::array<double, 3>>& seconds, const std::vector<double>& rewards,
                                const GuidedLearningConfig& config, int kernels) {
  config.validate();
  const std::size_t runs = parts.size();
  if (runs < 2) fail("only " + std::to_string(runs) + " guided runs to average: at least two are needed");
  if (seconds.size() != runs || rewards.size() != runs) fail("parts, durations and rewards of different counts");
  GuidedAverage out;
  out.weights = learning::rewardWeights(
      Eigen::Map<const Eigen::VectorXd>(rewards.data(), static_cast<Eigen::Index>(runs)), config.h);
  const int n = config.alignment.samples;
  out.average.resize(3 * n - 2, 2);
  out.average_times.resize(3 * n - 2);
  double start = 0.0;
  Eigen::Index row = 0;
  for (int p = 0; p < 3; ++p) {
    std::vector<Eigen::MatrixXd> curves;
    for (const std::array<Eigen::MatrixXd, 3>& r : parts) curves.push_back(r[p]);
    out.alignment[p] = learning::alignCurves(curves, config.alignment);
    Eigen::MatrixXd mean = Eigen::MatrixXd::Zero(n, 2);
    double duration = 0.0;
    for (std::size_t k = 0; k < runs; ++k) {
      mean += out.weights[static_cast<Eigen::Index>(k)] * out.alignment[p].aligned[k];
      duration += out.weights[static_cast<Eigen::Index>(k)] * seconds[k][p];
    }
    for (int i = p == 0 ? 0 : 1; i < n; ++i, ++row) {
      out.average.row(row) = mean.row(i);
      out.average_times[row] = start + duration * i / (n - 1);
    }
    start += duration;
  }
  // The task's DMP over its demonstration's 101 samples, fitted to the average in its own time.
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
  out.theta = DmpRollout::fit(resampled, BottleTask::kDemonstrationStep, kernels).parameters();
  return out;
}

GuidedLearning learnFromGuidance(WamBottleTask& task, const GuidedLearningConfig& config, std::uint32_t seed) {
  config.validate();
  const double step = task.simConfig().step;
  GuidedLearning out;
  out.runs.reserve(static_cast<std::size_t>(config.runs));
  std::vector<std::array<Eigen::MatrixXd, 3>> parts;
  std::vector<std::array<double, 3>> seconds;
  std::vector<double> rewards;
  for (int r = 0; r < config.runs; ++r) {
    const std::uint32_t s = seed + static_cast<std::uint32_t>(r);
    GuidedRun run{s, ScriptedPerson(config.person, task.lineLength(), s), {}, {}, {}, {}};
    run.reference = guidedReference(run.person, config.guidance, step);
    run.rollout = task.runPath(run.reference.path, s);
    if (run.rollout.outcome == FoldOutcome::Ok) {
      ++out.ok_runs;
      out.satisfactory_runs += run.rollout.satisfactory ? 1 : 0;
      run.parts = splitGuidedPath(task, run.rollout.tool_path, run.rollout.path_times, run.reference.take * step,
                                  run.reference.release * step,
                                  static_cast<double>(run.reference.path.cols() - 1) * step, run.seconds);
      parts.push_back(run.parts);
      seconds.push_back(run.seconds);
      rewards.push_back(run.rollout.reward);
    }
    out.runs.push_back(std::move(run));
  }
  if (out.ok_runs < 2) {
    fail("only " + std::to_string(out.ok_runs) + " of " + std::to_string(config.runs) +
         " guided runs ran on the arm: nothing to average");
  }
  static_cast<GuidedAverage&>(out) = averageGuidedRuns(parts, seconds, rewards, config, task.kernels());
  out.policy = task.run(out.theta, 0);
  return out;
}

}  // namespace bimanual_skills::tasks

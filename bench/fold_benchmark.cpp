// The cloth fold's ground truth against what the camera rewards make of it, and the best fold there is:
//
//   fold_benchmark --experiment folds|ceiling|rgbd_noise|repeatability|all --seed S --out DIR [--quick]
//                  [--count N] [--config FILE] [--jobs N] [--family symmetric|strategies] [--from DIR]
//
// folds: N clearly different folds (default 30), each the noise-free scripted demonstration of a fold drawn with the
//   seed: reach, lift, release height, duration and a late right arm (tasks::ClothFoldConfig's demo_*). Each is run
//   once and scored by every named reward setting on the same rendered images; the fold quality q of the cloth mesh
//   (tasks/fold_quality.hpp) is the ground truth. Writes DIR/folds.csv (a row per fold, as each finishes), the
//   camera's images of each fold (DIR/folds/NN_*.png: colour, and depth as 16-bit PNG in units of 0.1 mm), and
//   Spearman's rank correlation of each setting's reward with q (bootstrap interval over the folds) in
//   summary.json and tables.md (scripts/plot_fold_benchmark.py). Each fold is also scored (the first setting) on the
//   images of the perspective RGB-D camera (tasks::rgbdCameraFor, Kinect-like noise and holes) re-projected into the
//   reward's map (DIR/folds/NN_rgbd*.png): its Spearman with q and with the orthographic camera's reward, and its
//   offset (mean and 95 % Student-t interval over the folds).
// ceiling: q_max, the best fold a search with a large budget and the ground truth itself finds: CMA-ES on q over the
//   scripted demonstration's reach, lift, release height and duration (60 generations of 10), then CMA-ES on q over
//   the 12 goal offsets of the learner's policy from the best of those (120 generations of 12): 2040 rollouts.
//   Writes DIR/ceiling.csv (every rollout, as each generation finishes) and q_max in summary.json.
// repeatability: the learning file's demonstration N times (default 20, the thesis' count) with rollout seeds drawn
//   from the seed, the task's robot noise (tasks::FoldNoise) and the camera's: mean, standard deviation and its share
//   of the mean of the reward, its fold term, (7.52)'s R_color and R_depth, and q (DIR/repeatability.csv).
// learned: the final noise-free policies of a fold_learner directory (--from DIR) that are the task's whole policy
//   (the standard DMP's, PI2-CMA's, CMA-ES's), each as learned and N times (default 4) moved by a fraction of the
//   learner's exploration: Spearman's rho of the reward with q where learning ends (q >= 0.8), DIR/learned.csv.
//   --family strategies runs the folds experiment on other strategies: one arm folding, the corners carried inwards
//   (a diagonal fold), a late release.
// The learning file (--config, default config/fold_demo.yaml) gives the simulation, the controllers, the camera's
// noise and the reward's settings; only the demonstration (and, in the ceiling's second stage, the goals) changes.
#include "bimanual_skills/learning/covariance_adaptation.hpp"
#include "bimanual_skills/learning/gaussian.hpp"
#include "bimanual_skills/learning/rank_correlation.hpp"
#include "bimanual_skills/learning/student_t.hpp"
#include "bimanual_skills/parallel/parallel_for.hpp"
#include "bimanual_skills/rollout/fold_learning.hpp"
#include "bimanual_skills/rollout/fold_rollout_task.hpp"
#include "cli/package_share.hpp"
#include "cli/pinned_numerics.hpp"
#include "experiment_cli.hpp"
#include "io/csv_records.hpp"
#include "parallel_runs.hpp"

#include <opencv2/imgcodecs.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <memory>
#include <mutex>
#include <random>
#include <stdexcept>
#include <string>
#include <tuple>
#include <vector>

namespace bs = bimanual_skills;
namespace br = bimanual_skills::rollout;
namespace bt = bimanual_skills::tasks;

namespace {

using Options = bs::bench::ExperimentOptions;

/// The reward settings every fold is scored by, the learning file's first.
std::vector<std::string> rewardSettings() {
  return {"fold", "thesis", "goal"};
}

/// One scripted fold of the set.
struct FoldDraw {
  double reach = 0.0, lift = 0.0, drop = 0.0, duration = 0.0, lag = 0.0;
  double right_arc = 1.0, inward = 0.0;  ///< tasks::ClothFoldConfig's demo_right_arc, demo_inward.
  double hold_after = -1.0;              ///< The hold before the release [s]; < 0: the learning file's.
};

/// The folds experiment's sets: both arms on mirrored arcs (the scripted demonstration's family), or other
/// strategies: one arm folding, the corners carried inwards (a diagonal fold), the release late.
enum class FoldFamily { Symmetric, Strategies };

/// Fold `index` of the set of `seed`: reach 0–1.1 (the arc's end, × the cloth's half length before the fold line),
/// lift 0.1–0.7, release height 0–0.3 m, duration 2.5–5 s; in the symmetric family a third of the folds have the
/// right arm 10–40 % late; in the strategies family (a stream of its own) a third each have the right arm make 0–30 %
/// of its arc (one arm folds), the arcs end 30–90 % of the half width inwards (a diagonal fold), or the grippers open
/// 0.8–2 s after the movement instead of 0.3 s (a late release).
FoldDraw drawFold(std::uint32_t seed, int index, FoldFamily family = FoldFamily::Symmetric) {
  std::seed_seq sequence{seed, family == FoldFamily::Symmetric ? 0xf01du : 0x57a7u, static_cast<std::uint32_t>(index)};
  std::mt19937 rng(sequence);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  FoldDraw d;
  d.reach = 1.1 * unit(rng);
  d.lift = 0.1 + 0.6 * unit(rng);
  d.drop = 0.3 * unit(rng);
  d.duration = 2.5 + 2.5 * unit(rng);
  const double which = unit(rng), amount = unit(rng);
  if (family == FoldFamily::Symmetric) {
    d.lag = which < 1.0 / 3.0 ? 0.1 + 0.3 * amount : 0.0;
  } else if (which < 1.0 / 3.0) {
    d.right_arc = 0.3 * amount;
  } else if (which < 2.0 / 3.0) {
    d.inward = 0.3 + 0.6 * amount;
  } else {
    d.hold_after = 0.8 + 1.2 * amount;
  }
  return d;
}

/// The learning file's task with the scripted demonstration `d`.
bt::ClothFoldConfig withDemonstration(bt::ClothFoldConfig task, const FoldDraw& d) {
  task.demonstration_files.clear();
  task.demo_reach = d.reach;
  task.demo_lift = d.lift;
  task.demo_drop = d.drop;
  task.duration = d.duration;
  task.demo_lag = d.lag;
  task.demo_right_arc = d.right_arc;
  task.demo_inward = d.inward;
  if (d.hold_after >= 0.0) task.hold_after = d.hold_after;
  return task;
}

/// Writes a colour image and a depth image (CV_32FC1 [m]) as DIR/NAME.png and DIR/NAME_depth.png (uint16, 0.1 mm).
void writeImages(const std::string& dir, const std::string& name, const cv::Mat& bgr, const cv::Mat& depth) {
  cv::imwrite(dir + "/" + name + ".png", bgr);
  cv::Mat tenths;
  depth.convertTo(tenths, CV_16U, 1e4);
  cv::imwrite(dir + "/" + name + "_depth.png", tenths);
}

/// The fold reward of one rollout through the perspective RGB-D camera re-projected into the reward's map (flat and
/// final cloth, noise from `rng`), and the share of the map the camera saw.
std::pair<bt::FoldRewardTerms, double> perspectiveReward(const br::FoldLearningConfig& config,
                                                         const std::string& setting, const bt::ClothFoldTask& fold,
                                                         const bt::FoldRollout& rollout, std::mt19937& rng,
                                                         const std::string& images = "") {
  const bt::FoldRewardConfig reward_config = bt::rewardSetting(config.reward, setting, "fold_benchmark");
  bt::FoldReward reward(reward_config, fold.simConfig().cloth.length * fold.simConfig().cloth.width,
                        fold.idealFoldVertices(), fold.clothTriangles());
  bs::vision::PerspectiveRenderer rgbd(config.reward.renderer, bt::rgbdCameraFor(fold.simConfig()));
  bs::vision::HeightMapProjector projector(config.reward.renderer.camera);
  rgbd.render(rollout.cloth_rest_vertices, rollout.cloth_triangles, rng);
  projector.project(rgbd.bgr(), rgbd.depth(), rgbd.camera());
  reward.observeFlat(projector.bgr(), projector.depth());
  rgbd.render(rollout.cloth_vertices, rollout.cloth_triangles, rng);
  const bs::vision::VisionStatus seen = projector.project(rgbd.bgr(), rgbd.depth(), rgbd.camera());
  const bt::FoldRewardTerms terms =
      reward.evaluateImages(rollout.outcome, rollout.acceleration_cost, projector.bgr(), projector.depth());
  const bs::vision::HeightMapCoverage& c = projector.coverage();
  const double coverage = seen == bs::vision::VisionStatus::Ok ? static_cast<double>(c.observed + c.filled) /
                                                                     (projector.map().rows * projector.map().columns)
                                                               : 0.0;
  if (!images.empty()) {
    writeImages(std::filesystem::path(images).parent_path().string(), std::filesystem::path(images).filename().string(),
                rgbd.bgr(), rgbd.depth());
    writeImages(std::filesystem::path(images).parent_path().string(),
                std::filesystem::path(images).filename().string() + "_map", projector.bgr(), projector.depth());
  }
  return {terms, coverage};
}

struct FoldResult {
  FoldDraw draw;
  bt::FoldOutcome outcome = bt::FoldOutcome::Ok;
  std::string reason;
  bt::FoldQuality fold;
  double acceleration_cost = 0.0;
  std::vector<bt::FoldRewardTerms> terms;  ///< Per reward setting.
  /// The first setting's reward on the perspective RGB-D camera's images re-projected into the reward's map (the
  /// same final and flat cloth), and the share of the map the camera saw.
  bt::FoldRewardTerms perspective;
  double perspective_coverage = 0.0;
};

void foldsExperiment(const Options& options, const br::FoldLearningConfig& config, int count, FoldFamily family,
                     std::vector<bs::bench::JsonRow>& rows) {
  const char* family_name = family == FoldFamily::Symmetric ? "symmetric" : "strategies";
  const std::string image_dir = options.out + "/folds";
  std::filesystem::create_directories(image_dir);
  const std::vector<std::string> settings = rewardSettings();
  std::ofstream csv(options.out + "/folds.csv");
  csv << "index,reach,lift,drop,duration,lag,right_arc,inward,hold_after,outcome,fold_quality,fold_distance,"
         "fold_displacement,acceleration_cost";
  for (const std::string& s : settings) {
    csv << ',' << s << "_reward," << s << "_r_acceleration," << s << "_r_color," << s << "_r_depth," << s << "_r_goal,"
        << s << "_goal_mismatch," << s << "_r_fold";
  }
  csv << ",fold_mismatch,fold_edge,fold_single,fold_length,fold_heap,perspective_reward,perspective_r_fold,perspective_"
         "coverage,"
         "reason\n";
  std::vector<FoldResult> results(static_cast<std::size_t>(count));
  std::printf("fold_benchmark folds: %d scripted folds (%s family) of seed %u on %d threads\n", count, family_name,
              options.seed, options.jobs);
  bs::bench::parallelRuns(
      count, options.jobs,
      [&](int i) {
        FoldResult& r = results[static_cast<std::size_t>(i)];
        r.draw = drawFold(options.seed, i, family);
        bt::ClothFoldTask fold(withDemonstration(config.task, r.draw));
        const bt::FoldRollout rollout = fold.run(fold.demonstrationParameters());
        r.outcome = rollout.outcome;
        r.reason = rollout.reason;
        r.fold = rollout.fold;
        r.acceleration_cost = rollout.acceleration_cost;
        const std::uint32_t noise_seed = options.seed * 1000u + static_cast<std::uint32_t>(i);
        for (const std::string& name : settings) {
          const bt::FoldRewardConfig reward_config = bt::rewardSetting(config.reward, name, "fold_benchmark");
          bt::FoldReward reward(reward_config, fold.simConfig().cloth.length * fold.simConfig().cloth.width,
                                fold.idealFoldVertices(), fold.clothTriangles());
          std::seed_seq sequence{noise_seed, 0x5eedu};
          std::mt19937 rng(sequence);
          r.terms.push_back(reward.evaluate(rollout, rng));
          if (&name == &settings.front()) {
            char stem[32];
            std::snprintf(stem, sizeof stem, "%02d_final", i);
            writeImages(image_dir, stem, reward.bgr(), reward.depth());
          }
        }
        // The same final and flat cloth through the perspective RGB-D camera, re-projected into the reward's map.
        {
          std::seed_seq sequence{noise_seed, 0x96bdu};
          std::mt19937 rng(sequence);
          char stem[32];
          std::snprintf(stem, sizeof stem, "/%02d_rgbd", i);
          std::tie(r.perspective, r.perspective_coverage) =
              perspectiveReward(config, settings.front(), fold, rollout, rng, image_dir + stem);
        }
        // The flat cloth as the camera sees it after the reset.
        bs::vision::ClothRenderer renderer(config.reward.renderer);
        std::seed_seq flat_sequence{noise_seed, 0xf1a7u};
        std::mt19937 flat_rng(flat_sequence);
        renderer.render(rollout.cloth_rest_vertices, rollout.cloth_triangles, flat_rng);
        char stem[32];
        std::snprintf(stem, sizeof stem, "%02d_flat", i);
        writeImages(image_dir, stem, renderer.bgr(), renderer.depth());
      },
      [&](int i) {
        const FoldResult& r = results[static_cast<std::size_t>(i)];
        std::printf(
            "  fold %2d: reach %.2f lift %.2f drop %.3f duration %.2f lag %.2f right arc %.2f inward %.2f hold %.2f"
            "  q %6.3f  %s\n",
            i, r.draw.reach, r.draw.lift, r.draw.drop, r.draw.duration, r.draw.lag, r.draw.right_arc, r.draw.inward,
            r.draw.hold_after >= 0.0 ? r.draw.hold_after : config.task.hold_after, r.fold.q, bt::toString(r.outcome));
        std::fflush(stdout);
        csv << i << ',' << r.draw.reach << ',' << r.draw.lift << ',' << r.draw.drop << ',' << r.draw.duration << ','
            << r.draw.lag << ',' << r.draw.right_arc << ',' << r.draw.inward << ','
            << (r.draw.hold_after >= 0.0 ? r.draw.hold_after : config.task.hold_after) << ',' << bt::toString(r.outcome)
            << ',' << r.fold.q << ',' << r.fold.distance << ',' << r.fold.displacement << ',' << r.acceleration_cost;
        for (const bt::FoldRewardTerms& t : r.terms) {
          csv << ',' << t.reward << ',' << t.r_acceleration << ',' << t.r_color << ',' << t.r_depth << ',' << t.r_goal
              << ',' << t.goal_mismatch << ',' << t.r_fold;
        }
        const bt::FoldRewardTerms& t = r.terms.front();
        csv << ',' << t.fold_mismatch << ',' << t.fold_edge << ',' << t.fold_single << ',' << t.fold_length << ','
            << t.fold_heap << ',' << r.perspective.reward << ',' << r.perspective.r_fold << ','
            << r.perspective_coverage << ",\"" << r.reason << "\"\n"
            << std::flush;
        rows.emplace_back()
            .add("experiment", "folds")
            .add("index", i)
            .add("fold_quality", r.fold.q)
            .add("outcome", bt::toString(r.outcome));
      });
  // How each reward ranks the folds that finished: Spearman's ρ with q and its bootstrap interval over the folds.
  std::vector<double> q;
  std::vector<std::vector<double>> signals(settings.size() + 1);
  for (const FoldResult& r : results) {
    if (r.outcome != bt::FoldOutcome::Ok) continue;
    q.push_back(r.fold.q);
    for (std::size_t s = 0; s < settings.size(); ++s) signals[s].push_back(r.terms[s].reward);
    signals.back().push_back(-r.terms.front().fold_mismatch);
  }
  std::printf("fold_benchmark folds: %zu of %d folds finished; Spearman's rho with q (95 %% bootstrap interval):\n",
              q.size(), count);
  for (std::size_t s = 0; s <= settings.size() && q.size() >= 2; ++s) {
    const std::string name = s < settings.size() ? settings[s] + " reward" : "fold image term (-E/E_flat)";
    const bs::learning::BootstrapInterval rho = bs::learning::bootstrapSpearman(signals[s], q, 10000, options.seed);
    std::printf("  %-30s %6.3f [%6.3f, %6.3f]\n", name.c_str(), rho.estimate, rho.low, rho.high);
    rows.emplace_back()
        .add("experiment", "ranking")
        .add("family", family_name)
        .add("signal", name)
        .add("folds", static_cast<int>(q.size()))
        .add("spearman", rho.estimate)
        .add("spearman_low", rho.low)
        .add("spearman_high", rho.high)
        .add("bootstrap_resamples", rho.resamples);
  }
  // The perspective camera against the orthographic one on the same folds (the learner's setting): how each ranks
  // the folds, how they rank each other, and the offset of the perspective reward (mean, 95 % Student-t interval).
  std::vector<double> orthographic, perspective, offset;
  for (const FoldResult& r : results) {
    if (r.outcome != bt::FoldOutcome::Ok) continue;
    orthographic.push_back(r.terms.front().reward);
    perspective.push_back(r.perspective.reward);
    offset.push_back(r.perspective.reward - r.terms.front().reward);
  }
  if (q.size() >= 3) {
    const bs::learning::BootstrapInterval with_q = bs::learning::bootstrapSpearman(perspective, q, 10000, options.seed);
    const bs::learning::BootstrapInterval with_o =
        bs::learning::bootstrapSpearman(perspective, orthographic, 10000, options.seed);
    const bs::learning::MeanInterval shift = bs::learning::meanInterval95(offset);
    std::printf(
        "fold_benchmark folds: perspective RGB-D camera (%s reward, re-projected): Spearman with q %.3f [%.3f, %.3f], "
        "with the orthographic camera's reward %.3f [%.3f, %.3f]; offset %.4f +- %.4f (95 %% t interval, %d folds)\n",
        settings.front().c_str(), with_q.estimate, with_q.low, with_q.high, with_o.estimate, with_o.low, with_o.high,
        shift.mean, shift.half_width, shift.n);
    rows.emplace_back()
        .add("experiment", "perspective_camera")
        .add("setting", settings.front())
        .add("folds", shift.n)
        .add("spearman_with_q", with_q.estimate)
        .add("spearman_with_q_low", with_q.low)
        .add("spearman_with_q_high", with_q.high)
        .add("spearman_with_orthographic", with_o.estimate)
        .add("spearman_with_orthographic_low", with_o.low)
        .add("spearman_with_orthographic_high", with_o.high)
        .add("offset_mean", shift.mean)
        .add("offset_half_width_95", shift.half_width)
        .add("offset_std_dev", shift.std_dev);
  }
}

/// A learning directory's final noise-free policies with as many latent weights as the task's whole policy (the
/// standard DMP's, PI2-CMA's and CMA-ES's, whose coordination is the demonstration's PCA fit, a rotation): from its
/// rollout_parameters.csv the last epoch's `policy` rollout of each run, from its coordination.csv the run's final
/// coordination matrices Ω, with which the weights run.
struct LearnedPolicy {
  std::string algorithm;
  int run = 0, epoch = -1;
  Eigen::VectorXd theta;
  std::vector<Eigen::MatrixXd> coordination;
};

/// DIR/coordination.csv: (algorithm, run) → its final Ω's (rows of `dofs` values each, matrix by matrix).
std::map<std::pair<std::string, int>, std::vector<Eigen::MatrixXd>> finalCoordination(const std::string& dir,
                                                                                      int dofs) {
  const std::string path = dir + "/coordination.csv";
  std::ifstream in(path);
  if (!in) throw std::invalid_argument("cannot read " + path + " (--from: a fold_learner output directory)");
  std::map<std::pair<std::string, int>, std::vector<std::vector<Eigen::VectorXd>>> rows;
  std::string line;
  for (int n = 1; std::getline(in, line); ++n) {
    if (n == 1 || line.empty()) continue;
    const std::string where = path + " line " + std::to_string(n);
    const std::vector<std::string> f = bs::io::splitCsv(line);
    if (f.size() < 5) throw std::invalid_argument(where + ": too few fields");
    const int matrix = bs::io::parseInteger(f[2], where), row = bs::io::parseInteger(f[3], where);
    std::vector<std::vector<Eigen::VectorXd>>& matrices = rows[{f[0], bs::io::parseInteger(f[1], where)}];
    if (matrix < 0 || matrix > static_cast<int>(matrices.size()) || row < 0 || row >= dofs) {
      throw std::invalid_argument(where + ": matrix or row out of order");
    }
    if (matrix == static_cast<int>(matrices.size())) matrices.emplace_back();
    std::vector<Eigen::VectorXd>& m = matrices[static_cast<std::size_t>(matrix)];
    if (row != static_cast<int>(m.size())) throw std::invalid_argument(where + ": rows out of order");
    Eigen::VectorXd values(static_cast<Eigen::Index>(f.size() - 4));
    for (std::size_t i = 4; i < f.size(); ++i)
      values[static_cast<Eigen::Index>(i - 4)] = bs::io::parseNumber(f[i], where);
    if (!m.empty() && values.size() != m.front().size())
      throw std::invalid_argument(where + ": a row of another width");
    m.push_back(values);
  }
  std::map<std::pair<std::string, int>, std::vector<Eigen::MatrixXd>> out;
  for (const auto& [key, matrices] : rows) {
    for (const std::vector<Eigen::VectorXd>& m : matrices) {
      if (static_cast<int>(m.size()) != dofs) throw std::invalid_argument(path + ": a matrix without all its rows");
      Eigen::MatrixXd omega(dofs, m.front().size());
      for (int i = 0; i < dofs; ++i) omega.row(i) = m[static_cast<std::size_t>(i)].transpose();
      out[key].push_back(omega);
    }
  }
  return out;
}

std::vector<LearnedPolicy> finalPolicies(const std::string& dir, int parameters) {
  const std::string path = dir + "/rollout_parameters.csv";
  std::ifstream in(path);
  if (!in) throw std::invalid_argument("cannot read " + path + " (--from: a fold_learner output directory)");
  std::map<std::pair<std::string, int>, LearnedPolicy> last;
  std::string line;
  for (int n = 1; std::getline(in, line); ++n) {
    if (n == 1 || line.empty()) continue;
    const std::string where = path + " line " + std::to_string(n);
    const std::vector<std::string> f = bs::io::splitCsv(line);
    if (f.size() < 6) throw std::invalid_argument(where + ": too few fields");
    if (f[3] != "policy" || bs::io::parseInteger(f[5], where) != parameters) continue;
    if (f.size() != 6 + static_cast<std::size_t>(parameters)) throw std::invalid_argument(where + ": a short record");
    LearnedPolicy p;
    p.algorithm = f[0];
    p.run = bs::io::parseInteger(f[1], where);
    p.epoch = bs::io::parseInteger(f[2], where);
    p.theta.resize(parameters);
    for (int i = 0; i < parameters; ++i) p.theta[i] = bs::io::parseNumber(f[6 + static_cast<std::size_t>(i)], where);
    LearnedPolicy& slot = last[{p.algorithm, p.run}];
    if (p.epoch > slot.epoch) slot = p;
  }
  const auto coordination = finalCoordination(dir, bt::ClothFoldTask::kDofs);
  std::vector<LearnedPolicy> out;
  for (const auto& [key, policy] : last) {
    const auto omega = coordination.find(key);
    if (omega == coordination.end()) {
      throw std::invalid_argument(dir + "/coordination.csv has no coordination of " + key.first + " run " +
                                  std::to_string(key.second));
    }
    out.push_back(policy);
    out.back().coordination = omega->second;
  }
  if (out.empty()) {
    throw std::invalid_argument(path + " holds no noise-free policy of " + std::to_string(parameters) +
                                " parameters (the standard DMP's, PI2-CMA's or CMA-ES's runs)");
  }
  return out;
}

/// learned: the reward where learning ends. Each final policy of `from` (finalPolicies) runs as learned and
/// `perturbations` times moved by the learner's own exploration (initial_stddev per weight, goal_stddev per goal)
/// scaled by 0.5 k / perturbations, k = 1 …: folds of q about 0.75–0.95 from strategies the learning found, not
/// scripted. Spearman's ρ of the learning file's reward (and its image term) with q, over all of them and over those
/// with q ≥ 0.8, with bootstrap intervals over the folds. Writes DIR/learned.csv.
void learnedExperiment(const Options& options, const br::FoldLearningConfig& config, const std::string& from,
                       int perturbations, std::vector<bs::bench::JsonRow>& rows) {
  if (from.empty()) throw std::invalid_argument("the learned experiment needs --from DIR (a fold_learner directory)");
  bt::ClothFoldTask probe(config.task);
  const int basis = probe.policyBasisSize(), kernels = config.task.kernels;
  const double goal_sigma = probe.dmpParameters().alpha_z * probe.dmpParameters().beta_z * config.goal_stddev;
  const std::vector<LearnedPolicy> policies = finalPolicies(from, probe.parameterCount());
  struct Fold {
    const LearnedPolicy* policy = nullptr;
    int k = 0;
    double scale = 0.0;
    std::uint32_t seed = 0;
    bt::FoldRollout rollout;
    bt::FoldRewardTerms terms;
  };
  std::vector<Fold> folds;
  for (const LearnedPolicy& p : policies) {
    for (int k = 0; k <= perturbations; ++k) {
      Fold f;
      f.policy = &p;
      f.k = k;
      f.scale = 0.5 * k / std::max(perturbations, 1);
      folds.push_back(f);
    }
  }
  std::mt19937 seeds(options.seed);
  for (Fold& f : folds) f.seed = static_cast<std::uint32_t>(seeds());
  std::printf("fold_benchmark learned: %zu final policies of %s, each as learned and %d times perturbed, seed %u\n",
              policies.size(), from.c_str(), perturbations, options.seed);
  std::ofstream csv(options.out + "/learned.csv");
  csv << "algorithm,run,epoch,perturbation,scale,seed,outcome,fold_quality,reward,r_fold,fold_mismatch\n";
  bs::bench::parallelRuns(
      static_cast<int>(folds.size()), options.jobs,
      [&](int i) {
        Fold& f = folds[static_cast<std::size_t>(i)];
        std::mt19937 rng(f.seed);
        std::normal_distribution<double> normal;
        Eigen::VectorXd theta = f.policy->theta;
        for (Eigen::Index j = 0; j < theta.size(); ++j) {
          const double sigma = static_cast<int>(j % basis) < kernels ? config.initial_stddev : goal_sigma;
          theta[j] += f.scale * sigma * normal(rng);
        }
        br::FoldRolloutTask task(config.task, config.reward);
        f.rollout = task.task().run(f.policy->coordination, theta, f.seed);
        f.terms = task.score(f.rollout, f.seed);
      },
      [&](int i) {
        const Fold& f = folds[static_cast<std::size_t>(i)];
        std::printf("  %s run %d, perturbation %d (x%.3f): q %.3f, R %.4f  %s\n", f.policy->algorithm.c_str(),
                    f.policy->run, f.k, f.scale, f.rollout.fold.q, f.terms.reward, bt::toString(f.rollout.outcome));
        std::fflush(stdout);
        csv << '"' << f.policy->algorithm << "\"," << f.policy->run << ',' << f.policy->epoch << ',' << f.k << ','
            << f.scale << ',' << f.seed << ',' << bt::toString(f.rollout.outcome) << ',' << f.rollout.fold.q << ','
            << f.terms.reward << ',' << f.terms.r_fold << ',' << f.terms.fold_mismatch << '\n'
            << std::flush;
      });
  std::printf("fold_benchmark learned: Spearman's rho with q (95 %% bootstrap interval over the folds):\n");
  for (const double q_low : {0.0, 0.8}) {
    std::vector<double> q, reward, image;
    double q_min = 1.0, q_max = 0.0;
    for (const Fold& f : folds) {
      if (f.rollout.outcome != bt::FoldOutcome::Ok || f.rollout.fold.q < q_low) continue;
      q.push_back(f.rollout.fold.q);
      reward.push_back(f.terms.reward);
      image.push_back(-f.terms.fold_mismatch);
      q_min = std::min(q_min, f.rollout.fold.q);
      q_max = std::max(q_max, f.rollout.fold.q);
    }
    if (q.size() < 3) continue;
    for (const auto& [signal, values] : {std::pair{"fold reward", &reward}, std::pair{"fold image term", &image}}) {
      const bs::learning::BootstrapInterval rho = bs::learning::bootstrapSpearman(*values, q, 10000, options.seed);
      std::printf("  %-16s q >= %.1f (%zu folds, q %.3f-%.3f): %6.3f [%6.3f, %6.3f]\n", signal, q_low, q.size(), q_min,
                  q_max, rho.estimate, rho.low, rho.high);
      rows.emplace_back()
          .add("experiment", "learned_ranking")
          .add("signal", signal)
          .add("q_at_least", q_low)
          .add("folds", static_cast<int>(q.size()))
          .add("q_min", q_min)
          .add("q_max", q_max)
          .add("spearman", rho.estimate)
          .add("spearman_low", rho.low)
          .add("spearman_high", rho.high);
    }
  }
}

/// repeatability: the learning file's demonstration run `count` times with rollout seeds drawn from the seed (the
/// robot's noise of the file's task, if any, and the camera's), as the thesis ran its first attempt 20 times: mean,
/// standard deviation and coefficient of variation of the reward, its image term, (7.52)'s R_color and R_depth on the
/// same images, and q.
void repeatabilityExperiment(const Options& options, const br::FoldLearningConfig& config, int count,
                             std::vector<bs::bench::JsonRow>& rows) {
  struct Repetition {
    std::uint32_t seed = 0;
    bt::FoldRollout rollout;
    bt::FoldRewardTerms learned, thesis;
  };
  std::vector<Repetition> results(static_cast<std::size_t>(count));
  std::mt19937 seeds(options.seed);
  for (Repetition& r : results) r.seed = static_cast<std::uint32_t>(seeds());
  std::printf("fold_benchmark repeatability: the demonstration %d times (noise %s), seed %u, %d threads\n", count,
              config.task.noise.setting.c_str(), options.seed, options.jobs);
  std::ofstream csv(options.out + "/repeatability.csv");
  csv << "index,seed,outcome,reward,r_fold,r_acceleration,thesis_reward,r_color,r_depth,fold_quality,cloth_x,cloth_y,"
         "cloth_yaw,release_left,release_right\n";
  bs::bench::parallelRuns(
      count, options.jobs,
      [&](int i) {
        Repetition& r = results[static_cast<std::size_t>(i)];
        br::FoldRolloutTask task(config.task, config.reward);
        bt::ClothFoldTask& fold = task.task();
        r.rollout = fold.run({Eigen::MatrixXd::Identity(bt::ClothFoldTask::kDofs, bt::ClothFoldTask::kDofs)},
                             fold.demonstrationParameters(), r.seed);
        r.learned = task.score(r.rollout, r.seed);
        // (7.52) on the same images: the same camera noise (FoldRolloutTask::score's stream).
        bt::FoldReward thesis(bt::rewardSetting(config.reward, "thesis", "fold_benchmark"),
                              fold.simConfig().cloth.length * fold.simConfig().cloth.width, fold.idealFoldVertices(),
                              fold.clothTriangles());
        std::seed_seq sequence{r.seed, 0x5eedu};
        std::mt19937 rng(sequence);
        r.thesis = thesis.evaluate(r.rollout, rng);
      },
      [&](int i) {
        const Repetition& r = results[static_cast<std::size_t>(i)];
        const bt::FoldNoiseDraw& n = r.rollout.noise;
        std::printf("  repetition %2d: R %.4f (fold %.4f), R_color %.4f, R_depth %.4f, q %.3f  %s\n", i,
                    r.learned.reward, r.learned.r_fold, r.thesis.r_color, r.thesis.r_depth, r.rollout.fold.q,
                    bt::toString(r.rollout.outcome));
        std::fflush(stdout);
        csv << i << ',' << r.seed << ',' << bt::toString(r.rollout.outcome) << ',' << r.learned.reward << ','
            << r.learned.r_fold << ',' << r.learned.r_acceleration << ',' << r.thesis.reward << ',' << r.thesis.r_color
            << ',' << r.thesis.r_depth << ',' << r.rollout.fold.q << ',' << n.cloth_x << ',' << n.cloth_y << ','
            << n.cloth_yaw << ',' << n.release[0] << ',' << n.release[1] << '\n'
            << std::flush;
      });
  const auto summarise = [&](const std::string& signal, const auto& value) {
    std::vector<double> values;
    for (const Repetition& r : results) {
      if (r.rollout.outcome == bt::FoldOutcome::Ok) values.push_back(value(r));
    }
    if (values.size() < 2) return;
    const bs::learning::MeanInterval m = bs::learning::meanInterval95(values);
    const double cv = m.mean != 0.0 ? m.std_dev / std::abs(m.mean) : 0.0;
    std::printf("  %-14s %8.4f +- %.4f (std dev; %.1f %% of the mean), %d repetitions\n", signal.c_str(), m.mean,
                m.std_dev, 100.0 * cv, m.n);
    rows.emplace_back()
        .add("experiment", "repeatability")
        .add("noise", config.task.noise.setting)
        .add("signal", signal)
        .add("repetitions", m.n)
        .add("mean", m.mean)
        .add("std_dev", m.std_dev)
        .add("coefficient_of_variation", cv);
  };
  std::printf("fold_benchmark repeatability (the thesis' 20 runs: R_depth 0.473 +- 0.029, R_color 0.799 +- 0.088):\n");
  summarise("reward", [](const Repetition& r) { return r.learned.reward; });
  summarise("r_fold", [](const Repetition& r) { return r.learned.r_fold; });
  summarise("r_color", [](const Repetition& r) { return r.thesis.r_color; });
  summarise("r_depth", [](const Repetition& r) { return r.thesis.r_depth; });
  summarise("fold_quality", [](const Repetition& r) { return r.rollout.fold.q; });
  int failed = 0;
  for (const Repetition& r : results) failed += r.rollout.outcome != bt::FoldOutcome::Ok ? 1 : 0;
  rows.emplace_back()
      .add("experiment", "repeatability")
      .add("noise", config.task.noise.setting)
      .add("signal", "failed")
      .add("repetitions", count)
      .add("failed", failed);
}

/// rgbd_noise: the first `count` folds of the set, each scored `draws` times with fresh camera noise through the
/// orthographic and the perspective camera: how much the fold term moves with the sensor's noise alone.
void rgbdNoiseExperiment(const Options& options, const br::FoldLearningConfig& config, int count, int draws,
                         std::vector<bs::bench::JsonRow>& rows) {
  std::ofstream csv(options.out + "/rgbd_noise.csv");
  csv << "index,fold_quality,draw,camera,fold_mismatch,reward\n";
  const std::string setting = rewardSettings().front();
  std::printf("fold_benchmark rgbd_noise: %d folds of seed %u, %d noise draws each, both cameras\n", count,
              options.seed, draws);
  std::vector<std::vector<double>> ortho(static_cast<std::size_t>(count)), persp(static_cast<std::size_t>(count));
  std::vector<double> q(static_cast<std::size_t>(count), std::nan(""));
  bs::bench::parallelRuns(
      count, options.jobs,
      [&](int i) {
        bt::ClothFoldTask fold(withDemonstration(config.task, drawFold(options.seed, i)));
        const bt::FoldRollout rollout = fold.run(fold.demonstrationParameters());
        if (rollout.outcome != bt::FoldOutcome::Ok) return;
        q[static_cast<std::size_t>(i)] = rollout.fold.q;
        bt::FoldReward reward(bt::rewardSetting(config.reward, setting, "fold_benchmark"),
                              fold.simConfig().cloth.length * fold.simConfig().cloth.width, fold.idealFoldVertices(),
                              fold.clothTriangles());
        for (int k = 0; k < draws; ++k) {
          std::seed_seq sequence{options.seed, 0x40d5u, static_cast<std::uint32_t>(i), static_cast<std::uint32_t>(k)};
          std::mt19937 rng(sequence);
          ortho[static_cast<std::size_t>(i)].push_back(reward.evaluate(rollout, rng).fold_mismatch);
          char stem[64];
          std::snprintf(stem, sizeof stem, "/rgbd_noise/%02d_%02d", i, k);
          const bool keep = k < 3;
          if (keep) std::filesystem::create_directories(options.out + "/rgbd_noise");
          persp[static_cast<std::size_t>(i)].push_back(
              perspectiveReward(config, setting, fold, rollout, rng, keep ? options.out + stem : "")
                  .first.fold_mismatch);
        }
      },
      [&](int i) {
        const auto& o = ortho[static_cast<std::size_t>(i)];
        const auto& p = persp[static_cast<std::size_t>(i)];
        if (o.empty()) return;
        const bs::learning::MeanInterval mo = bs::learning::meanInterval95(o), mp = bs::learning::meanInterval95(p);
        std::printf(
            "  fold %2d  q %.3f  fold mismatch: orthographic %.3f sd %.3f [%.3f, %.3f]  perspective %.3f sd %.3f "
            "[%.3f, %.3f]\n",
            i, q[static_cast<std::size_t>(i)], mo.mean, mo.std_dev, *std::min_element(o.begin(), o.end()),
            *std::max_element(o.begin(), o.end()), mp.mean, mp.std_dev, *std::min_element(p.begin(), p.end()),
            *std::max_element(p.begin(), p.end()));
        std::fflush(stdout);
        for (std::size_t k = 0; k < o.size(); ++k) {
          csv << i << ',' << q[static_cast<std::size_t>(i)] << ',' << k << ",orthographic," << o[k] << ",\n";
          csv << i << ',' << q[static_cast<std::size_t>(i)] << ',' << k << ",perspective," << p[k] << ",\n";
        }
        csv << std::flush;
        rows.emplace_back()
            .add("experiment", "rgbd_noise")
            .add("index", i)
            .add("fold_quality", q[static_cast<std::size_t>(i)])
            .add("orthographic_sd", mo.std_dev)
            .add("perspective_sd", mp.std_dev)
            .add("perspective_max", *std::max_element(p.begin(), p.end()));
      });
}

/// The scripted fold of a point of the unit box: reach 0–1.2, lift 0.1–0.8, release height 0–0.3 m, duration
/// 2.5–5 s (coordinates clamped into the box).
FoldDraw scriptedFold(const Eigen::VectorXd& x) {
  const Eigen::VectorXd u = x.cwiseMax(0.0).cwiseMin(1.0);
  FoldDraw d;
  d.reach = 1.2 * u[0];
  d.lift = 0.1 + 0.7 * u[1];
  d.drop = 0.3 * u[2];
  d.duration = 2.5 + 2.5 * u[3];
  return d;
}

void ceilingExperiment(const Options& options, const br::FoldLearningConfig& config,
                       std::vector<bs::bench::JsonRow>& rows) {
  const int population[2] = {options.quick ? 4 : 10, options.quick ? 4 : 12};
  const int generations[2] = {options.quick ? 2 : 60, options.quick ? 2 : 120};
  std::ofstream csv(options.out + "/ceiling.csv");
  csv << "stage,generation,index,reach,lift,drop,duration";
  for (int i = 0; i < bt::ClothFoldTask::kDofs; ++i) csv << ",goal_" << i;
  csv << ",outcome,fold_quality\n";
  std::mt19937 rng(options.seed);
  bs::learning::GaussianSampler sampler;
  double best_q = -std::numeric_limits<double>::infinity();
  FoldDraw best_fold;
  Eigen::VectorXd best_goals = Eigen::VectorXd::Zero(bt::ClothFoldTask::kDofs);
  int evaluated = 0;
  std::printf("fold_benchmark ceiling: CMA-ES on q, seed %u, %d + %d rollouts on %d threads\n", options.seed,
              population[0] * generations[0], population[1] * generations[1], options.jobs);
  for (int stage = 0; stage < 2; ++stage) {
    // Stage 0: the scripted fold's 4 parameters in the unit box, from its middle; stage 1: the 12 goal offsets [m]
    // of the best scripted fold's policy, from 0.
    const Eigen::Index dims = stage == 0 ? 4 : bt::ClothFoldTask::kDofs;
    Eigen::VectorXd mean = stage == 0 ? Eigen::VectorXd::Constant(dims, 0.5) : Eigen::VectorXd::Zero(dims);
    const double sigma = stage == 0 ? 0.25 : 0.04;
    bs::learning::CovarianceAdaptation adaptation =
        bs::learning::CovarianceAdaptation::start(sigma * sigma * Eigen::MatrixXd::Identity(dims, dims));
    const FoldDraw base = best_fold;
    std::vector<std::unique_ptr<bt::ClothFoldTask>> tasks(static_cast<std::size_t>(options.jobs));
    for (int g = 0; g < generations[stage]; ++g) {
      Eigen::MatrixXd samples =
          sampler.draw(mean, bs::learning::choleskyFactor(adaptation.covariance()), population[stage], rng);
      if (stage == 0) samples = samples.cwiseMax(0.0).cwiseMin(1.0);  // the box: evaluated and recombined clamped
      std::vector<bt::FoldRollout> results(static_cast<std::size_t>(population[stage]));
      std::vector<FoldDraw> draws(results.size(), base);
      bs::parallel::parallelFor(results.size(), options.jobs, [&](int worker, std::size_t k) {
        const Eigen::VectorXd x = samples.row(static_cast<Eigen::Index>(k)).transpose();
        if (stage == 0) {
          draws[k] = scriptedFold(x);
          bt::ClothFoldTask task(withDemonstration(config.task, draws[k]));
          results[k] = task.run(task.demonstrationParameters());
          return;
        }
        std::unique_ptr<bt::ClothFoldTask>& task = tasks[static_cast<std::size_t>(worker)];
        if (!task) task = std::make_unique<bt::ClothFoldTask>(withDemonstration(config.task, base));
        Eigen::VectorXd theta = task->demonstrationParameters();
        const int n = task->policyBasisSize(), kernels = task->config().kernels;
        const double forcing = task->dmpParameters().alpha_z * task->dmpParameters().beta_z;
        for (int dof = 0; dof < bt::ClothFoldTask::kDofs; ++dof) theta[dof * n + kernels] = forcing * x[dof];
        results[k] = task->run(theta);
      });
      Eigen::VectorXd q(population[stage]);
      for (std::size_t k = 0; k < results.size(); ++k) {
        const bt::FoldRollout& r = results[k];
        q[static_cast<Eigen::Index>(k)] = r.fold.q;
        const Eigen::VectorXd goals = stage == 0
                                          ? Eigen::VectorXd::Zero(bt::ClothFoldTask::kDofs)
                                          : Eigen::VectorXd(samples.row(static_cast<Eigen::Index>(k)).transpose());
        csv << stage << ',' << g << ',' << k << ',' << draws[k].reach << ',' << draws[k].lift << ',' << draws[k].drop
            << ',' << draws[k].duration;
        for (Eigen::Index i = 0; i < goals.size(); ++i) csv << ',' << goals[i];
        csv << ',' << bt::toString(r.outcome) << ',' << r.fold.q << '\n';
        if (r.outcome == bt::FoldOutcome::Ok && r.fold.q > best_q) {
          best_q = r.fold.q;
          best_fold = draws[k];
          best_goals = goals;
        }
      }
      csv << std::flush;
      evaluated += population[stage];
      mean = bs::learning::cmaEsStep(mean, adaptation, samples, q);
      if (g % 10 == 9 || g + 1 == generations[stage]) {
        std::printf("  stage %d generation %3d: best q of the generation %.3f, q_max so far %.3f (%d rollouts)\n",
                    stage, g + 1, q.maxCoeff(), best_q, evaluated);
        std::fflush(stdout);
      }
    }
  }
  std::printf(
      "fold_benchmark ceiling: q_max = %.3f (reach %.3f, lift %.3f, release height %.3f m, duration %.2f s, "
      "goal offsets |%.3f| m)\n",
      best_q, best_fold.reach, best_fold.lift, best_fold.drop, best_fold.duration, best_goals.norm());
  bs::bench::JsonRow& row = rows.emplace_back();
  row.add("experiment", "ceiling")
      .add("q_max", best_q)
      .add("rollouts", evaluated)
      .add("reach", best_fold.reach)
      .add("lift", best_fold.lift)
      .add("drop", best_fold.drop)
      .add("duration", best_fold.duration);
  for (Eigen::Index i = 0; i < best_goals.size(); ++i) row.add("goal_" + std::to_string(i), best_goals[i]);
}

}  // namespace

int main(int argc, char** argv) {
  bimanual_skills::cli::pinNumerics(argv);
  std::string config_path, family = "symmetric", from;
  long count = 0;
  bs::bench::ExperimentProgram program;
  program.name = "fold_benchmark";
  program.description =
      "The cloth fold's ground truth (the fold quality q of the simulated mesh) against the camera rewards, on a\n"
      "set of clearly different scripted folds (folds); and q_max, the best fold a large search on q finds (ceiling).";
  program.experiments = {"folds", "ceiling", "rgbd_noise", "repeatability", "learned", "all"};
  program.with_jobs = true;
  program.extra = [&](bs::cli::CommandLine& line) {
    line.option("--config", "FILE", "fold learning file (default: config/fold_demo.yaml)", &config_path);
    line.option("--count", "N",
                "folds of the folds experiment (default 30; 4 with --quick), repetitions of repeatability (20; 3)",
                &count, 1, 10000);
    line.option("--family", "NAME",
                "folds' strategies: symmetric (mirrored arcs, default) or strategies (one arm, diagonal, late release)",
                &family);
    line.option("--from", "DIR", "learned: the fold_learner directory whose final policies it perturbs", &from);
  };
  const Options options = bs::bench::parseExperimentOptions(argc, argv, program);
  try {
    if (config_path.empty()) config_path = bs::cli::packageFile("config/fold_demo.yaml");
    const br::FoldLearningConfig config = br::withSimulationRenderer(br::FoldLearningConfig::fromYamlFile(config_path));
    std::filesystem::create_directories(options.out);
    std::vector<bs::bench::JsonRow> rows;
    if (options.experiment == "folds" || options.experiment == "all") {
      if (family != "symmetric" && family != "strategies") {
        throw std::invalid_argument("--family: symmetric or strategies, not '" + family + "'");
      }
      foldsExperiment(options, config, count > 0 ? static_cast<int>(count) : (options.quick ? 4 : 30),
                      family == "symmetric" ? FoldFamily::Symmetric : FoldFamily::Strategies, rows);
    }
    if (options.experiment == "ceiling" || options.experiment == "all") ceilingExperiment(options, config, rows);
    if (options.experiment == "rgbd_noise" || options.experiment == "all") {
      rgbdNoiseExperiment(options, config, count > 0 ? static_cast<int>(count) : (options.quick ? 2 : 8),
                          options.quick ? 3 : 20, rows);
    }
    if (options.experiment == "learned" || (options.experiment == "all" && !from.empty())) {
      learnedExperiment(options, config, from, count > 0 ? static_cast<int>(count) : (options.quick ? 1 : 4), rows);
    }
    if (options.experiment == "repeatability" || options.experiment == "all") {
      repeatabilityExperiment(options, config, count > 0 ? static_cast<int>(count) : (options.quick ? 3 : 20), rows);
    }
    bs::bench::writeSummaryJson(options, "fold_benchmark", rows);
    bs::bench::runPlotScript("fold_benchmark", "plot_fold_benchmark.py", options.out);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "fold_benchmark: %s\n", e.what());
    return 1;
  }
  return 0;
}

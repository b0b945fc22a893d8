// fit_friction: identify a joint friction model (thesis 2.13, 2.14 or 4.16, with coupled pairs) from a log.
//
//   fit_friction --model viscous|initial|basic|advanced --in log.csv --out friction.yaml
//                [--urdf FILE --base LINK --tip LINK] [--pairs 2-3,5-6|none] [--epsilon 0.05]
//                [--holdout 0.25] [--restarts 8] [--seed 1] [--sign logged|filtered]
//
// The log's columns are t, q1..qn, qd1..qdn, qdd1..qddn, tau1..taun (tau: applied joint torques). Friction is
// observed as tau - M qdd - C qd - G (2.12) with the arm model; the fit uses the first 1 - holdout of the samples and
// the errors (MAE, MSE, maximum, as in Table 4.1) are printed for the held-out rest.
#include "bimanual_skills/dynamics/friction_identification.hpp"
#include "bimanual_skills/dynamics/friction_yaml.hpp"
#include "cli/command_line.hpp"
#include "cli/package_share.hpp"
#include "cli/pinned_numerics.hpp"

#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <sstream>
#include <string>

namespace bd = bimanual_skills::dynamics;
namespace bk = bimanual_skills::kinematics;

namespace {

/// Parses "i-j[,k-l]" (1-based) or "none"; false if malformed.
bool parsePairs(const std::string& text, std::vector<std::pair<int, int>>& pairs) {
  pairs.clear();
  if (text == "none") return true;
  std::stringstream stream(text);
  std::string item;
  while (std::getline(stream, item, ',')) {
    const auto dash = item.find('-');
    if (dash == std::string::npos) return false;
    char* end_a = nullptr;
    char* end_b = nullptr;
    const std::string a = item.substr(0, dash), b = item.substr(dash + 1);
    const long i = std::strtol(a.c_str(), &end_a, 10), j = std::strtol(b.c_str(), &end_b, 10);
    if (a.empty() || b.empty() || *end_a != '\0' || *end_b != '\0' || i < 1 || j < 1) return false;
    pairs.emplace_back(static_cast<int>(i) - 1, static_cast<int>(j) - 1);
  }
  return !pairs.empty();
}

}  // namespace

int main(int argc, char** argv) {
  bimanual_skills::cli::pinNumerics(argv);
  std::string model_name, in, out, sign = "logged", pairs_text;
  std::string urdf, base = "wam_base", tip = "wam_tool";
  bd::FrictionFitOptions options;
  long restarts = options.restarts, seed = options.seed;
  bimanual_skills::cli::CommandLine line(
      "fit_friction", "--model viscous|initial|basic|advanced --in log.csv --out friction.yaml [options]",
      "Identifies a joint friction model (thesis 2.13, 2.14 or 4.16, with cable-coupled pairs) from a log whose\n"
      "columns are t, q1..qn, qd1..qdn, qdd1..qddn, tau1..taun (tau: applied torques). Friction is observed as\n"
      "tau - M qdd - C qd - G (2.12) with the arm model; the fit uses the first 1 - holdout of the samples and prints\n"
      "the errors of Table 4.1 (MAE, MSE, maximum) on the held-out rest; the model is written as YAML.");
  line.choice("--model", {"viscous", "initial", "basic", "advanced"}, "the friction model (Table 4.1)", &model_name);
  line.option("--in", "FILE", "the log (CSV)", &in);
  line.option("--out", "FILE", "the fitted model (YAML)", &out);
  line.option("--urdf", "FILE", "robot description (default: urdf/wam.urdf)", &urdf);
  line.option("--base", "LINK", "base link of the chain (default: wam_base)", &base);
  line.option("--tip", "LINK", "tip link of the chain (default: wam_tool)", &tip);
  line.option("--pairs", "I-J,K-L", "coupled joint pairs, 1-based, or none (default: 2-3,5-6 for 7 joints)",
              &pairs_text);
  line.option("--epsilon", "E", "dead band of the pair switching [rad/s] (default 0.05)", &options.epsilon);
  line.option("--holdout", "F", "fraction of samples, at the end, kept for validation (default 0.25)",
              &options.holdout);
  line.option("--restarts", "N", "seeded starts of the nonlinear search (default 8)", &restarts, 1, 1000);
  line.option("--seed", "S", "seed of the search's starts (default 1)", &seed, 0, 0xffffffffL);
  line.choice("--sign", {"logged", "filtered"},
              "sign of qdd from the logged qdd (logged) or filtered velocities (filtered; default logged)", &sign);
  line.parse(argc, argv);
  options.restarts = static_cast<int>(restarts);
  options.seed = static_cast<std::uint32_t>(seed);
  if (!bd::parseFrictionModelType(model_name, options.type)) line.fail("--model is required");
  if (in.empty() || out.empty()) line.fail("--in and --out are required");
  try {
    if (urdf.empty()) urdf = bimanual_skills::cli::packageFile("urdf/wam.urdf");
    const bk::ChainModel model = bk::ChainModel::fromUrdfFile(urdf, base, tip);
    const bd::FrictionLog log = bd::readFrictionLog(in);
    if (!parsePairs(pairs_text.empty() ? (log.joints() == 7 ? "2-3,5-6" : "none") : pairs_text, options.pairs)) {
      line.fail("--pairs takes i-j[,k-l] (1-based) or none, got '" + pairs_text + "'");
    }
    std::printf(
        "fit_friction: %s model, %d samples of %d joints from %s (%.1f s), held out: last %.0f %%, "
        "%d restarts, seed %u, sign of qdd: %s\n",
        model_name.c_str(), log.samples(), log.joints(), in.c_str(), log.t[log.samples() - 1] - log.t[0],
        100.0 * options.holdout, options.restarts, options.seed, sign.c_str());
    const Eigen::MatrixXd friction = bd::observedFriction(model, log);
    const Eigen::MatrixXd signs = bd::accelerationSigns(
        log, sign == "logged" ? bd::SignSource::LoggedAcceleration : bd::SignSource::FilteredVelocity);
    const bd::FrictionFit fit = bd::fitFriction(log, friction, signs, options);
    std::printf("%-6s %10s %10s %10s   %10s %10s  (held-out samples: %d)\n", "joint", "MAE", "MSE", "max error",
                "train MAE", "train MSE", fit.test.empty() ? 0 : fit.test[0].samples);
    for (int j = 0; j < log.joints(); ++j) {
      const auto& test = fit.test[static_cast<std::size_t>(j)];
      const auto& train = fit.train[static_cast<std::size_t>(j)];
      std::printf("%-6d %10.4f %10.4f %10.4f   %10.4f %10.4f\n", j + 1, test.mae, test.mse, test.max_error, train.mae,
                  train.mse);
    }
    std::ostringstream comment;
    comment << "Friction model fitted by fit_friction --model " << model_name << " --in " << in << " (seed "
            << options.seed << ", " << log.samples() << " samples, holdout " << options.holdout << ")";
    bd::saveFrictionModel(fit.model, out, comment.str());
    std::printf("fit_friction: wrote %s\n", out.c_str());
  } catch (const std::exception& e) {
    std::fprintf(stderr, "fit_friction: %s\n", e.what());
    return 1;
  }
  return 0;
}

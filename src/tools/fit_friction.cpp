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

#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <sstream>
#include <string>

namespace bd = bimanual_skills::dynamics;
namespace bk = bimanual_skills::kinematics;

namespace {

[[noreturn]] void usage(const std::string& error) {
  std::cerr << "fit_friction: " << error << "\n"
            << "usage: fit_friction --model viscous|initial|basic|advanced --in log.csv --out friction.yaml\n"
               "                    [--urdf FILE --base LINK --tip LINK] [--pairs 2-3,5-6|none] [--epsilon E]\n"
               "                    [--holdout F] [--restarts N] [--seed S] [--sign logged|filtered]\n";
  std::exit(2);
}

double number(const std::string& flag, const std::string& text) {
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  if (text.empty() || *end != '\0') usage(flag + " needs a number, got '" + text + "'");
  return v;
}

std::vector<std::pair<int, int>> parsePairs(const std::string& text) {
  std::vector<std::pair<int, int>> pairs;
  if (text == "none") return pairs;
  std::stringstream stream(text);
  std::string item;
  while (std::getline(stream, item, ',')) {
    const auto dash = item.find('-');
    if (dash == std::string::npos) usage("--pairs takes i-j[,k-l] (1-based) or none, got '" + text + "'");
    pairs.emplace_back(static_cast<int>(number("--pairs", item.substr(0, dash))) - 1,
                       static_cast<int>(number("--pairs", item.substr(dash + 1))) - 1);
  }
  return pairs;
}

}  // namespace

int main(int argc, char** argv) {
  std::string model_name, in, out, sign = "logged", pairs_text;
  std::string urdf = BIMANUAL_SKILLS_SOURCE_DIR "/urdf/wam.urdf", base = "wam_base", tip = "wam_tool";
  bd::FrictionFitOptions options;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    const auto value = [&]() -> std::string {
      if (i + 1 >= argc) usage(arg + " needs a value");
      return argv[++i];
    };
    if (arg == "--model")
      model_name = value();
    else if (arg == "--in")
      in = value();
    else if (arg == "--out")
      out = value();
    else if (arg == "--urdf")
      urdf = value();
    else if (arg == "--base")
      base = value();
    else if (arg == "--tip")
      tip = value();
    else if (arg == "--pairs")
      pairs_text = value();
    else if (arg == "--epsilon")
      options.epsilon = number(arg, value());
    else if (arg == "--holdout")
      options.holdout = number(arg, value());
    else if (arg == "--restarts")
      options.restarts = static_cast<int>(number(arg, value()));
    else if (arg == "--seed")
      options.seed = static_cast<std::uint32_t>(number(arg, value()));
    else if (arg == "--sign")
      sign = value();
    else
      usage("unknown argument '" + arg + "'");
  }
  if (!bd::parseFrictionModelType(model_name, options.type))
    usage("--model must be viscous, initial, basic or advanced");
  if (in.empty() || out.empty()) usage("--in and --out are required");
  if (sign != "logged" && sign != "filtered") usage("--sign must be logged or filtered");
  try {
    const bk::ChainModel model = bk::ChainModel::fromUrdfFile(urdf, base, tip);
    const bd::FrictionLog log = bd::readFrictionLog(in);
    options.pairs = parsePairs(pairs_text.empty() ? (log.joints() == 7 ? "2-3,5-6" : "none") : pairs_text);
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

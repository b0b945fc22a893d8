#include "bimanual_skills/workspace/placement_search.hpp"

#include "bimanual_skills/realtime/clock.hpp"

#include <nlopt.hpp>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <random>
#include <stdexcept>

namespace bimanual_skills::workspace {

namespace {

/// Calls the objective and keeps the search's record (best parameters, best-so-far curve).
class Recorder {
 public:
  Recorder(std::string method, const PlacementObjective& objective) : objective_(objective) {
    result_.method = std::move(method);
  }

  double operator()(const Eigen::VectorXd& x) {
    const double value = objective_(x);
    if (!std::isfinite(value)) throw std::runtime_error("placement search: the objective is not finite");
    if (result_.evaluations == 0 || value > result_.quality) {
      result_.quality = value;
      result_.best = x;
    }
    ++result_.evaluations;
    result_.best_after.push_back(result_.quality);
    return value;
  }

  SearchResult finish(realtime::Clock::time_point start) {
    result_.seconds = realtime::secondsSince(start);
    return result_;
  }

 private:
  const PlacementObjective& objective_;
  SearchResult result_;
};

}  // namespace

void SearchBounds::validate() const {
  if (lower.size() == 0 || lower.size() != upper.size()) {
    throw std::invalid_argument("placement search: lower and upper bounds of one size > 0");
  }
  if (!lower.allFinite() || !upper.allFinite() || !(lower.array() < upper.array()).all()) {
    throw std::invalid_argument("placement search: finite bounds with lower < upper");
  }
}

int SearchResult::evaluationsToReach(double target) const {
  for (std::size_t k = 0; k < best_after.size(); ++k) {
    if (best_after[k] >= target) return static_cast<int>(k) + 1;
  }
  return -1;
}

void GeneticSettings::validate() const {
  if (generations < 1) throw std::invalid_argument("genetic search: generations >= 1");
  if (population < 4 || population % 2 != 0) throw std::invalid_argument("genetic search: an even population >= 4");
  if (!(mutation >= 0.0 && mutation <= 1.0)) throw std::invalid_argument("genetic search: mutation in [0, 1]");
  if (!(mutation_decay > 0.0 && mutation_decay <= 1.0)) {
    throw std::invalid_argument("genetic search: mutation_decay in (0, 1]");
  }
}

SearchResult geneticSearch(const SearchBounds& bounds, const PlacementObjective& objective,
                           const GeneticSettings& settings) {
  bounds.validate();
  settings.validate();
  const auto start = realtime::Clock::now();
  Recorder record("GA", objective);
  std::mt19937 rng(settings.seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  const Eigen::Index n = bounds.lower.size();
  const auto uniform = [&](Eigen::Index i) {
    return bounds.lower[i] + unit(rng) * (bounds.upper[i] - bounds.lower[i]);
  };
  struct Individual {
    Eigen::VectorXd x;
    double quality = 0.0;
  };
  std::vector<Individual> generation(static_cast<std::size_t>(settings.population));
  for (Individual& g : generation) {
    g.x.resize(n);
    for (Eigen::Index i = 0; i < n; ++i) g.x[i] = uniform(i);
    g.quality = record(g.x);
  }
  double mutation = settings.mutation;
  for (int round = 1; round < settings.generations; ++round) {
    std::stable_sort(generation.begin(), generation.end(),
                     [](const Individual& a, const Individual& b) { return a.quality > b.quality; });
    std::vector<Individual> parents(generation.begin(), generation.begin() + settings.population / 2);
    std::vector<Individual> children;
    while (static_cast<int>(children.size()) < settings.population) {
      std::shuffle(parents.begin(), parents.end(), rng);
      for (std::size_t p = 0; p + 1 < parents.size() && static_cast<int>(children.size()) < settings.population;
           p += 2) {
        for (int twin = 0; twin < 2; ++twin) {
          Individual child;
          child.x.resize(n);
          for (Eigen::Index i = 0; i < n; ++i) {
            const double w = unit(rng);
            child.x[i] = w * parents[p].x[i] + (1.0 - w) * parents[p + 1].x[i];
            if (unit(rng) < mutation) child.x[i] = uniform(i);
          }
          children.push_back(std::move(child));
        }
      }
    }
    children.resize(static_cast<std::size_t>(settings.population));
    for (Individual& c : children) c.quality = record(c.x);
    generation = std::move(children);
    mutation *= settings.mutation_decay;
  }
  return record.finish(start);
}

const std::vector<std::string>& nloptPlacementAlgorithms() {
  static const std::vector<std::string> names = {"ESCH", "CRS2", "ISRES", "DIRECT"};
  return names;
}

SearchResult nloptSearch(const std::string& algorithm, const SearchBounds& bounds, const PlacementObjective& objective,
                         int evaluations, std::uint32_t seed) {
  bounds.validate();
  if (evaluations < 1) throw std::invalid_argument("placement search: evaluations >= 1");
  nlopt::algorithm which;
  if (algorithm == "ESCH") {
    which = nlopt::GN_ESCH;
  } else if (algorithm == "CRS2") {
    which = nlopt::GN_CRS2_LM;
  } else if (algorithm == "ISRES") {
    which = nlopt::GN_ISRES;
  } else if (algorithm == "DIRECT") {
    which = nlopt::GN_DIRECT_L;
  } else {
    throw std::invalid_argument("placement search: unknown NLopt algorithm '" + algorithm +
                                "' (ESCH, CRS2, ISRES, DIRECT)");
  }
  const auto start = realtime::Clock::now();
  Recorder record(algorithm, objective);
  const auto n = static_cast<unsigned>(bounds.lower.size());
  nlopt::opt optimiser(which, n);
  const auto toStd = [](const Eigen::VectorXd& v) { return std::vector<double>(v.data(), v.data() + v.size()); };
  optimiser.set_lower_bounds(toStd(bounds.lower));
  optimiser.set_upper_bounds(toStd(bounds.upper));
  optimiser.set_maxeval(evaluations);
  nlopt::srand(seed);
  // Some algorithms (CRS2) may call once more than maxeval: the budget is enforced here.
  struct Budgeted {
    Recorder* record;
    int left;
  } budgeted{&record, evaluations};
  optimiser.set_max_objective(
      [](unsigned m, const double* x, double*, void* data) {
        auto* b = static_cast<Budgeted*>(data);
        if (b->left-- <= 0) throw nlopt::forced_stop();
        return (*b->record)(Eigen::Map<const Eigen::VectorXd>(x, m));
      },
      &budgeted);
  std::vector<double> x = toStd(0.5 * (bounds.lower + bounds.upper));
  double value = 0.0;
  try {
    optimiser.optimize(x, value);
  } catch (const nlopt::roundoff_limited&) {
    // The best point so far stands (NLopt stops without having failed).
  } catch (const nlopt::forced_stop&) {
    // The budget is spent; the best point so far stands.
  }
  return record.finish(start);
}

}  // namespace bimanual_skills::workspace

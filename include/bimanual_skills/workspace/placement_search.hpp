/// \file
/// The search for the best relative placement of two arms (thesis Sec. 3.2.4): a placement is a parameter vector
/// within bounds (up to 6: offsets and angles of the second base), scored by an objective such as the placement
/// quality (3.41). Two searches: the thesis' genetic algorithm (generations of 20, the best half paired into the next
/// generation, a mutation probability decreasing each generation) and NLopt's global algorithms (ESCH, CRS2, ISRES,
/// DIRECT-L).
/// Both record the best quality after every evaluation, so that they can be compared at equal numbers of
/// evaluations. Target bimanual_skills_workspace. Offline: allocates; errors are exceptions.
#pragma once

#include <Eigen/Core>

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

namespace bimanual_skills::workspace {

/// What is maximised: the quality of the placement with these parameters.
using PlacementObjective = std::function<double(const Eigen::VectorXd& parameters)>;

struct SearchBounds {
  Eigen::VectorXd lower, upper;  ///< Finite, lower < upper, one entry per parameter.
  /// \throws std::invalid_argument for empty, mismatched, non-finite or inverted bounds.
  void validate() const;
};

struct SearchResult {
  std::string method;
  Eigen::VectorXd best;            ///< The best parameters found.
  double quality = 0.0;            ///< Their objective.
  int evaluations = 0;             ///< Objective calls.
  std::vector<double> best_after;  ///< best_after[k]: the best objective among the first k + 1 calls.
  double seconds = 0.0;

  /// The number of evaluations after which the best objective first reached `target` (−1: never).
  int evaluationsToReach(double target) const;
};

/// The thesis' genetic algorithm (Sec. 3.2.4): a first generation uniform within the bounds; from each generation
/// the best half is kept and paired at random, each pair giving two children by a blend of the parents (each
/// parameter a uniform random mix of the two), and each child's parameters are redrawn uniformly with the
/// generation's mutation probability, which decreases geometrically. `generations` × `population` evaluations.
struct GeneticSettings {
  int generations = 10;
  int population = 20;          ///< Even, ≥ 4.
  double mutation = 0.3;        ///< Probability per parameter in the first generation of children, in [0, 1].
  double mutation_decay = 0.9;  ///< Factor per generation, in (0, 1].
  std::uint32_t seed = 1;

  void validate() const;
};

SearchResult geneticSearch(const SearchBounds& bounds, const PlacementObjective& objective,
                           const GeneticSettings& settings);

/// NLopt's global derivative-free algorithms by name: "ESCH" (evolutionary), "CRS2" (controlled random search with
/// local mutation), "ISRES" (evolution strategy), "DIRECT" (DIRECT-L, deterministic: the seed does not matter); at
/// most `evaluations` calls, from the middle of the bounds, NLopt's generator seeded with `seed`.
/// \throws std::invalid_argument for an unknown name or evaluations < 1.
SearchResult nloptSearch(const std::string& algorithm, const SearchBounds& bounds, const PlacementObjective& objective,
                         int evaluations, std::uint32_t seed);

/// The names nloptSearch() accepts.
const std::vector<std::string>& nloptPlacementAlgorithms();

}  // namespace bimanual_skills::workspace

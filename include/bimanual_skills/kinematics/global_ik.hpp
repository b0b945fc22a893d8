/// \file
/// Global inverse kinematics: a CLIK method restarted deterministically from the caller's seed, then from seeded
/// random configurations within the joint limits, keeping only joint-limit-respecting solutions.
#pragma once

#include "bimanual_skills/kinematics/clik.hpp"

#include <cstdint>
#include <random>
#include <vector>

namespace bimanual_skills::kinematics {

/// What the global solver returns.
enum class SolutionMode {
  FirstFound,     ///< The first valid solution (the caller's seed is tried first, so it is usually the closest).
  ClosestToSeed,  ///< Search the whole budget; the valid solution closest to the seed (Euclidean in joint space).
  AllDistinct,    ///< Search the whole budget; every distinct valid solution (see solutions()).
};

struct GlobalIkParameters {
  /// Local method (its own timeout is replaced by what is left of the budget). Default ED (error damping, 3.7)
  /// without a limit scheme, attempts capped at 40 iterations, restarted from random configurations until one
  /// converges within the limits: chosen by measurement under TRAC-IK's protocol on the WAM and two other arms
  /// (docs/RESULTS.md), where it was the fastest configuration at 100 % within limits. The thesis' methods stay
  /// selectable (e.g. CTP+SD+SVF, which keeps every attempt inside the limits but steps at most γ_max per iteration).
  ClikParameters local = defaultLocal();
  /// Polish stage run from the end point of a local attempt that did not give a valid solution, for local methods
  /// with a limit scheme (JW, GP, JC, TA, TP, CTP): by default a damped Newton method (ED) clamped into the limits.
  /// Those methods stall where a solution needs a joint inside its activation buffer β (the thesis' "algorithmic
  /// singularity"); this stage finishes those. A method without a limit scheme is not polished: a fresh start beats
  /// polishing an attempt that converged outside the limits (measured: p99 twice lower with ED). Set
  /// refine_enabled = false for the pure local method.
  ClikParameters refine = defaultRefine();
  bool refine_enabled = true;
  double timeout = 0.005;     ///< Time budget per solve [s] (> 0).
  int max_attempts = 100000;  ///< Cap on local solves per call (≥ 1).
  std::uint32_t seed = 1;     ///< Seed of the restart generator, re-seeded at every call: same inputs, same answer.
  SolutionMode mode = SolutionMode::FirstFound;
  double distinct_tolerance = 1e-3;  ///< Solutions closer than this (max |Δq_i|, rad) are the same.
  int max_solutions = 64;            ///< AllDistinct: capacity (≥ 1).

  /// Throws std::invalid_argument naming the first parameter out of range (and validates `local`).
  void validate() const;

  /// ED without a limit scheme, max_iterations = 40 (a stalled attempt costs less than a fresh start).
  static ClikParameters defaultLocal();
  /// ED, no limit scheme, q clamped into the limits after each step, 100 iterations.
  static ClikParameters defaultRefine();
};

/// Outcome of a global solve.
struct GlobalIkResult {
  /// Converged: q holds a solution within limits. Timeout: budget spent without one. MaxIterations: attempt cap
  /// reached without one. InvalidInput: bad target or seed. In the failure cases q holds the attempt with the
  /// smallest residual.
  IkStatus status = IkStatus::InvalidInput;
  int attempts = 0;    ///< Local solves run.
  int iterations = 0;  ///< CLIK iterations over all attempts.
  double residual = 0.0;
};

/// Global IK for one chain. Construction allocates everything; solve() does not allocate.
class GlobalIkSolver {
 public:
  /// \throws std::invalid_argument for invalid parameters or a chain of more than kClikMaxJoints joints.
  GlobalIkSolver(const ChainModel& model, const GlobalIkParameters& parameters);

  /// Solves for the tip pose `target` (base frame) from `seed` (size n, finite; may lie outside the limits).
  /// The solution (or best attempt) is written to `q` (resized beforehand by the caller to n). `timeout` > 0
  /// replaces the configured budget for this call.
  /// Real-time safe in the sense of no allocation and no exceptions; it runs for up to the time budget.
  GlobalIkResult solve(const Eigen::Isometry3d& target, const Eigen::Ref<const Eigen::VectorXd>& seed,
                       Eigen::Ref<Eigen::VectorXd> q, double timeout = 0.0) noexcept;

  /// AllDistinct mode: the distinct solutions of the last solve() (ordered by discovery). Other modes: the returned
  /// one.
  int solutionCount() const noexcept { return solution_count_; }
  const Eigen::VectorXd& solution(int i) const noexcept { return solutions_[static_cast<std::size_t>(i)]; }

  const GlobalIkParameters& parameters() const noexcept { return parameters_; }
  const ChainModel& model() const noexcept { return model_; }

 private:
  /// Brings revolute joints into their limits by multiples of 2π where possible; true if then within limits.
  bool wrapIntoLimits(Eigen::Ref<Eigen::VectorXd> q) const noexcept;
  bool isKnownSolution(const Eigen::VectorXd& q) const noexcept;

  ChainModel model_;
  GlobalIkParameters parameters_;
  ClikParameters local_;
  ClikParameters refine_;
  ClikData data_;
  ClikData refine_data_;
  std::mt19937 rng_;
  Eigen::VectorXd candidate_, best_, start_;
  std::vector<Eigen::VectorXd> solutions_;
  int solution_count_ = 0;
};

}  // namespace bimanual_skills::kinematics

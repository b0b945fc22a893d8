#include "bimanual_skills/rollout/dispatcher.hpp"
#include "bimanual_skills/realtime/clock.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <deque>
#include <map>
#include <set>
#include <stdexcept>
#include <thread>
#include <utility>

namespace bimanual_skills::rollout {

namespace {

using bimanual_skills::realtime::Clock;
using bimanual_skills::realtime::secondsSince;

/// Below this many seconds of rollouts per worker, what is left of a batch goes out in one share per worker: the
/// halving shares' round trips would cost more than the balance they buy.
constexpr double kEvenShareSeconds = 0.05;

/// Why `results` cannot be the answer to a share of `size` rollouts of a task with `terms` terms; empty if it can.
std::string garbage(const std::vector<RolloutResult>& results, std::size_t size, std::size_t terms) {
  if (results.size() != size) {
    return std::to_string(results.size()) + " results for " + std::to_string(size) + " rollouts";
  }
  for (std::size_t k = 0; k < results.size(); ++k) {
    if (!std::isfinite(results[k].reward)) return "a non-finite reward for rollout " + std::to_string(k);
    // Its wall time sets the share size: a clock that cannot be right is a worker that cannot be trusted.
    if (!(results[k].wall_seconds >= 0.0 && results[k].wall_seconds < 1e7)) {
      return "a wall time of " + std::to_string(results[k].wall_seconds) + " s for rollout " + std::to_string(k);
    }
    if (static_cast<std::size_t>(results[k].terms.size()) != terms) {
      return std::to_string(results[k].terms.size()) + " reward terms instead of " + std::to_string(terms);
    }
  }
  return {};
}

}  // namespace

void DispatchConfig::validate() const {
  if (!(timeout > 0.0) || !std::isfinite(timeout)) throw std::invalid_argument("dispatch: timeout must be > 0");
  if (!(wait_for_workers > 0.0) || !std::isfinite(wait_for_workers)) {
    throw std::invalid_argument("dispatch: wait_for_workers must be > 0");
  }
  if (max_attempts < 1) throw std::invalid_argument("dispatch: max_attempts must be >= 1");
  if (!(poll_period > 0.0) || !std::isfinite(poll_period)) {
    throw std::invalid_argument("dispatch: poll_period must be > 0");
  }
  if (!(join_period > 0.0) || !std::isfinite(join_period)) {
    throw std::invalid_argument("dispatch: join_period must be > 0");
  }
}

struct Dispatcher::Worker {
  std::string name;
  std::unique_ptr<WorkerLink> link;
  std::vector<std::size_t> share;  ///< Request indices of the share it holds (empty: idle).
  std::size_t progress = 0;
  Clock::time_point since;  ///< When the share was sent or last made progress.
};

Dispatcher::Dispatcher(std::unique_ptr<WorkerDirectory> directory, std::size_t terms, DispatchConfig config)
    : directory_(std::move(directory)), terms_(terms), config_(std::move(config)) {
  if (!directory_) throw std::invalid_argument("dispatch: no worker directory");
  config_.validate();
}

Dispatcher::~Dispatcher() = default;

std::size_t Dispatcher::discover() {
  std::vector<std::string> unreachable;
  return lookUp(unreachable);
}

std::size_t Dispatcher::lookUp(std::vector<std::string>& left_out) {
  const std::vector<std::string> alive = directory_->alive();
  workers_.erase(std::remove_if(workers_.begin(), workers_.end(),
                                [&](const std::unique_ptr<Worker>& w) {
                                  return std::find(alive.begin(), alive.end(), w->name) == alive.end();
                                }),
                 workers_.end());
  join(alive, left_out);
  return workers_.size();
}

void Dispatcher::join(const std::vector<std::string>& alive, std::vector<std::string>& left_out) {
  for (const std::string& name : alive) {
    const bool known = std::any_of(workers_.begin(), workers_.end(),
                                   [&](const std::unique_ptr<Worker>& w) { return w->name == name; });
    if (known || std::find(left_out.begin(), left_out.end(), name) != left_out.end() || refused_.count(name) > 0) {
      continue;
    }
    std::unique_ptr<WorkerLink> link = directory_->connect(name);
    if (!link) {
      left_out.push_back(name);  // tried once per look-up round: connecting can take seconds
      continue;
    }
    auto w = std::make_unique<Worker>();
    w->name = name;
    w->link = std::move(link);
    workers_.push_back(std::move(w));
    if (config_.log) config_.log("worker " + name + " joined", false);
  }
}

std::vector<RolloutResult> Dispatcher::evaluate(const std::vector<RolloutRequest>& batch, const Done& done,
                                                const std::function<bool()>& stop) {
  const auto start = Clock::now();
  const auto log = [&](const std::string& line, bool fault) {
    if (config_.log) config_.log(line, fault);
  };
  last_ = DispatchStats{};
  last_.rollouts = batch.size();
  std::set<std::string> took_part;
  std::vector<std::string> left_out;  // Workers lost in this batch.

  std::deque<std::size_t> pending;
  for (std::size_t i = 0; i < batch.size(); ++i) pending.push_back(i);
  std::vector<RolloutResult> results(batch.size());
  std::vector<int> failures(batch.size(), 0);
  std::size_t reported = 0;
  bool stopping = false;

  const auto cancelAll = [&] {
    for (const std::unique_ptr<Worker>& w : workers_) {
      if (!w->share.empty()) w->link->cancel();
      w->share.clear();
    }
  };
  // Gives the share of worker `at` back to the queue (in request order, ahead of the rest) and drops the worker.
  const auto drop = [&](std::size_t at, const std::string& why) {
    Worker& w = *workers_[at];
    for (const std::size_t i : w.share) {
      if (++failures[i] >= config_.max_attempts) {
        cancelAll();
        throw std::runtime_error("dispatch: rollout " + std::to_string(i) + " failed on " +
                                 std::to_string(failures[i]) + " workers, the last " + w.name + ": " + why);
      }
    }
    last_.redispatched += w.share.size();
    pending.insert(pending.begin(), w.share.begin(), w.share.end());
    std::sort(pending.begin(), pending.end());
    last_.lost.push_back(w.name + ": " + why);
    left_out.push_back(w.name);
    log("worker " + w.name + " lost (" + why + ")" +
            (w.share.empty() ? std::string()
                             : ": its " + std::to_string(w.share.size()) + " rollout(s) go to the others"),
        true);
    w.share.clear();
    workers_.erase(workers_.begin() + static_cast<std::ptrdiff_t>(at));
  };

  try {
    lookUp(left_out);
    auto waiting = Clock::now(), joined = Clock::now();
    while (reported < batch.size()) {
      if (!stopping && stop && stop()) stopping = true;
      const bool busy = std::any_of(workers_.begin(), workers_.end(),
                                    [](const std::unique_ptr<Worker>& w) { return !w->share.empty(); });
      if (stopping && !busy) throw std::runtime_error("stopped");
      if (workers_.empty()) {
        if (secondsSince(waiting) > config_.wait_for_workers) {
          std::string refusals;
          for (const auto& [name, why] : refused_) refusals += "; " + name + " " + why;
          throw std::runtime_error("dispatch: no rollout worker alive for " +
                                   std::to_string(static_cast<int>(config_.wait_for_workers)) + " s (" +
                                   std::to_string(batch.size() - reported) + " rollouts left) " + directory_->where() +
                                   (refusals.empty() ? std::string() : " (left out" + refusals + ")"));
        }
        std::this_thread::sleep_for(std::chrono::duration<double>(std::min(0.2, config_.wait_for_workers)));
        discover();
        continue;
      }
      waiting = Clock::now();
      if (secondsSince(joined) > config_.join_period) {
        join(directory_->alive(), left_out);
        joined = Clock::now();
      }

      // Hand out shares to the idle workers.
      for (std::size_t at = 0; at < workers_.size() && !stopping && !pending.empty(); ++at) {
        Worker& w = *workers_[at];
        if (!w.share.empty()) continue;
        std::size_t size = config_.share;
        if (size == 0) {
          // Cheap rollouts: an even split of what is left among the idle workers, one share each.
          const auto idle = static_cast<std::size_t>(
              std::count_if(workers_.begin() + static_cast<std::ptrdiff_t>(at), workers_.end(),
                            [](const std::unique_ptr<Worker>& v) { return v->share.empty(); }));
          const std::size_t even = (pending.size() + idle - 1) / idle;
          const bool cheap = timed_ > 0 && rollout_seconds_ * static_cast<double>(even) < kEvenShareSeconds;
          size = cheap ? even : (pending.size() + 2 * workers_.size() - 1) / (2 * workers_.size());
        }
        size = std::max<std::size_t>(1, std::min(size, pending.size()));
        std::vector<RolloutRequest> requests;
        for (std::size_t k = 0; k < size; ++k) {
          w.share.push_back(pending.front());
          requests.push_back(batch[pending.front()]);
          pending.pop_front();
        }
        w.progress = 0;
        w.since = Clock::now();
        ++last_.shares;
        took_part.insert(w.name);
        if (!w.link->start(requests)) {
          drop(at--, "the share could not be sent");
          continue;
        }
      }

      // Collect.
      for (std::size_t at = 0; at < workers_.size(); ++at) {
        Worker& w = *workers_[at];
        if (w.share.empty()) continue;
        WorkerLink::Status status = w.link->poll();
        switch (status.state) {
          case WorkerLink::State::Idle:
          case WorkerLink::State::Running:
            if (status.done > w.progress) {
              w.progress = status.done;
              w.since = Clock::now();
            } else if (secondsSince(w.since) > config_.timeout) {
              w.link->cancel();
              drop(at--, "no rollout finished for " + std::to_string(static_cast<int>(config_.timeout)) + " s");
            }
            break;
          case WorkerLink::State::Finished: {
            const std::string wrong = garbage(status.results, w.share.size(), terms_);
            if (!wrong.empty()) {
              drop(at--, "it answered " + wrong);
              break;
            }
            const std::vector<std::size_t> share = std::move(w.share);
            w.share.clear();
            for (std::size_t k = 0; k < share.size(); ++k) {
              ++timed_;
              rollout_seconds_ += (status.results[k].wall_seconds - rollout_seconds_) / static_cast<double>(timed_);
              results[share[k]] = std::move(status.results[k]);
              ++reported;
              if (done) done(share[k], results[share[k]], nullptr);
            }
            break;
          }
          case WorkerLink::State::Refused: {
            // That worker's fault (another configuration file on its host, a task it lacks): left out for good, its
            // rollouts go to the others; a request every worker refuses fails on max_attempts of them.
            const std::string why = "it refused the rollouts: " + (status.reason.empty() ? "no reason" : status.reason);
            refused_[w.name] = why;
            drop(at--, why + "; left out of this learning");
            break;
          }
          case WorkerLink::State::Lost:
            drop(at--, status.reason.empty() ? "lost" : status.reason);
            break;
        }
      }
      if (reported < batch.size()) std::this_thread::sleep_for(std::chrono::duration<double>(config_.poll_period));
    }
  } catch (...) {
    cancelAll();
    last_.workers = took_part.size();
    last_.alive = workers_.size();
    last_.seconds = secondsSince(start);
    throw;
  }
  last_.workers = took_part.size();
  last_.alive = workers_.size();
  last_.seconds = secondsSince(start);
  if (config_.batch) config_.batch(last_);
  return results;
}

}  // namespace bimanual_skills::rollout

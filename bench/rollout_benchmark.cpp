// rollout_benchmark: what rollouts cost on threads of one process and on rollout worker nodes (topics with
// TCP_NODELAY), on this machine. It starts its own ROS master when none answers at ROS_MASTER_URI, and its own
// rollout_worker processes (the binary next to it) in a namespace of its own, so it needs nothing running.
//   throughput: a batch of fold rollouts on 1 and 2 threads and on 1, 2, 4 workers (default; --workers), and on the
//               workers already running under --worker-namespace NS if given (other hosts, say), rollouts/s and
//               whether every result equals the one-thread result bit for bit; then cheap rollouts (ps_benchmark's
//               circle task, 0.3 ms each) in batches of 50, one batch after another as a learner asks for them, on
//               one thread and on 1 and 2 workers;
//   overhead:   the dispatch's own cost per rollout: batches of the instant "quadratic" task on one worker, one
//               rollout per share and adaptive shares, as a fraction of a 1 s rollout; Table 7.3's planar DR-DMP
//               task (cheap rollouts) on two workers; and on the fold with one rollout per share, the batch's time
//               minus the rollouts' own (as the worker timed them).
//   threads:    the learning's fold rollouts on N threads of this process, no ROS (--threads, default 1,2,4,8,16;
//               one thread always, first):
//               rollouts/s, the speed-up over one thread and the efficiency (speed-up / N), each thread's task built
//               before the timing, and whether every result equals the one-thread result bit for bit; beside it the
//               rollouts' own time (timed inside each) and the machine's speed-up on arithmetic in registers.
// Writes DIR/summary.json, DIR/rollout_benchmark.csv, and (scripts/plot_rollout_benchmark.py) DIR/throughput.png
// and DIR/tables.md.
#include "bimanual_skills/parallel/parallel_for.hpp"
#include "bimanual_skills/realtime/clock.hpp"
#include "bimanual_skills/rollout/dispatcher.hpp"
#include "bimanual_skills/rollout/task_registry.hpp"
#include "bimanual_skills/ros_layer/workers/topic_workers.hpp"
#include "cli/package_share.hpp"
#include "cli/pinned_numerics.hpp"
#include "experiment_cli.hpp"
#include "ros_processes.hpp"

#include <ros/ros.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

namespace bs = bimanual_skills;
namespace br = bimanual_skills::rollout;

namespace {

using bimanual_skills::realtime::Clock;
using bimanual_skills::realtime::secondsSince;

struct Batch {
  std::string task, config;
  std::vector<br::RolloutRequest> requests;
};

Batch makeBatch(const std::string& task, const std::string& config, int rollouts, std::uint32_t seed) {
  Batch b{task, config, {}};
  const Eigen::VectorXd parameters = br::makeRolloutTask(task, config)->initialParameters();
  for (int k = 0; k < rollouts; ++k) b.requests.push_back({parameters, seed + static_cast<std::uint32_t>(k)});
  return b;
}

struct Timing {
  double seconds = 0.0;
  std::vector<br::RolloutResult> results;
  /// [ms] The batch's time not spent in rollouts (as the workers timed them), per rollout: the dispatch's cost.
  double dispatchMs() const {
    double busy = 0.0;
    for (const br::RolloutResult& r : results) busy += r.wall_seconds;
    return results.empty() ? 0.0 : 1000.0 * (seconds - busy) / static_cast<double>(results.size());
  }
};

/// The machine's own scaling, the ceiling of any program's: `chunks` equal pieces of arithmetic in registers (a
/// dependent chain: no memory, no allocation, nothing shared) on `threads` threads [s].
double arithmeticSeconds(int chunks, int threads) {
  std::vector<double> sink(static_cast<std::size_t>(chunks));
  const auto start = Clock::now();
  bs::parallel::parallelFor(sink.size(), threads, [&](int, std::size_t i) {
    double x = 1.0 + static_cast<double>(i);
    for (long k = 0; k < 40'000'000; ++k) x = x * 0.999999 + 1e-6;
    sink[i] = x;
  });
  const double seconds = secondsSince(start);
  if (!std::isfinite(sink.front())) throw std::logic_error("the arithmetic's chain diverged");
  return seconds;
}

/// Times `evaluate` on the requests of `b` in consecutive batches of `per_batch` (all at once for 0).
Timing inBatches(const Batch& b, std::size_t per_batch, br::Evaluator& evaluator) {
  const std::size_t size = per_batch == 0 ? b.requests.size() : per_batch;
  const auto start = Clock::now();
  Timing t;
  for (std::size_t first = 0; first < b.requests.size(); first += size) {
    const auto begin = b.requests.begin() + static_cast<std::ptrdiff_t>(first);
    const std::vector<br::RolloutRequest> batch(
        begin, begin + static_cast<std::ptrdiff_t>(std::min(size, b.requests.size() - first)));
    for (br::RolloutResult& r : evaluator.evaluate(batch)) t.results.push_back(std::move(r));
  }
  t.seconds = secondsSince(start);
  return t;
}

Timing onThreads(const Batch& b, int threads, std::size_t per_batch = 0) {
  br::ParallelEvaluator evaluator([&] { return br::makeRolloutTask(b.task, b.config); }, threads);
  return inBatches(b, per_batch, evaluator);
}

/// A dispatcher to `workers` rollout_worker processes started under a namespace of their own or, with `workers` 0,
/// to the workers already running under `external` (all of those alive once their number stops growing).
class WorkerSet {
 public:
  WorkerSet(int workers, const std::string& external, const std::string& task, const std::string& config,
            std::size_t terms, std::size_t share, const std::string& log) {
    std::string space = external;
    if (workers > 0) {
      const std::string binary = (std::filesystem::read_symlink("/proc/self/exe").parent_path() / "rollout_worker");
      space = "/rollout_benchmark_" + std::to_string(::getpid()) + "_" + std::to_string(++sets_);
      for (int i = 0; i < workers; ++i) {
        children_.push_back(std::make_unique<bs::bench::Child>(
            std::vector<std::string>{binary, "__name:=worker_" + std::to_string(i), "__ns:=" + space}, log));
      }
    }
    bs::ros_layer::WorkerSelection selection;
    selection.space = space;
    selection.task = task;
    selection.config = config;
    br::DispatchConfig dispatch;
    dispatch.share = share;
    dispatch.timeout = 120.0;
    dispatcher_ = std::make_unique<br::Dispatcher>(std::make_unique<bs::ros_layer::TopicWorkerDirectory>(selection),
                                                   terms, dispatch);
    // Until every worker is up (started ones), or until no new one came for 3 s (running ones).
    const auto start = Clock::now();
    auto last_change = start;
    std::size_t seen = 0;
    while (secondsSince(start) < 60.0) {
      if (const std::size_t now = dispatcher_->discover(); now != seen) {
        seen = now;
        last_change = Clock::now();
      }
      if (workers > 0 ? static_cast<int>(seen) == workers : seen > 0 && secondsSince(last_change) > 3.0) break;
      std::this_thread::sleep_for(std::chrono::milliseconds(200));
    }
    count_ = static_cast<int>(seen);
    if (workers > 0 ? count_ != workers : count_ == 0) {
      throw std::runtime_error(std::to_string(count_) + " workers came up under " + space + " (see " + log + ")");
    }
  }

  int count() const noexcept { return count_; }

  /// Times the requests (in batches of `per_batch`, all at once for 0) after a first batch of one rollout per worker
  /// (each builds its task on its first share).
  Timing run(const Batch& b, int workers, std::size_t per_batch = 0) {
    const std::vector<br::RolloutRequest> warm(static_cast<std::size_t>(workers), b.requests.front());
    dispatcher_->evaluate(warm);
    return inBatches(b, per_batch, *dispatcher_);
  }

 private:
  static inline int sets_ = 0;
  int count_ = 0;
  std::vector<std::unique_ptr<bs::bench::Child>> children_;
  std::unique_ptr<br::Dispatcher> dispatcher_;
};

bool identical(const std::vector<br::RolloutResult>& a, const std::vector<br::RolloutResult>& b) {
  if (a.size() != b.size()) return false;
  for (std::size_t i = 0; i < a.size(); ++i) {
    if (a[i].reward != b[i].reward || a[i].terms != b[i].terms || a[i].outcome != b[i].outcome) return false;
  }
  return true;
}

std::vector<int> parseCounts(const std::string& option, const std::string& text) {
  std::vector<int> out;
  std::stringstream ss(text);
  for (std::string item; std::getline(ss, item, ',');) {
    const int n = std::atoi(item.c_str());
    if (n < 1 || n > 64) throw std::invalid_argument(option + ": '" + item + "' is not a count in [1, 64]");
    out.push_back(n);
  }
  if (out.empty()) throw std::invalid_argument(option + ": no count");
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  bimanual_skills::cli::pinNumerics(argv);
  std::string config, workers_text = "1,2,4", threads_text = "1,2,4,8,16", external;  // config: (config/fold_demo.yaml)
  long rollouts = 0;
  bs::bench::ExperimentProgram program;
  program.name = "rollout_benchmark";
  program.description =
      "Rollouts on threads of one process against rollout_worker nodes (topics): throughput of fold rollouts on 1\n"
      "and 2 threads and on 1, 2, 4 workers, and of cheap rollouts (circle, 0.3 ms, in batches of 50) on one thread\n"
      "and on 1 and 2 workers; and the dispatch's own cost per rollout. Starts its own ROS master when none answers\n"
      "at ROS_MASTER_URI, and its own workers. threads: the fold rollouts on N threads of this process (no ROS),\n"
      "speed-up and efficiency per N, results checked identical.";
  program.experiments = {"throughput", "overhead", "threads", "all"};
  program.extra = [&](bs::cli::CommandLine& line) {
    line.option("--config", "FILE", "fold learning file of the fold rollouts (default: config/fold_demo.yaml)",
                &config);
    line.option("--workers", "LIST", "worker counts of the throughput experiment (default 1,2,4)", &workers_text);
    line.option("--threads", "LIST", "thread counts of the threads experiment (default 1,2,4,8,16)", &threads_text);
    line.option("--rollouts", "N", "fold rollouts per batch (default 16; 4 with --quick)", &rollouts, 1, 100000);
    line.option("--worker-namespace", "NS",
                "throughput also on the rollout workers already running under NS (e.g. on other hosts; they read "
                "--config on their host)",
                &external);
  };
  const bs::bench::ExperimentOptions options = bs::bench::parseExperimentOptions(argc, argv, program);
  std::vector<int> worker_counts, thread_counts;
  try {
    worker_counts = parseCounts("--workers", workers_text);
    thread_counts = parseCounts("--threads", threads_text);
  } catch (const std::invalid_argument& e) {
    std::fprintf(stderr, "rollout_benchmark: %s (see --help)\n", e.what());
    return 2;
  }
  try {
    if (config.empty()) config = bimanual_skills::cli::packageFile("config/fold_demo.yaml");
    const int n = rollouts > 0 ? static_cast<int>(rollouts) : (options.quick ? 4 : 16);
    std::filesystem::create_directories(options.out);
    const std::string log = options.out + "/ros.log";
    const bool with_ros = options.experiment != "threads";  // the threads experiment needs no master
    std::unique_ptr<bs::bench::Child> master;
    if (with_ros) {
      master = bs::bench::ensureMaster(log, "rollout_benchmark");
      int ros_argc = 1;
      ros::init(ros_argc, argv, "rollout_benchmark",
                ros::init_options::AnonymousName | ros::init_options::NoSigintHandler);
    }
    std::printf("rollout_benchmark: seed %u, %d fold rollouts per batch (%s)%s\n", options.seed, n, config.c_str(),
                with_ros ? (", worker logs in " + log).c_str() : "");

    std::vector<bs::bench::JsonRow> rows;
    std::ofstream csv(options.out + "/rollout_benchmark.csv");
    csv << "experiment,task,mode,count,share,rollouts,seconds,rollouts_per_second,ms_per_rollout,identical\n";
    const auto record = [&](const std::string& experiment, const std::string& task, const std::string& mode, int count,
                            const std::string& share, int size, double seconds, bool same) {
      const double rate = size / seconds, ms = 1000.0 * seconds / size;
      std::printf("  %-10s %-9s %-7s x%d share %-4s %5d rollouts in %8.3f s: %9.2f rollouts/s, %9.4f ms each%s\n",
                  experiment.c_str(), task.c_str(), mode.c_str(), count, share.c_str(), size, seconds, rate, ms,
                  same ? "" : "  RESULTS DIFFER");
      std::fflush(stdout);
      csv << experiment << ',' << task << ',' << mode << ',' << count << ',' << share << ',' << size << ',' << seconds
          << ',' << rate << ',' << ms << ',' << (same ? "true" : "false") << '\n'
          << std::flush;
      rows.emplace_back()
          .add("experiment", experiment)
          .add("task", task)
          .add("mode", mode)
          .add("count", count)
          .add("share", share)
          .add("rollouts", size)
          .add("seconds", seconds)
          .add("rollouts_per_second", rate)
          .add("ms_per_rollout", ms)
          .add("identical", same);
    };

    const Batch fold = makeBatch("fold", config, n, options.seed);
    const std::size_t fold_terms = br::makeRolloutTask("fold", config)->termNames().size();
    bool all_identical = true;
    if (options.experiment == "threads" || options.experiment == "all") {
      // Enough rollouts for every thread count to keep its threads busy to the end: 4 per thread of the largest.
      const int largest = *std::max_element(thread_counts.begin(), thread_counts.end());
      const Batch batch = makeBatch("fold", config, std::max(n, 4 * largest), options.seed);
      // One thread first: the reference of the speed-ups and of the results.
      std::vector<int> counts{1};
      for (const int threads : thread_counts)
        if (threads != 1) counts.push_back(threads);
      std::vector<br::RolloutResult> reference;
      double one = 0.0, arithmetic_one = 0.0;
      for (const int threads : counts) {
        br::ParallelEvaluator evaluator([&] { return br::makeRolloutTask(batch.task, batch.config); }, threads);
        const Timing t = inBatches(batch, 0, evaluator);
        if (reference.empty()) reference = t.results;
        const bool same = identical(t.results, reference);
        all_identical = all_identical && same;
        const int size = static_cast<int>(batch.requests.size());
        // The rollouts' own time (each timed inside its thread): growing with N is contention (memory, the
        // allocator, the clock), where a constant one with a lower speed-up would be the scheduling's.
        double inside = 0.0;
        for (const br::RolloutResult& r : t.results) inside += r.wall_seconds;
        inside /= static_cast<double>(size);
        const double arithmetic = arithmeticSeconds(4 * largest, threads);
        if (threads == 1) {
          one = t.seconds;
          arithmetic_one = arithmetic;
        }
        record("threads", "fold", "threads", threads, "-", size, t.seconds, same);
        rows.back()
            .add("speedup", one / t.seconds)
            .add("efficiency", one / t.seconds / threads)
            .add("ms_inside_rollout", 1000.0 * inside)
            .add("arithmetic_speedup", arithmetic_one / arithmetic)
            .add("hardware_threads", static_cast<int>(std::thread::hardware_concurrency()));
        std::printf(
            "  threads    x%-2d speed-up %.2f over one thread, efficiency %.2f, %.1f ms inside a rollout; the "
            "machine's arithmetic %.2f\n",
            threads, one / t.seconds, one / t.seconds / threads, 1000.0 * inside, arithmetic_one / arithmetic);
      }
    }
    const Timing one_thread = with_ros ? onThreads(fold, 1) : Timing{};
    if (with_ros) record("throughput", "fold", "threads", 1, "-", n, one_thread.seconds, true);
    if (with_ros && options.experiment != "overhead") {
      const Timing two = onThreads(fold, 2);
      record("throughput", "fold", "threads", 2, "-", n, two.seconds, identical(two.results, one_thread.results));
      all_identical = all_identical && identical(two.results, one_thread.results);
      for (const int w : worker_counts) {
        WorkerSet set(w, "", "fold", config, fold_terms, 0, log);
        const Timing t = set.run(fold, w);
        const bool same = identical(t.results, one_thread.results);
        all_identical = all_identical && same;
        record("throughput", "fold", "workers", w, "auto", n, t.seconds, same);
        if (w == 1) rows.back().add("dispatch_ms_per_rollout", t.dispatchMs());
      }
      if (!external.empty()) {
        WorkerSet set(0, external, "fold", config, fold_terms, 0, log);
        const Timing t = set.run(fold, set.count());
        const bool same = identical(t.results, one_thread.results);
        all_identical = all_identical && same;
        record("throughput", "fold", "workers", set.count(), "auto", n, t.seconds, same);
        rows.back().add("namespace", external);
      }
      // Cheap rollouts as ps_benchmark's circle experiment asks for them: batches of 50, one after another.
      constexpr std::size_t kPerBatch = 50;
      const std::string circle_config = bimanual_skills::cli::packageFile("config/circle_task.yaml");
      const Batch circle = makeBatch("circle", circle_config, options.quick ? 500 : 10000, options.seed);
      const std::size_t circle_terms = br::makeRolloutTask("circle", circle_config)->termNames().size();
      const Timing local = onThreads(circle, 1, kPerBatch);
      const int size = static_cast<int>(circle.requests.size());
      record("throughput", "circle", "threads", 1, "-", size, local.seconds, true);
      rows.back().add("per_batch", static_cast<int>(kPerBatch));
      for (const int w : {1, 2}) {
        WorkerSet set(w, "", "circle", circle_config, circle_terms, 0, log);
        const Timing t = set.run(circle, w, kPerBatch);
        const bool same = identical(t.results, local.results);
        all_identical = all_identical && same;
        record("throughput", "circle", "workers", w, "auto", size, t.seconds, same);
        rows.back()
            .add("per_batch", static_cast<int>(kPerBatch))
            .add("vs_one_thread", local.seconds / t.seconds)
            .add("dispatch_ms_per_rollout", t.dispatchMs())
            .add("ms_per_batch", 1000.0 * t.seconds * kPerBatch / size);
      }
    }
    if (with_ros && options.experiment != "throughput") {
      const int quadratic_rollouts = options.quick ? 100 : 1000;
      const Batch quadratic = makeBatch("quadratic", "", quadratic_rollouts, options.seed);
      const Timing local = onThreads(quadratic, 1);
      for (const std::size_t share : {std::size_t{1}, std::size_t{0}}) {
        WorkerSet set(1, "", "quadratic", "", 1, share, log);
        const Timing t = set.run(quadratic, 1);
        const bool same = identical(t.results, local.results);
        all_identical = all_identical && same;
        const std::string label = share == 0 ? "auto" : std::to_string(share);
        record("overhead", "quadratic", "workers", 1, label, quadratic_rollouts, t.seconds, same);
        rows.back()
            .add("dispatch_ms_per_rollout", t.dispatchMs())
            .add("percent_of_1s_rollout", 100.0 * t.seconds / quadratic_rollouts);
      }
      // A DR-DMP task of Ch. 7 (Table 7.3's planar arm, exploration from each rollout's seed) over a worker.
      const Batch planar = makeBatch("planar_viapoint", "", options.quick ? 50 : 500, options.seed);
      const Timing planar_local = onThreads(planar, 1);
      {
        WorkerSet workers(2, "", "planar_viapoint", "", 2, 0, log);
        const Timing t = workers.run(planar, 2);
        const bool same = identical(t.results, planar_local.results);
        all_identical = all_identical && same;
        record("overhead", "planar_viapoint", "workers", 2, "auto", static_cast<int>(planar.requests.size()), t.seconds,
               same);
        rows.back()
            .add("dispatch_ms_per_rollout", t.dispatchMs())
            .add("percent_of_1s_rollout", 100.0 * t.seconds / static_cast<double>(planar.requests.size()));
      }
      WorkerSet set(1, "", "fold", config, fold_terms, 1, log);
      const Timing t = set.run(fold, 1);
      const bool same = identical(t.results, one_thread.results);
      all_identical = all_identical && same;
      record("overhead", "fold", "workers", 1, "1", n, t.seconds, same);
      rows.back()
          .add("dispatch_ms_per_rollout", t.dispatchMs())
          .add("percent_of_rollout", 100.0 * t.dispatchMs() / (1000.0 * t.seconds / n))
          .add("extra_ms_per_rollout_vs_thread", 1000.0 * (t.seconds - one_thread.seconds) / n);
    }
    bs::bench::writeSummaryJson(options, "rollout_benchmark", rows);
    bs::bench::runPlotScript("rollout_benchmark", "plot_rollout_benchmark.py", options.out);
    if (!all_identical) {
      std::fprintf(stderr, "rollout_benchmark: results differ between threads and workers\n");
      return 1;
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "rollout_benchmark: %s\n", e.what());
    return 1;
  }
  return 0;
}

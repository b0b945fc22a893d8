#!/usr/bin/python3
"""Plots of rollout_benchmark: DIR/throughput.png (fold and cheap circle rollouts per second on threads and on
rollout workers, relative to one thread), DIR/threads.png (the fold's speed-up and efficiency on N threads) and
DIR/tables.md, from DIR/summary.json. Usage: plot_rollout_benchmark.py DIR"""
import json
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from plot_common import output_directory, read_summary  # noqa: E402


def main():
    out = output_directory(__doc__)
    summary = read_summary(out)
    rows = summary["results"]
    throughput = [r for r in rows if r["experiment"] == "throughput"]
    overhead = [r for r in rows if r["experiment"] == "overhead"]
    threads = [r for r in rows if r["experiment"] == "threads"]
    lines = ["# rollout_benchmark (seed %d%s)" % (summary["seed"], ", quick" if summary["quick"] else ""), ""]
    tasks = [t for t in ("fold", "circle") if any(r["task"] == t for r in throughput)]
    if tasks:
        lines += ["| task | evaluator | rollouts | s | rollouts/s | vs 1 thread | same results |",
                  "|---|---|---:|---:|---:|---:|---|"]
        fig, axes = plt.subplots(1, len(tasks), figsize=(6.4 * len(tasks), 3.6), squeeze=False)
        for ax, task in zip(axes[0], tasks):
            rows_t = [r for r in throughput if r["task"] == task]
            base = next(r for r in rows_t if r["mode"] == "threads" and r["count"] == 1)["rollouts_per_second"]
            for r in rows_t:
                mode = r["mode"] if r["count"] > 1 else r["mode"][:-1]
                if "namespace" in r:
                    mode += " under " + r["namespace"]
                lines.append("| %s | %d %s | %d | %.2f | %.3f | %.2f× | %s |" % (
                    task, r["count"], mode, r["rollouts"], r["seconds"], r["rollouts_per_second"],
                    r["rollouts_per_second"] / base, "yes" if r["identical"] else "NO"))

            def label(r):
                text = "%d %s" % (r["count"], r["mode"] if r["count"] > 1 else r["mode"][:-1])
                return text + "\n" + r["namespace"] if "namespace" in r else text

            colours = ["tab:blue" if r["mode"] == "threads" else "tab:green" if "namespace" in r else "tab:orange"
                       for r in rows_t]
            ax.bar([label(r) for r in rows_t], [r["rollouts_per_second"] / base for r in rows_t], color=colours)
            ax.axhline(1.0, color="grey", lw=0.8)
            ax.set_ylabel("throughput / one thread's")
            per_batch = rows_t[0].get("per_batch")
            ax.set_title("%s rollouts (%s)" % (task, "batches of %d" % per_batch if per_batch else
                                               "%d per batch" % rows_t[0]["rollouts"]))
            ax.grid(axis="y", alpha=0.3)
        lines.append("")
        fig.suptitle("Rollout throughput on this machine (2 cores)")
        fig.tight_layout()
        fig.savefig(os.path.join(out, "throughput.png"), dpi=120)
    if overhead:
        lines += ["| task | share | rollouts | ms per rollout | dispatch ms per rollout | dispatch cost |",
                  "|---|---|---:|---:|---:|---:|"]
        for r in overhead:
            if "percent_of_1s_rollout" in r:
                cost = "%.3f %% of a 1 s rollout" % r["percent_of_1s_rollout"]
            else:
                cost = "%.2f %% of the rollout (%+.1f ms vs 1 thread)" % (r["percent_of_rollout"],
                                                                           r["extra_ms_per_rollout_vs_thread"])
            lines.append("| %s | %s | %d | %.3f | %.3f | %s |" % (
                r["task"], r["share"], r["rollouts"], r["ms_per_rollout"], r["dispatch_ms_per_rollout"], cost))
        lines.append("")
    if threads:
        cores = threads[0]["hardware_threads"]
        lines += ["The learning's fold rollouts on N threads, no ROS (%d hardware threads):" % cores, "",
                  "| threads | rollouts | s | rollouts/s | speed-up | efficiency | ms inside a rollout | "
                  "machine's arithmetic speed-up | same results |",
                  "|---:|---:|---:|---:|---:|---:|---:|---:|---|"]
        for r in threads:
            lines.append("| %d | %d | %.2f | %.3f | %.2f× | %.2f | %.1f | %.2f× | %s |" % (
                r["count"], r["rollouts"], r["seconds"], r["rollouts_per_second"], r["speedup"], r["efficiency"],
                r["ms_inside_rollout"], r["arithmetic_speedup"], "yes" if r["identical"] else "NO"))
        lines.append("")
        fig, ax = plt.subplots(figsize=(5.5, 3.8))
        counts = [r["count"] for r in threads]
        ax.plot(counts, [r["speedup"] for r in threads], "o-", label="fold rollouts")
        ax.plot(counts, [r["arithmetic_speedup"] for r in threads], "s--", label="arithmetic in registers (the machine)")
        ax.plot(counts, counts, ":", color="grey", label="ideal")
        ax.axvline(cores, color="tab:red", lw=0.8, label="hardware threads")
        ax.set_xlabel("threads")
        ax.set_ylabel("speed-up over one thread")
        ax.set_title("Fold rollouts on N threads (%d hardware threads)" % cores)
        ax.legend(fontsize=8)
        ax.grid(alpha=0.3)
        fig.tight_layout()
        fig.savefig(os.path.join(out, "threads.png"), dpi=120)
    with open(os.path.join(out, "tables.md"), "w") as f:
        f.write("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())

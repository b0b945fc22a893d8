#!/usr/bin/env python3
"""Plots and tables of control_loop_benchmark: DIR/periods.png (the distribution of the loop period of each design
beside the noise floor), DIR/services.png (the services' answer times by caller) and DIR/tables.md (summary.json's
loop and services rows and pacing.csv as Markdown). Usage: plot_control_loop_benchmark.py DIR"""
import csv
import json
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402


def read_rows(path):
    with open(path) as f:
        return list(csv.DictReader(f))


def main():
    if len(sys.argv) != 2 or sys.argv[1] in ("-h", "--help"):
        print(__doc__)
        return 0 if len(sys.argv) == 2 else 2
    out = sys.argv[1]
    lines = []
    with open(os.path.join(out, "summary.json")) as f:
        results = json.load(f)["results"]
    loop_rows = [r for r in results if r["experiment"] == "loop"]
    if loop_rows:
        lines += ["| design | priority | runs × s | period median / p99 / p99.9 [µs] | jitter p99.9 [µs] | "
                  "jitter p99.9 beyond the floor, mean ± t 95 % [µs] | command → first torque, median / p99 [µs] | "
                  "control allocations |",
                  "|---|---:|---|---|---:|---|---|---|"]
        for r in loop_rows:
            us = lambda k: (r[k] if r[k] is not None else float("nan")) * 1e6  # noqa: E731
            alloc = "—" if r["control_allocations"] is None else f"{int(r['control_allocations'])}"
            latency = "—" if r["design"] == "noise_floor" else f"{us('latency_median_s'):.0f} / {us('latency_p99_s'):.0f}"
            beyond = "—" if r["design"] == "noise_floor" else (f"{us('jitter_p999_beyond_floor_mean_s'):+.1f} ± "
                                                               f"{us('jitter_p999_beyond_floor_ci95_s'):.1f}")
            lines.append(f"| {r['design'].replace('_', ' ')} | {r['priority']} | {r['runs']} × {r['seconds_per_run']:g} | "
                         f"{us('period_median_s'):.1f} / {us('period_p99_s'):.1f} / {us('period_p999_s'):.1f} | "
                         f"{us('jitter_p999_s'):.1f} | {beyond} | {latency} | {alloc} |")
        fig, axes = plt.subplots(1, 2, figsize=(12, 4.5), sharey=True)
        for ax, priority in zip(axes, ("0", "80")):
            drawn = False
            for design, color in (("noise_floor", "0.5"), ("hosted", "tab:blue"), ("per_message", "tab:red")):
                name = f"periods_{design}_{priority}.csv"
                path = os.path.join(out, name)
                if not os.path.exists(path):
                    continue
                periods = np.array([float(r["period_s"]) for r in read_rows(path)]) * 1e6
                if len(periods) == 0:
                    continue
                jitter = np.sort(np.abs(periods - 1000.0))
                tail = 1.0 - np.arange(len(jitter)) / len(jitter)
                ax.loglog(np.maximum(jitter, 0.1), tail, color=color, label=design.replace("_", " "))
                drawn = True
            ax.set_title("normal priority" if priority == "0" else "SCHED_FIFO priority 80")
            ax.set_xlabel("period jitter |T − 1 ms| [µs]")
            ax.grid(True, which="both", alpha=0.3)
            if drawn:
                ax.legend()
            else:
                ax.text(0.5, 0.5, "not measured (--quick)", transform=ax.transAxes, ha="center")
        axes[0].set_ylabel("fraction of periods with more jitter")
        fig.suptitle("Control loop period under a competing load (control_loop_benchmark)")
        fig.tight_layout()
        fig.savefig(os.path.join(out, "periods.png"), dpi=110)
    service_rows = [r for r in results if r["experiment"] == "services"]
    if service_rows:
        lines += ["", "| service | caller | answers | median [ms] | p99 [ms] | max [ms] | without an answer |",
                  "|---|---|---:|---:|---:|---:|---:|"]
        for r in sorted(service_rows, key=lambda r: (r["service"], r["method"])):
            lines.append(f"| {r['service']} | {r['method'].replace('_', '-')} | {int(r['answers'])} | "
                         f"{1e3 * r['answer_median_s']:.2f} | {1e3 * r['answer_p99_s']:.2f} | "
                         f"{1e3 * r['answer_max_s']:.2f} | {int(r['without_answer'])} |")
        fig, ax = plt.subplots(figsize=(8, 4.5))
        for method, color in (("persistent", "tab:blue"), ("non_persistent", "tab:red")):
            times = [1e3 * float(r["answer_s"]) for r in read_rows(os.path.join(out, "services.csv"))
                     if r["method"] == method and r["answered"] == "1"]
            if times:
                times = np.sort(times)
                ax.semilogx(times, np.arange(1, len(times) + 1) / len(times), color=color,
                            label=method.replace("_", "-") + " (" + str(len(times)) + " answers)")
        ax.axvline(50.0, color="0.5", linestyle="--", label="50 ms")
        ax.set_xlabel("answer time [ms]")
        ax.set_ylabel("fraction of calls answered sooner")
        ax.set_title("bullet_sim's ~pause, ~step, ~grasp, ~reset beside a second simulator and a busy learner")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend()
        fig.tight_layout()
        fig.savefig(os.path.join(out, "services.png"), dpi=110)
    pacing = os.path.join(out, "pacing.csv")
    if os.path.exists(pacing):
        lines += ["", "| when | real-time factor (target 1) |", "|---|---:|"]
        lines += [f"| {r['when']} | {float(r['realtime_factor']):.4f} |" for r in read_rows(pacing)]
    with open(os.path.join(out, "tables.md"), "w") as f:
        f.write("\n".join(lines) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""Plots and tables of track_benchmark (compliant object tracking, thesis Sec. 4.3.2).

usage: plot_track_benchmark.py DIR

Reads DIR/paths.csv (a record per object path), DIR/samples.csv (tracking errors with the object's speed) and
DIR/summary.json; writes DIR/error_by_speed.png (the tool's error against the object's pre-grasp point by the
object's speed, the 2 cm goal), DIR/paths.png (each path's p95 error, its grasp) and DIR/tables.md."""
import csv
import math
import os

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from plot_common import output_directory, read_summary  # noqa: E402

BINS = [0.0, 0.05, 0.1, 0.15, 0.2, 1e9]


def read_csv(path):
    with open(path, encoding="utf-8") as f:
        return list(csv.DictReader(f))


def number(text):
    return float(text) if text not in ("", "nan") else math.nan


def main():
    directory = output_directory(__doc__)
    summary = read_summary(directory)
    paths = sorted(read_csv(os.path.join(directory, "paths.csv")), key=lambda r: int(r["path"]))
    samples = read_csv(os.path.join(directory, "samples.csv"))
    errors = np.array([number(r["error_m"]) for r in samples]) * 1e3
    speeds = np.array([number(r["speed_m_s"]) for r in samples])

    labels, groups = [], []
    for low, high in zip(BINS[:-1], BINS[1:]):
        chosen = errors[(speeds >= low) & (speeds < high)]
        if chosen.size:
            labels.append(f"{low:.2f}-{high:.2f}" if high < 10 else f">= {low:.2f}")
            groups.append(chosen)
    fig, ax = plt.subplots(figsize=(7, 4.2))
    ax.boxplot(groups, labels=labels, whis=(5, 95), showfliers=False)
    for k, g in enumerate(groups):
        ax.plot(k + 1, np.percentile(g, 95), "r_", markersize=18)
    ax.axhline(20.0, color="tab:red", linestyle="--", label="goal: p95 <= 20 mm up to 0.2 m/s")
    ax.set_xlabel("object speed [m/s]")
    ax.set_ylabel("tool to pre-grasp point [mm]")
    ax.set_title(f"Tracking error over {len(paths)} paths (whiskers 5-95 %, red: p95)")
    ax.legend(loc="upper left")
    fig.tight_layout()
    fig.savefig(os.path.join(directory, "error_by_speed.png"), dpi=120)
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(7, 4.2))
    index = [int(r["path"]) for r in paths]
    p95 = [number(r["error_p95_m"]) * 1e3 for r in paths]
    grasped = [r["grasped"] == "1" for r in paths]
    ax.bar(index, p95, color=["tab:green" if g else "tab:orange" for g in grasped])
    ax.axhline(20.0, color="tab:red", linestyle="--")
    ax.set_xticks(index)
    ax.set_xlabel("path (green: grasped, orange: not)")
    ax.set_ylabel("p95 tracking error [mm]")
    ax.set_title(f"Each path: p95 error while following; {sum(grasped)} of {len(paths)} grasped")
    fig.tight_layout()
    fig.savefig(os.path.join(directory, "paths.png"), dpi=120)
    plt.close(fig)

    lines = [f"# track_benchmark, seed {summary['seed']}{' (quick)' if summary['quick'] else ''}", "",
             "| object speed [m/s] | samples | mean [mm] | p95 [mm] | max [mm] |", "|---|---:|---:|---:|---:|"]
    for row in summary["results"]:
        if row.get("table") != "error_by_speed" or row["samples"] == 0:
            continue
        lines.append(f"| {row['speed_from']:.2f}-{row['speed_to']:.2f} | {row['samples']} | "
                     f"{1e3 * row['error_mean_m']:.1f} | {1e3 * row['error_p95_m']:.1f} | {1e3 * row['error_max_m']:.1f} |")
    total = [r for r in summary["results"] if r.get("table") == "paths"][0]
    lost = sum(int(r["lost"]) for r in paths)
    reacquired = sum(int(r["reacquired"]) for r in paths)
    back = [number(r["reacquire_time_s"]) for r in paths if not math.isnan(number(r["reacquire_time_s"]))]
    hold = [number(r["hold_speed_rad_s"]) for r in paths if int(r["lost"]) > 0]
    latency = [number(r["latency_median_s"]) for r in paths]
    times = ", ".join("%.1f" % number(r["grasp_at_s"]) for r in paths if r["grasped"] == "1")
    carried = sum(1 for r in paths if r["grasped"] == "1" and number(r["grasp_at_s"]) < number(r["put_down_s"]))
    misses = sum(int(r["grasp_requests"]) - (r["grasped"] == "1") for r in paths)
    lines += ["", f"- paths {total['paths']}, grasped {total['grasped']} ({100 * total['grasp_success']:.0f} %), "
              f"{carried} of them while the can was carried (the rest after it was put down); grippers closed on "
              f"nothing {misses} times; grasp times {times} s",
              f"- tracking error p95 at speeds <= 0.2 m/s: {1e3 * total['error_p95_up_to_0_2_m_s']:.1f} mm",
              f"- targets lost {lost} times (out of view), reacquired {reacquired}; back within 2 cm after "
              f"{np.mean(back) if back else math.nan:.2f} s on average; joint reference speed 0.5 s after a loss at "
              f"most {max(hold) if hold else 0:.3g} rad/s",
              f"- latency (modelled {1e3 * total['latency_model_s']:.0f} ms + the follower's period): median "
              f"{1e3 * np.median(latency):.1f} ms",
              f"- allocations in the control loop: {total['control_allocations']}",
              "- following ended on its own (the controller left tracking): "
              + (", ".join(f"path {r['path']} at {number(r['ended_s']):.1f} s ({r['ended']})" for r in paths
                           if number(r["ended_s"]) >= 0) or "never")]
    with open(os.path.join(directory, "tables.md"), "w", encoding="utf-8") as f:
        f.write("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()

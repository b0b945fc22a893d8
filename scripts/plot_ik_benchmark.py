#!/usr/bin/env python3
"""Plots and markdown tables for ik_benchmark output: reads DIR/*.csv and DIR/summary.json, writes DIR/*.png and
DIR/tables.md (measured figures next to the thesis' Tables 3.4 and 3.5 and TRAC-IK's published protocol).

Usage: plot_ik_benchmark.py DIR
"""
import csv
import math
import os
from collections import OrderedDict, defaultdict

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from plot_common import output_directory, read_summary  # noqa: E402

# Thesis Table 3.4: % sol, t_sol (ms, Matlab), e_nosol, it_sol.
THESIS_34 = {
    "JP": (100.0, 42.6, None, 12.2), "JT": (40.70, 504.8, 0.302, 148.7), "SD": (98.4, 154.3, 0.042, 43.5),
    "JD": (100.0, 39.4, None, 11.6), "JF": (100.0, 38.6, None, 11.2), "ED": (100.0, 36.9, None, 10.6),
    "IED": (100.0, 38.7, None, 11.1), "SVF": (100.0, 37.1, None, 10.7), "SVF+ED": (100.0, 35.8, None, 10.3),
    "SVF+SD": (99.7, 145.2, 0.041, 41.1),
}
# Thesis Table 3.5 (A = 1.0): % sol, % sol (JL), t_sol (ms), e_nosol, it_sol.
THESIS_35 = {
    "JW": (100.0, 45.3, 37.5, None, 9.6), "GP": (100.0, 34.7, 43.0, None, 11.0), "TA": (100.0, 84.6, 147.3, None, 28.3),
    "JC": (73.6, 53.5, 73.1, 0.826, 18.9), "TP": (33.6, 33.6, 48.9, 1.005, 12.0), "CTP": (83.7, 83.7, 366.8, 0.381, 21.8),
    "CTP+SVF": (86.6, 86.6, 300.4, 0.401, 48.2), "CTP+SD": (97.1, 97.1, 660.0, 0.867, 26.2),
    "CTP+SD+SVF": (98.3, 98.3, 568.7, 0.719, 22.6),
}


def read_csv(path):
    with open(path, newline="", encoding="utf-8") as f:
        return list(csv.DictReader(f))


def fmt(x, digits=1):
    return "-" if x is None else f"{x:.{digits}f}"


def results(summary, experiment):
    return [r for r in summary["results"] if r["experiment"] == experiment]


def bars(ax, labels, values, ylabel, title, log=False):
    ax.bar(range(len(labels)), values, color="#4477aa")
    ax.set_xticks(range(len(labels)))
    ax.set_xticklabels(labels, rotation=45, ha="right", fontsize=8)
    ax.set_ylabel(ylabel)
    ax.set_title(title, fontsize=10)
    if log:
        ax.set_yscale("log")
    ax.grid(axis="y", alpha=0.3)


def table34(out, summary, lines):
    rows = results(summary, "table34")
    if not rows:
        return
    fig, axes = plt.subplots(1, 3, figsize=(14, 4))
    names = [r["solver"] for r in rows]
    bars(axes[0], names, [100 * r["success_rate"] for r in rows], "% solved", "Success")
    bars(axes[1], names, [r["median_us"] for r in rows], "median time [us]", "Time per solve", log=True)
    bars(axes[2], names, [r["mean_iterations"] for r in rows], "iterations", "Mean iterations (solved)")
    fig.suptitle(f"Table 3.4 reproduction: WAM, {rows[0]['samples']} random start/goal pairs")
    fig.tight_layout()
    fig.savefig(os.path.join(out, "table34.png"), dpi=110)
    plt.close(fig)
    lines += ["### Table 3.4: methods not concerned with joint limits", "",
              f"{rows[0]['samples']} random start/goal pairs uniform within the limits (seed {summary['seed']}).", "",
              "| method | % sol. | % sol. thesis | median t (us) | p99 t (us) | thesis t̄ (ms, Matlab) | ē_nosol | thesis ē_nosol | it | thesis it |",
              "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for r in rows:
        t = THESIS_34.get(r["solver"], (None,) * 4)
        e = r["mean_residual_failed"] if r["success_rate"] < 1 else None
        lines.append(f"| {r['solver']} | {100 * r['success_rate']:.1f} | {fmt(t[0])} | {r['median_us']:.1f} | "
                     f"{r['p99_us']:.1f} | {fmt(t[1])} | {fmt(e, 3)} | {fmt(t[2], 3)} | {r['mean_iterations']:.1f} | "
                     f"{fmt(t[3])} |")
    lines.append("")


def table35(out, summary, lines):
    rows = results(summary, "table35")
    if not rows:
        return
    fig, axes = plt.subplots(1, 2, figsize=(12, 4))
    names = [r["solver"] for r in rows]
    x = range(len(names))
    axes[0].bar([i - 0.2 for i in x], [100 * r["success_rate"] for r in rows], 0.4, label="solved")
    axes[0].bar([i + 0.2 for i in x], [100 * r["within_limits_rate"] for r in rows], 0.4, label="solved within limits")
    axes[0].set_xticks(list(x))
    axes[0].set_xticklabels(names, rotation=45, ha="right", fontsize=8)
    axes[0].set_ylabel("%")
    axes[0].legend(fontsize=8)
    axes[0].grid(axis="y", alpha=0.3)
    bars(axes[1], names, [r["median_us"] for r in rows], "median time [us]", "Time per solve", log=True)
    fig.suptitle(f"Table 3.5 reproduction: WAM, {rows[0]['samples']} pairs, A = 1.0")
    fig.tight_layout()
    fig.savefig(os.path.join(out, "table35.png"), dpi=110)
    plt.close(fig)
    lines += ["### Table 3.5: limit-aware methods, A = 1.0", "",
              f"{rows[0]['samples']} start/goal pairs with |q0 - qF| < 1.0 per joint (seed {summary['seed']}).", "",
              "| method | % sol. | thesis | % sol. (JL) | thesis | median t (us) | p99 t (us) | thesis t̄ (ms, Matlab) | ē_nosol | thesis | it | thesis |",
              "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for r in rows:
        t = THESIS_35.get(r["solver"], (None,) * 5)
        e = r["mean_residual_failed"] if r["success_rate"] < 1 else None
        lines.append(f"| {r['solver']} | {100 * r['success_rate']:.1f} | {fmt(t[0])} | "
                     f"{100 * r['within_limits_rate']:.1f} | {fmt(t[1])} | {r['median_us']:.1f} | {r['p99_us']:.1f} | "
                     f"{fmt(t[2])} | {fmt(e, 3)} | {fmt(t[3], 3)} | {r['mean_iterations']:.1f} | {fmt(t[4])} |")
    lines.append("")


def fig35(out, summary, lines):
    rows = results(summary, "fig35")
    if not rows:
        return
    curves = OrderedDict()
    for r in rows:
        curves.setdefault(r["solver"], []).append((float(r["setting"].split("=")[1]), 100 * r["within_limits_rate"]))
    fig, ax = plt.subplots(figsize=(8, 5))
    for name, points in curves.items():
        ax.plot([p[0] for p in points], [p[1] for p in points], marker="o", label=name,
                linewidth=2.5 if name == "CTP+SD+SVF" else 1.2)
    ax.set_xlabel("A [rad]: max |q0 - qF| per joint")
    ax.set_ylabel("% solved within joint limits")
    ax.set_title("Fig. 3.5 reproduction: WAM")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(os.path.join(out, "fig35.png"), dpi=110)
    plt.close(fig)
    amplitudes = sorted({p[0] for pts in curves.values() for p in pts})
    lines += ["### Fig. 3.5: % solved within limits vs A", "",
              "| method | " + " | ".join(f"{a:.2f}" for a in amplitudes) + " |",
              "|---|" + "---:|" * len(amplitudes)]
    for name, points in curves.items():
        values = dict(points)
        lines.append(f"| {name} | " + " | ".join(f"{values.get(a, float('nan')):.1f}" for a in amplitudes) + " |")
    lines.append("")


def fig32(out):
    path = os.path.join(out, "fig32.csv")
    if not os.path.exists(path):
        return
    series = defaultdict(list)
    for row in read_csv(path):
        series[row["method"]].append((float(row["sigma_min"]), float(row["condition_number"])))
    fig, ax = plt.subplots(figsize=(7, 5))
    for name, points in series.items():
        ax.loglog([p[0] for p in points], [p[1] for p in points], label=name, linewidth=2.5 if name == "SVF" else 1.2)
    ax.invert_xaxis()
    ax.set_xlabel("smallest singular value of J (approaching the singular target)")
    ax.set_ylabel("condition number of the inverse operator")
    ax.set_title("Fig. 3.2 reproduction: 4R planar arm")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(os.path.join(out, "fig32.png"), dpi=110)
    plt.close(fig)


def fig33(out):
    path = os.path.join(out, "fig33.csv")
    if not os.path.exists(path):
        return
    runs = OrderedDict()
    for row in read_csv(path):
        runs.setdefault((row["figure"], row["method"]), []).append(row)
    for figure in ("3.3", "3.4"):
        keys = [k for k in runs if k[0] == figure]
        if not keys:
            continue
        fig, axes = plt.subplots(2, len(keys), figsize=(2.6 * len(keys), 5.5), squeeze=False)
        for col, key in enumerate(keys):
            rows = runs[key]
            its = [int(r["iteration"]) for r in rows]
            top, bottom = axes[0][col], axes[1][col]
            for j in range(1, 5):
                top.plot(its, [float(r[f"q{j}"]) for r in rows], label=f"q{j}")
            top.axhline(2.0, color="k", linewidth=0.6, linestyle="--")
            top.axhline(-2.0, color="k", linewidth=0.6, linestyle="--")
            top.set_ylim(-8.0, 8.0)  # TP's discontinuous gains reach 1e12 rad; clipped so the limits stay visible
            top.set_title(key[1], fontsize=9)
            top.set_xlabel("iteration", fontsize=8)
            top.tick_params(labelsize=7)
            stride = max(1, len(rows) // 12)
            for k, r in enumerate(rows[::stride] + [rows[-1]]):
                q = [float(r[f"q{j}"]) for j in range(1, 5)]
                xs, ys, angle = [0.0], [0.0], 0.0
                for qi in q:
                    angle += qi
                    xs.append(xs[-1] + 0.25 * math.cos(angle))
                    ys.append(ys[-1] + 0.25 * math.sin(angle))
                shade = 0.85 - 0.75 * k / max(1, len(rows[::stride]))
                bottom.plot(xs, ys, color=(shade, shade, shade), linewidth=1)
            bottom.plot([float(r["x"]) for r in rows], [float(r["y"]) for r in rows], "k-", linewidth=0.5)
            bottom.plot([0.15], [0.55], "r*")
            bottom.set_aspect("equal")
            bottom.tick_params(labelsize=7)
        axes[0][0].legend(fontsize=7)
        fig.suptitle(f"Fig. {figure} reproduction: 4R planar arm from the horizontal start to (0.15, 0.55); "
                     "joint plots clipped to ±8 rad, limits ±2 rad dashed")
        fig.tight_layout()
        fig.savefig(os.path.join(out, "fig33.png" if figure == "3.3" else "fig34.png"), dpi=110)
        plt.close(fig)


def tracik(out, summary, lines):
    rows = results(summary, "tracik")
    if not rows:
        return
    robot = rows[0].get("robot", "wam")
    fig, axes = plt.subplots(1, 2, figsize=(13, 4.5))
    labels = [f"{r['solver']} {r['setting']}" for r in rows]
    bars(axes[0], labels, [100 * r["within_limits_rate"] for r in rows], "% solved within limits", "Success")
    bars(axes[1], labels, [r["median_us"] for r in rows], "median time [us]", "Time per solve (5 ms budget)", log=True)
    fig.suptitle(f"TRAC-IK protocol: {robot}, {rows[0]['samples']} random poses")
    fig.tight_layout()
    fig.savefig(os.path.join(out, "tracik.png"), dpi=110)
    plt.close(fig)
    lines += [f"### TRAC-IK protocol ({robot})", "",
              f"{rows[0]['samples']} random configurations within limits -> FK -> IK; success: every pose-error twist "
              f"component <= 1e-5; 5 ms budget; failures counted with their full time (seed {summary['seed']}).", "",
              "| solver | setting | % solved | % solved within limits | median (us) | p99 (us) |",
              "|---|---|---:|---:|---:|---:|"]
    for r in rows:
        lines.append(f"| {r['solver']} | {r['setting']} | {100 * r['success_rate']:.2f} | "
                     f"{100 * r['within_limits_rate']:.2f} | {r['median_us']:.1f} | {r['p99_us']:.1f} |")
    lines.append("")


def closest(out, summary, lines):
    rows = results(summary, "closest")
    if not rows:
        return
    robot = rows[0].get("robot", "wam")
    lines += [f"### Distance of the answer to the seed ({robot})", "",
              "Excess over the nearest solution a 100 ms AllDistinct search (and the goal configuration) gives, "
              f"seeds within +-A of the goal configuration (seed {summary['seed']}).", "",
              "| mode | A (rad) | solved | at the nearest | excess median (rad) | p90 | p99 | max |",
              "|---|---:|---:|---:|---:|---:|---:|---:|"]
    for r in rows:
        mode = r["setting"].split(" /")[0]
        lines.append(f"| {mode} | {r['A']:.1f} | {r['samples']} | {100 * r['fraction_at_best']:.1f} % | "
                     f"{r['excess_median_rad']:.4f} | {r['excess_p90_rad']:.4f} | {r['excess_p99_rad']:.4f} | "
                     f"{r['excess_max_rad']:.4f} |")
    lines.append("")


def main():
    out = output_directory(__doc__)
    summary = read_summary(out)
    lines = [f"Generated by ik_benchmark --experiment {summary['experiment']} --seed {summary['seed']}"
             + (" --quick" if summary["quick"] else ""), ""]
    table34(out, summary, lines)
    table35(out, summary, lines)
    fig35(out, summary, lines)
    tracik(out, summary, lines)
    closest(out, summary, lines)
    fig32(out)
    fig33(out)
    with open(os.path.join(out, "tables.md"), "w", encoding="utf-8") as f:
        f.write("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()

#!/usr/bin/env python3
"""Learning curves, paths, the EM-vs-PCA map and markdown tables for dr_benchmark output: reads DIR/*.csv and
DIR/summary.json, writes DIR/planar15.png, DIR/planar10.png, DIR/wam_circle.png (reward of the mean policy per update,
mean and 95 % interval of the mean over runs), DIR/planar10_paths.png (the arm's initial motion and the first run's
path before and after learning, via-points; cf. Fig. 7.6a, c), DIR/wam_circle_paths.png (the tool's path before and
after learning against the circle; cf. Fig. 7.7a), DIR/em_vs_pca.png (mean rho of 7.21 per (d, r)),
DIR/optima_progress.png (the cost L-BFGS reaches against the rollouts it spent, beside the learners' budget),
DIR/nao_distribution.png, DIR/nao_correlation.png and DIR/nao_fit.png (the NAO walks: cf. Figs. 7.4, 7.3) and
DIR/tables.md (measured figures next to the thesis' Tables 7.3 and 7.4).

Usage: plot_dr_benchmark.py DIR
"""
import csv
import math
import os
from collections import defaultdict

import matplotlib
import numpy as np

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from plot_common import mean_ci, output_directory, read_summary  # noqa: E402

CHECKPOINTS = [1, 10, 25, 50, 100, 200]
# Table 7.3: -log10(-R) after 1, 10, 25, 50, 100, 200 updates (mean, 95 % interval over 20 runs).
THESIS_73 = {
    'DR-DMP_CMU(10)': [(0.698, 0.07), (1.244, 0.101), (1.713, 0.102), (1.897, 0.038), (1.934, 0.03), (1.949, 0.026)],
    'DR-DMP_CMU(8)': [(0.724, 0.073), (1.265, 0.155), (1.617, 0.135), (1.849, 0.079), (1.905, 0.072), (1.923, 0.075)],
    'DR-DMP_CMU(5)': [(0.752, 0.117), (1.304, 0.098), (1.73, 0.108), (1.91, 0.076), (1.954, 0.063), (1.968, 0.064)],
    'DR-DMP_CMU(2)': [(0.677, 0.063), (1.211, 0.093), (1.786, 0.073), (1.977, 0.04), (1.993, 0.039), (1.997, 0.037)],
    'DR-DMP_CMU(1)': [(0.612, 0.057), (1.161, 0.103), (1.586, 0.071), (1.86, 0.056), (1.931, 0.041), (1.951, 0.042)],
    'DR-DMP_MCMU(2,10)': [(0.738, 0.094), (1.304, 0.074), (1.666, 0.159), (1.848, 0.117), (1.893, 0.08), (1.919, 0.054)],
    'DR-DMP_MCMU(2,8)': [(0.676, 0.123), (1.27, 0.168), (1.681, 0.148), (1.883, 0.058), (1.927, 0.038), (1.939, 0.036)],
    'DR-DMP_MCMU(2,5)': [(0.687, 0.052), (1.264, 0.113), (1.684, 0.13), (1.897, 0.091), (1.95, 0.056), (1.962, 0.054)],
    'DR-DMP_MCMU(2,2)': [(0.704, 0.055), (1.258, 0.13), (1.749, 0.162), (1.976, 0.029), (2.0, 0.016), (2.006, 0.017)],
    'DR-DMP_MCMU(2,1)': [(0.579, 0.076), (1.103, 0.125), (1.607, 0.131), (1.885, 0.107), (1.959, 0.055), (1.972, 0.054)],
    'IDR-DMP_CMU': [(0.715, 0.14), (1.195, 0.091), (1.672, 0.121), (1.952, 0.04), (1.997, 0.034), (2.004, 0.03)],
    'IDR-DMP_MCMU(2)': [(0.656, 0.058), (1.174, 0.158), (1.683, 0.169), (1.937, 0.067), (2.013, 0.03), (2.019, 0.028)],
}
# Table 7.4: R after 1, 10, 25, 50, 100, 200 updates (mean, 95 % interval over 10 runs).
THESIS_74 = {
    'DR-DMP0(7)': [(-1.812, 0.076), (-0.834, 0.078), (-0.355, 0.071), (-0.165, 0.034), (-0.085, 0.024), (-0.054, 0.019)],
    'DR-DMP0(6)': [(-1.801, 0.053), (-0.836, 0.058), (-0.359, 0.058), (-0.169, 0.04), (-0.093, 0.027), (-0.06, 0.021)],
    'DR-DMP0(5)': [(-1.81, 0.047), (-0.834, 0.058), (-0.372, 0.048), (-0.164, 0.037), (-0.086, 0.028), (-0.057, 0.023)],
    'DR-DMP0(4)': [(-1.879, 0.054), (-0.901, 0.043), (-0.405, 0.059), (-0.189, 0.037), (-0.093, 0.025), (-0.061, 0.021)],
    'DR-DMP0(3)': [(-1.523, 0.057), (-0.765, 0.051), (-0.34, 0.052), (-0.162, 0.038), (-0.096, 0.03), (-0.072, 0.025)],
    'DR-DMP0(2)': [(-1.833, 0.065), (-0.906, 0.074), (-0.422, 0.063), (-0.23, 0.043), (-0.14, 0.029), (-0.099, 0.024)],
    'DR-DMP0(1)': [(-0.86, 0.03), (-0.447, 0.031), (-0.195, 0.031), (-0.103, 0.022), (-0.068, 0.022), (-0.052, 0.021)],
    'DR-DMP_CMU(7)': [(-1.97, 0.08), (-0.907, 0.072), (-0.386, 0.045), (-0.167, 0.04), (-0.084, 0.028), (-0.053, 0.021)],
    'DR-DMP_CMU(6)': [(-1.949, 0.071), (-0.878, 0.078), (-0.367, 0.066), (-0.175, 0.046), (-0.09, 0.028), (-0.06, 0.021)],
    'DR-DMP_CMU(5)': [(-1.925, 0.073), (-0.897, 0.078), (-0.41, 0.076), (-0.192, 0.042), (-0.092, 0.025), (-0.056, 0.019)],
    'DR-DMP_CMU(4)': [(-2.146, 0.085), (-1.108, 0.15), (-0.386, 0.113), (-0.174, 0.055), (-0.094, 0.036), (-0.067, 0.031)],
    'DR-DMP_CMU(3)': [(-0.678, 0.274), (-0.33, 0.122), (-0.141, 0.058), (-0.073, 0.033), (-0.044, 0.025), (-0.03, 0.021)],
    'DR-DMP_CMU(2)': [(-0.758, 0.329), (-0.401, 0.155), (-0.173, 0.074), (-0.085, 0.045), (-0.043, 0.024), (-0.027, 0.014)],
    'DR-DMP_CMU(1)': [(-0.563, 0.108), (-0.216, 0.081), (-0.094, 0.036), (-0.053, 0.022), (-0.034, 0.017), (-0.025, 0.013)],
    'DR-DMP0_MCMU(3,7)': [(-1.88, 0.08), (-0.854, 0.061), (-0.384, 0.047), (-0.196, 0.041), (-0.107, 0.032), (-0.07, 0.024)],
    'DR-DMP0_MCMU(3,6)': [(-1.937, 0.064), (-0.901, 0.098), (-0.371, 0.063), (-0.164, 0.041), (-0.075, 0.024), (-0.046, 0.018)],
    'DR-DMP0_MCMU(3,5)': [(-1.995, 0.087), (-0.916, 0.072), (-0.363, 0.067), (-0.165, 0.039), (-0.083, 0.027), (-0.055, 0.019)],
    'DR-DMP0_MCMU(3,4)': [(-2.169, 0.054), (-1.108, 0.115), (-0.355, 0.103), (-0.154, 0.058), (-0.081, 0.035), (-0.053, 0.022)],
    'DR-DMP0_MCMU(3,3)': [(-0.468, 0.016), (-0.239, 0.02), (-0.104, 0.016), (-0.054, 0.011), (-0.029, 0.006), (-0.017, 0.004)],
    'DR-DMP0_MCMU(3,2)': [(-0.499, 0.016), (-0.272, 0.025), (-0.117, 0.016), (-0.057, 0.01), (-0.031, 0.006), (-0.021, 0.005)],
    'DR-DMP0_MCMU(3,1)': [(-0.462, 0.033), (-0.146, 0.014), (-0.061, 0.012), (-0.031, 0.008), (-0.019, 0.006), (-0.012, 0.003)],
    'DR-DMP_MCMU(3,7)': [(-1.97, 0.074), (-0.872, 0.059), (-0.39, 0.045), (-0.181, 0.026), (-0.086, 0.021), (-0.05, 0.016)],
    'DR-DMP_MCMU(3,6)': [(-1.981, 0.053), (-0.929, 0.117), (-0.376, 0.086), (-0.181, 0.06), (-0.084, 0.036), (-0.05, 0.021)],
    'DR-DMP_MCMU(3,5)': [(-1.951, 0.058), (-0.851, 0.075), (-0.32, 0.05), (-0.133, 0.025), (-0.068, 0.019), (-0.045, 0.016)],
    'DR-DMP_MCMU(3,4)': [(-2.165, 0.053), (-1.09, 0.133), (-0.322, 0.107), (-0.142, 0.059), (-0.075, 0.034), (-0.051, 0.022)],
    'DR-DMP_MCMU(3,3)': [(-0.456, 0.014), (-0.244, 0.021), (-0.112, 0.021), (-0.057, 0.011), (-0.03, 0.009), (-0.017, 0.005)],
    'DR-DMP_MCMU(3,2)': [(-0.5, 0.019), (-0.285, 0.025), (-0.134, 0.022), (-0.07, 0.016), (-0.037, 0.009), (-0.022, 0.007)],
    'DR-DMP_MCMU(3,1)': [(-0.492, 0.032), (-0.15, 0.016), (-0.062, 0.015), (-0.028, 0.01), (-0.014, 0.007), (-0.01, 0.005)],
    'IDR-DMP_CMU': [(-1.826, 0.093), (-0.815, 0.089), (-0.3, 0.063), (-0.137, 0.038), (-0.069, 0.024), (-0.047, 0.019)],
    'IDR-DMP_MCMU(3)': [(-1.955, 0.085), (-0.807, 0.127), (-0.24, 0.054), (-0.105, 0.04), (-0.05, 0.015), (-0.033, 0.011)],
    'EM DR-DMP(6)': [(-2.288, 0.021), (-0.884, 0.105), (-0.18, 0.027), (-0.086, 0.012), (-0.051, 0.003), (-0.043, 0.002)],
    'EM DR-DMP(5)': [(-2.274, 0.018), (-0.975, 0.175), (-0.217, 0.034), (-0.094, 0.015), (-0.056, 0.006), (-0.043, 0.002)],
    'EM DR-DMP(4)': [(-2.363, 0.026), (-0.926, 0.144), (-0.194, 0.026), (-0.1, 0.017), (-0.059, 0.006), (-0.044, 0.002)],
    'EM DR-DMP(3)': [(-2.05, 0.027), (-1.075, 0.155), (-0.231, 0.064), (-0.103, 0.018), (-0.063, 0.003), (-0.049, 0.002)],
    'EM DR-DMP(2)': [(-2.271, 0.015), (-1.417, 0.1), (-0.335, 0.049), (-0.203, 0.014), (-0.145, 0.009), (-0.091, 0.007)],
    'EM DR-DMP(1)': [(-1.111, 0.015), (-0.653, 0.072), (-0.283, 0.028), (-0.196, 0.006), (-0.182, 0.001), (-0.177, 0.001)],
}


def curves(path):
    """{algorithm: {run: {update: policy_reward}}} and the latent dimension likewise, in file order."""
    rewards = defaultdict(lambda: defaultdict(dict))
    dims = defaultdict(lambda: defaultdict(dict))
    with open(path) as f:
        for row in csv.DictReader(f):
            rewards[row["algorithm"]][int(row["run"])][int(row["update"])] = float(row["policy_reward"])
            dims[row["algorithm"]][int(row["run"])][int(row["update"])] = int(row["latent_dims"])
    return rewards, dims


def neglog(r):
    return -math.log10(-r) if r < 0 else float("nan")


def series(runs, transform):
    updates = sorted(next(iter(runs.values())).keys())
    means, half = [], []
    for u in updates:
        m, h = mean_ci([transform(run[u]) for run in runs.values() if u in run])
        means.append(m)
        half.append(h)
    return updates, means, half


def plot_panels(directory, experiment, panels, transform, ylabel, title):
    path = os.path.join(directory, experiment + ".csv")
    if not os.path.exists(path):
        return
    rewards, _ = curves(path)
    fig, axes = plt.subplots(1, len(panels), figsize=(5.2 * len(panels), 4.4), squeeze=False)
    for ax, (panel_title, members) in zip(axes[0], panels):
        for algorithm in [a for a in rewards if members(a)]:
            updates, means, half = series(rewards[algorithm], transform)
            line, = ax.plot(updates, means, label="%s (%d)" % (algorithm, len(rewards[algorithm])), lw=1.2)
            ax.fill_between(updates, [m - h for m, h in zip(means, half)], [m + h for m, h in zip(means, half)],
                            alpha=0.15, color=line.get_color())
        ax.set_title(panel_title, fontsize=9)
        ax.set_xlabel("policy update")
        ax.set_ylabel(ylabel)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(os.path.join(directory, experiment + ".png"), dpi=110)
    plt.close(fig)


def read_paths(directory, experiment):
    """{algorithm: {"initial"|"final": rows}} of DIR/<experiment>_paths.csv and the rows of DIR/<experiment>_target.csv,
    or None when either is missing."""
    paths_file = os.path.join(directory, experiment + "_paths.csv")
    target_file = os.path.join(directory, experiment + "_target.csv")
    if not (os.path.exists(paths_file) and os.path.exists(target_file)):
        return None
    paths = defaultdict(lambda: defaultdict(list))
    with open(paths_file) as f:
        reader = csv.reader(f)
        next(reader)
        for row in reader:
            paths[row[0]][row[1]].append([float(v) for v in row[3:]])
    with open(target_file) as f:
        reader = csv.reader(f)
        next(reader)
        target = np.array([[float(v) for v in row] for row in reader])
    return paths, target


def best_algorithm(directory, experiment, paths):
    """The algorithm with the best mean final reward over its runs, among those with paths."""
    rewards, _ = curves(os.path.join(directory, experiment + ".csv"))
    finals = {a: sum(run[max(run)] for run in runs.values()) / len(runs) for a, runs in rewards.items() if a in paths}
    return max(finals, key=finals.get)


def arm(q):
    """Base, joints and tip of the planar arm of unit links at joint angles q (2 x (d + 1))."""
    angles = np.cumsum(q)
    return np.vstack([np.zeros(2), np.cumsum(np.column_stack([np.cos(angles), np.sin(angles)]), axis=0)]).T


def plot_planar10_paths(directory):
    data = read_paths(directory, "planar10")
    if data is None:
        return
    paths, target = data
    algorithm = "IDR-DMP_CMU" if "IDR-DMP_CMU" in paths else best_algorithm(directory, "planar10", paths)
    initial, final = np.array(paths[algorithm]["initial"]), np.array(paths[algorithm]["final"])
    steps = len(initial) - 1
    via_steps = [int(round(t * steps)) for t in target[:, 0]]
    fig, axes = plt.subplots(1, 2, figsize=(11, 5.6))
    ax = axes[0]
    shown = range(0, steps + 1, max(steps // 5, 1))
    for k, i in enumerate(shown):
        links = arm(initial[i])
        ax.plot(links[0], links[1], "-o", color=plt.get_cmap("viridis")(k / max(len(shown) - 1, 1)), ms=2.5, lw=1.2,
                label="t = %.1f s" % (i / steps))
    tips = np.array([arm(q)[:, -1] for q in initial])
    ax.plot(tips[:, 0], tips[:, 1], "r-", lw=1.3, label="tip path")
    ax.set_title("the initial motion (the demonstrations' DMP; cf. Fig. 7.6a)", fontsize=9)
    ax = axes[1]
    for label, rows, colour in (("initial", initial, "m"), ("after learning", final, "b")):
        tips = np.array([arm(q)[:, -1] for q in rows])
        ax.plot(tips[:, 0], tips[:, 1], "-", color=colour, lw=1.4, label="%s tip path" % label)
        for n, i in enumerate(via_steps):
            links = arm(rows[i])
            ax.plot(links[0], links[1], "-", color=colour, lw=0.8, alpha=0.6,
                    label="%s arm at the via-point times" % label if n == 0 else None)
            ax.plot(*tips[i], "o", color=colour, ms=5)
    ax.plot(target[:, 1], target[:, 2], "kx", ms=12, mew=1.5, zorder=1, label="via-points (t = %s s)" % ", ".join(
        "%.1f" % t for t in target[:, 0]))
    ax.set_title("%s, first run: before and after learning (cf. Fig. 7.6c)" % algorithm, fontsize=9)
    for ax in axes:
        ax.set_aspect("equal")
        ax.grid(alpha=0.3)
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
        ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.17), ncol=2)
    fig.tight_layout()
    fig.savefig(os.path.join(directory, "planar10_paths.png"), dpi=110)
    plt.close(fig)


def plot_wam_circle_paths(directory, summary):
    data = read_paths(directory, "wam_circle")
    if data is None:
        return
    paths, circle = data
    algorithm = best_algorithm(directory, "wam_circle", paths)
    centre = circle.mean(axis=0)
    normal = np.linalg.svd(circle - centre)[2][2]
    u = (circle[0] - centre) / np.linalg.norm(circle[0] - centre)
    v = np.cross(normal, u)
    radius = np.linalg.norm(circle - centre, axis=1).mean()

    def in_plane(points):
        return (points - centre) @ u * 1e3, (points - centre) @ v * 1e3

    def distance(points):
        offset = points - centre
        height = offset @ normal
        planar = np.linalg.norm(offset - np.outer(height, normal), axis=1)
        return np.hypot(planar - radius, height) * 1e3

    fig, axes = plt.subplots(1, 2, figsize=(11, 4.8), gridspec_kw={"width_ratios": [1, 1.4]})
    # The circle the reward measured from (dr_benchmark --circle), as its rows record it.
    target = next((r.get("circle", "fitted") for r in summary["results"] if r["experiment"] == "wam_circle"), "fitted")
    label = "the fitted circle" if target == "fitted" else "the circle the demonstration was made from"
    axes[0].plot(*in_plane(np.vstack([circle, circle[:1]])), "g-", lw=2.5, alpha=0.6, label=label)
    # The full-dimension DMP's initial policy is the demonstration's fit; the reduced ones project it first.
    full = "DR-DMP0(7)" if "DR-DMP0(7)" in paths else algorithm
    for label, points, colour in (("the demonstration's DMP (%s before learning)" % full, paths[full]["initial"], "b"),
                                  ("%s after learning" % algorithm, paths[algorithm]["final"], "k")):
        points = np.array(points)
        axes[0].plot(*in_plane(points), "-", color=colour, lw=1.1, label=label)
        t = np.linspace(0.0, 8.0, len(points))
        axes[1].plot(t, distance(points), "-", color=colour, lw=1.1,
                     label="%s: sum %.3f m" % (label, distance(points).sum() * 1e-3))
    axes[0].set_aspect("equal")
    axes[0].set_xlabel("in the circle's plane [mm]")
    axes[0].set_ylabel("[mm]")
    axes[0].set_title("the tool's path, first run (cf. Fig. 7.7a)", fontsize=9)
    axes[1].set_xlabel("time [s]")
    axes[1].set_ylabel("distance from the circle [mm]")
    axes[1].set_yscale("log")
    axes[1].set_title("the reward's distance term (7.51), per sample", fontsize=9)
    for ax in axes:
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(os.path.join(directory, "wam_circle_paths.png"), dpi=110)
    plt.close(fig)


# Rollouts each learner of planar10 and wam_circle spends: 20 per update, 200 and 250 updates.
LEARNER_BUDGET = {"planar10": 20 * 200, "wam_circle": 20 * 250}


def plot_optima_progress(directory):
    path = os.path.join(directory, "optima_progress.csv")
    if not os.path.exists(path):
        return
    progress = defaultdict(lambda: defaultdict(list))
    with open(path) as f:
        for row in csv.DictReader(f):
            progress[row["task"]][row["algorithm"]].append((int(row["rollouts"]), float(row["best_reward"])))
    fig, axes = plt.subplots(1, len(progress), figsize=(6.2 * len(progress), 4.6), squeeze=False)
    for ax, (task, algorithms) in zip(axes[0], progress.items()):
        learned = os.path.join(directory, task + ".csv")
        finals = {}
        if os.path.exists(learned):
            rewards, _ = curves(learned)
            finals = {a: mean_ci([run[max(run)] for run in runs.values()])[0] for a, runs in rewards.items()}
        for algorithm, points in algorithms.items():
            x, y = zip(*points)
            line, = ax.plot(x, [-v for v in y], "--" if "MCMU" in algorithm else "-", lw=1.1, label=algorithm)
            if algorithm in finals:
                ax.plot([LEARNER_BUDGET[task]], [-finals[algorithm]], "o", color=line.get_color(), ms=5)
        ax.axvline(LEARNER_BUDGET[task], color="k", ls=":", lw=1,
                   label="the learners' budget (%d rollouts)%s" % (LEARNER_BUDGET[task],
                                                                   "; dots: where they end" if finals else ""))
        thesis = [-cells[-1][0] if task == "wam_circle" else 10 ** -cells[-1][0]
                  for cells in (THESIS_74 if task == "wam_circle" else THESIS_73).values()]
        ax.axhspan(min(thesis), max(thesis), color="0.5", alpha=0.15, label="the thesis' learners after 200 updates")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("rollouts spent (central-difference gradients)")
        ax.set_ylabel("cost -R of the best iterate")
        ax.set_title("%s: L-BFGS from each constant coordination's initial policy" % task, fontsize=9)
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=6, ncol=2)
    fig.tight_layout()
    fig.savefig(os.path.join(directory, "optima_progress.png"), dpi=110)
    plt.close(fig)


def plot_em_vs_pca(directory):
    path = os.path.join(directory, "em_vs_pca.csv")
    if not os.path.exists(path):
        return None
    cells = defaultdict(list)
    with open(path) as f:
        for row in csv.DictReader(f):
            cells[(int(row["d"]), int(row["r"]))].append(float(row["rho"]))
    ds = sorted({d for d, _ in cells})
    rs = list(range(1, max(ds)))
    grid = [[(sum(cells[(d, r)]) / len(cells[(d, r)])) if (d, r) in cells else float("nan") for r in rs] for d in ds]
    fig, ax = plt.subplots(figsize=(6.5, 3.8))
    image = ax.imshow(grid, cmap="viridis", aspect="auto", origin="lower")
    ax.set_xticks(range(len(rs)))
    ax.set_xticklabels(rs)
    ax.set_yticks(range(len(ds)))
    ax.set_yticklabels(ds)
    ax.set_xlabel("latent dimension r")
    ax.set_ylabel("DoF d")
    for i, row in enumerate(grid):
        for j, v in enumerate(row):
            if not math.isnan(v):
                ax.text(j, i, "%.2f" % v, ha="center", va="center", fontsize=6, color="w" if v < -0.3 else "k")
    fig.colorbar(image, ax=ax, label="rho = (KL_EM - KL_PCA) / KL_PCA")
    ax.set_title("EM vs PCA fits of simulated ProMP data, mean rho (7.21) (cf. Fig. 7.2)", fontsize=9)
    fig.tight_layout()
    fig.savefig(os.path.join(directory, "em_vs_pca.png"), dpi=110)
    plt.close(fig)
    return ds, rs, grid, cells


def read_rows(directory, name):
    path = os.path.join(directory, name)
    if not os.path.exists(path):
        return None
    with open(path) as f:
        return list(csv.DictReader(f))


def plot_nao(directory):
    """nao_walking: Fig. 7.4 (the 13 strides' distribution per joint against the r = 4 fit), Fig. 7.3 (the joints'
    correlations: the model's, the data's over walks and time, the data's within walks) and the fit's error per r."""
    distribution = read_rows(directory, "nao_distribution.csv")
    strides = read_rows(directory, "nao_strides.csv")
    if distribution is None or strides is None:
        return
    joints = list(dict.fromkeys(row["joint"] for row in distribution))
    fig, axes = plt.subplots(2, 6, figsize=(15, 5.2), sharex=True)
    for k, joint in enumerate(joints):
        ax = axes[k // 6][k % 6]
        rows = [r for r in distribution if r["joint"] == joint]
        phase = np.array([float(r["phase"]) for r in rows])
        for walk in sorted({r["walk"] for r in strides}):
            ax.plot([float(r["phase"]) for r in strides if r["walk"] == walk],
                    [float(r[joint]) for r in strides if r["walk"] == walk], color="tab:red", lw=0.4, alpha=0.5)
        for key, colour, label in (("data", "tab:red", "13 walks"), ("fit", "tab:blue", "DR-ProMP, r = 4")):
            mean = np.array([float(r[key + "_mean"]) for r in rows])
            std = np.array([float(r[key + "_std"]) for r in rows])
            ax.fill_between(phase, mean - 2 * std, mean + 2 * std, color=colour, alpha=0.25, lw=0)
            ax.plot(phase, mean, color=colour, lw=1.2, label=label + " (mean, 2 sd)")
        ax.set_title("%d %s" % (k + 1, joint), fontsize=8)
        ax.tick_params(labelsize=7)
        if k % 6 == 0:
            ax.set_ylabel("deg", fontsize=8)
        if k >= 6:
            ax.set_xlabel("normalised time", fontsize=8)
    axes[0][0].legend(fontsize=6, loc="best")
    fig.suptitle("NAO leg joints over one stride: 13 generated walks (red) and their DR-ProMP fit with r = 4 (blue) "
                 "(cf. Fig. 7.4)", fontsize=10)
    fig.tight_layout()
    fig.savefig(os.path.join(directory, "nao_distribution.png"), dpi=110)
    plt.close(fig)

    correlation = read_rows(directory, "nao_correlation.csv")
    if correlation:
        d = max(int(r["i"]) for r in correlation)
        fig, axes = plt.subplots(1, 3, figsize=(16, 5.6), constrained_layout=True)
        for n, (ax, key, title) in enumerate(zip(axes, ("model", "data", "data_within_walks"),
                                  ("the model, r = 4 (over time and walks)", "the data (over time and walks)",
                                   "the data within walks (each walk's mean out)"))):
            m = np.zeros((d, d))
            for r in correlation:
                m[int(r["i"]) - 1][int(r["j"]) - 1] = float(r[key])
            image = ax.imshow(m, cmap="RdBu_r", vmin=-1, vmax=1)
            ax.set_xticks(range(d))
            ax.set_xticklabels(range(1, d + 1), fontsize=7)
            ax.set_yticks(range(d))
            ax.set_yticklabels(["%d %s" % (i + 1, j) for i, j in enumerate(joints)] if n == 0 else range(1, d + 1),
                               fontsize=7)
            for i in range(d):
                for j in range(d):
                    ax.text(j, i, "%.1f" % m[i][j], ha="center", va="center", fontsize=5)
            ax.set_title(title, fontsize=9)
        fig.colorbar(image, ax=axes, shrink=0.8, label="correlation")
        fig.suptitle("NAO leg joints' correlations (cf. Fig. 7.3): 1-6 left, 7-12 right", fontsize=10)
        fig.savefig(os.path.join(directory, "nao_correlation.png"), dpi=110)
        plt.close(fig)

    fit = read_rows(directory, "nao_fit.csv")
    if fit:
        fig, ax = plt.subplots(figsize=(6, 3.6))
        rs = [int(r["r"]) for r in fit]
        ax.semilogy(rs, [float(r["rms_mean_error_deg"]) for r in fit], "o-", label="mean (rms over joints and time)")
        ax.semilogy(rs, [float(r["rms_std_error_deg"]) for r in fit], "s-", label="standard deviation")
        ax.set_xlabel("latent dimension r")
        ax.set_ylabel("fit's error [deg]")
        ax.set_xticks(rs)
        ax.legend(fontsize=8)
        ax.set_title("DR-ProMP of 13 NAO walks: the fit's error per r", fontsize=9)
        fig.tight_layout()
        fig.savefig(os.path.join(directory, "nao_fit.png"), dpi=110)
        plt.close(fig)


def checkpoint_table(rewards, algorithm, transform):
    runs = rewards[algorithm]
    out = []
    for c in CHECKPOINTS:
        values = [transform(run[c]) for run in runs.values() if c in run]
        out.append(mean_ci(values) if values else None)
    return out


def fmt(cell, digits=3):
    if cell is None:
        return "–"
    return "%.*f ± %.*f" % (digits, cell[0], digits, cell[1])


def tables(directory, summary, em):
    rows = summary["results"]
    lines = ["dr_benchmark, seed %d%s\n" % (summary["seed"], " (quick)" if summary["quick"] else "")]
    by = defaultdict(list)
    for r in rows:
        by[r["experiment"]].append(r)
    for r in by.get("estep", []):
        lines += ["### estep\n", "| N_t | d | r | kernels | trajectories | naive E-step (ms) | fast E-step (ms) | "
                  "speedup | max diff. means | max diff. covariance | rel. diff. log-likelihood |",
                  "|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
                  "| %d | %d | %d | %d | %d | %.2f | %.4f | %.0f | %.1e | %.1e | %.1e |" % (
                      r["steps"], r["dofs"], r["latent_dims"], r["kernels"], r["trajectories"], r["naive_ms"],
                      r["fast_ms"], r["speedup"], r["max_difference_means"], r["max_difference_covariance"],
                      r["log_likelihood_relative_difference"]), ""]
    if em is not None:
        ds, rs, grid, cells = em
        lines += ["### em_vs_pca: mean rho (7.21) per (d, r)\n",
                  "| d \\ r | " + " | ".join(str(r) for r in rs) + " |", "|---" * (len(rs) + 1) + "|"]
        for d, row in zip(ds, grid):
            lines.append("| %d | " % d + " | ".join("–" if math.isnan(v) else "%.3f" % v for v in row) + " |")
        for r in by.get("em_vs_pca", []):
            if r["algorithm"] == "rho":
                lines.append("\nFits: %d; mean rho %.3f; rho of the summed KL %.3f (thesis: about -0.20)." % (
                    r["fits"], r["rho_mean"], r["rho_of_sums"]))
        lines.append("")
    path = os.path.join(directory, "planar15.csv")
    if os.path.exists(path):
        rewards, _ = curves(path)
        lines += ["### planar15 (cf. Fig. 7.5): reward of the mean policy\n",
                  "| algorithm | runs | initial | after 10 | after 50 | final |", "|---|---:|---:|---:|---:|---:|"]
        for algorithm, runs in rewards.items():
            last = max(next(iter(runs.values())).keys())
            cells_ = [mean_ci([run[u] for run in runs.values()]) if all(u in run for run in runs.values()) else None
                      for u in (0, 10, 50, last)]
            lines.append("| %s | %d | " % (algorithm, len(runs)) + " | ".join(fmt(c, 2) for c in cells_) + " |")
        lines.append("")
    for experiment, thesis, transform, label in (
            ("planar10", THESIS_73, neglog, "-log10(-R)"), ("wam_circle", THESIS_74, lambda r: r, "R")):
        path = os.path.join(directory, experiment + ".csv")
        if not os.path.exists(path):
            continue
        rewards, dims = curves(path)
        header = " | ".join("%d upd." % c for c in CHECKPOINTS)
        lines += ["### %s: %s, ours (mean ± 95 %% interval) and the thesis' below each\n" % (experiment, label),
                  "| method | runs | final r | " + header + " |", "|---|---:|---:|" + "---:|" * len(CHECKPOINTS)]
        for algorithm in rewards:
            ours = checkpoint_table(rewards, algorithm, transform)
            final_dims = [run[max(run.keys())] for run in dims[algorithm].values()]
            lines.append("| %s | %d | %.1f | " % (algorithm, len(rewards[algorithm]), sum(final_dims) /
                                                 len(final_dims)) + " | ".join(fmt(c) for c in ours) + " |")
            if algorithm in thesis:
                lines.append("| thesis | | | " + " | ".join(fmt(c) for c in thesis[algorithm]) + " |")
        lines.append("")
    optima = [r for r in rows if r["experiment"] == "optima"]
    if optima:
        lines += ["### optima: the noise-free reward L-BFGS reaches from the initial mean weights with each constant "
                  "coordination (PCA initialisation)\n",
                  "Path: the length of the task's path before and after (planar10: the joints', rad; wam_circle: the "
                  "tool's, m). Zero weights: the reward with all latent weights zero, which every coordination "
                  "contains.\n",
                  "| task | coordination | weights | initial R | optimum R | optimum -log10(-R) | path | "
                  "zero weights R | rollouts |",
                  "|---|---|---:|---:|---:|---:|---:|---:|---:|"]
        for r in optima:
            log = "%.3f" % neglog(r["optimum_reward"]) if r["task"] == "planar10" else "–"
            lines.append("| %s | %s | %d | %.4f | %.4f | %s | %.3f → %.3f | %.4f | %d |" % (
                r["task"], r["algorithm"], r["weights"], r["initial_reward"], r["optimum_reward"], log,
                r["initial_path_length"], r["optimum_path_length"], r["zero_weights_reward"], r["rollouts"]))
        lines.append("")
    return "\n".join(lines) + "\n"


def main():
    directory = output_directory(__doc__)
    summary = read_summary(directory)
    plot_panels(directory, "planar15", [("15-DoF planar arm, Cartesian tracking (7.22)", lambda a: True)],
                lambda r: r, "reward of the mean policy", "planar15 (cf. Fig. 7.5), 95 % intervals")
    plot_panels(directory, "planar10",
                [("one coordination matrix", lambda a: a.startswith("DR-DMP_CMU")),
                 ("two coordination matrices", lambda a: a.startswith("DR-DMP_MCMU")),
                 ("iterative reduction (eta = 50)", lambda a: a.startswith("IDR"))],
                neglog, "-log10(-R) of the mean policy", "planar10 (cf. Table 7.3, Fig. 7.6d), 95 % intervals")
    plot_panels(directory, "wam_circle",
                [("fixed Omega", lambda a: a.startswith("DR-DMP0(")),
                 ("CMU", lambda a: a.startswith("DR-DMP_CMU")),
                 ("3 fixed Omega_s", lambda a: a.startswith("DR-DMP0_MCMU")),
                 ("MCMU (3)", lambda a: a.startswith("DR-DMP_MCMU")),
                 ("IDR and EM", lambda a: a.startswith("IDR") or a.startswith("EM"))],
                lambda r: r, "reward of the mean policy", "wam_circle (cf. Table 7.4, Fig. 7.7b), 95 % intervals")
    plot_planar10_paths(directory)
    plot_wam_circle_paths(directory, summary)
    plot_optima_progress(directory)
    em = plot_em_vs_pca(directory)
    plot_nao(directory)
    with open(os.path.join(directory, "tables.md"), "w") as f:
        f.write(tables(directory, summary, em))


if __name__ == "__main__":
    main()

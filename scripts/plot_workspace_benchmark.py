#!/usr/bin/python3
"""Plots of workspace_benchmark, from DIR/summary.json and its CSVs: DIR/map_slices.png (the solution ratio of the
WAM's workspace map in the vertical plane nearest y = 0 and in the horizontal plane with the most reachable voxels,
cf. thesis Fig. 3.7), DIR/fig39.png and DIR/fig310.png (the placement quality F over the grid of offsets, cf. Figs.
3.9 and 3.10), DIR/placement.png (the best quality found against the evaluations spent, mean over runs, by the
genetic algorithm and NLopt's algorithms), and DIR/tables.md. Usage: plot_workspace_benchmark.py DIR"""
import csv
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from plot_common import output_directory, read_summary  # noqa: E402

SETTINGS = {
    "fig39": "second base perpendicular (z along -x) at (dx, 0, dz), cf. thesis Fig. 3.9",
    "fig310": "second base upside down (z axes parallel, facing) at (dx, 0, dz), cf. thesis Fig. 3.10",
}


def read_csv(path):
    with open(path) as f:
        return [{k: float(v) for k, v in r.items()} for r in csv.DictReader(f)]


def plot_map(out, row):
    voxels = read_csv(os.path.join(out, "map.csv"))
    h = row["resolution_m"]
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.6))

    def reachable_in(fixed, plane):
        return sum(1 for v in voxels if abs(v[fixed] - plane) < 1e-9 and v["solved"] > 0)

    for ax, (fixed, a, b, title) in zip(axes, [("y", "x", "z", "vertical plane"),
                                                ("z", "x", "y", "horizontal plane")]):
        planes = sorted({v[fixed] for v in voxels})
        plane = min(planes, key=abs) if fixed == "y" else max(planes, key=lambda c: reachable_in(fixed, c))
        grid_a = sorted({v[a] for v in voxels})
        grid_b = sorted({v[b] for v in voxels})
        image = np.full((len(grid_b), len(grid_a)), np.nan)
        for v in voxels:
            if abs(v[fixed] - plane) < 1e-9:
                image[grid_b.index(v[b]), grid_a.index(v[a])] = v["solution_ratio"]
        shown = ax.imshow(image, origin="lower", cmap="viridis", vmin=0, vmax=1,
                          extent=[grid_a[0] - h / 2, grid_a[-1] + h / 2, grid_b[0] - h / 2, grid_b[-1] + h / 2])
        ax.set_xlabel(a + " [m]")
        ax.set_ylabel(b + " [m]")
        ax.set_title("%s (%s = %.2f m)" % (title, fixed, plane), fontsize=10)
        fig.colorbar(shown, ax=ax, label="orientations solved")
    fig.suptitle("WAM workspace map: %.3f m voxels, %d orientations each (cf. thesis Fig. 3.7)"
                 % (h, row["orientations"]))
    fig.tight_layout()
    fig.savefig(os.path.join(out, "map_slices.png"), dpi=110)
    plt.close(fig)


def plot_placements(out, row):
    name = row["experiment"]
    cells = read_csv(os.path.join(out, name + ".csv"))
    xs = sorted({round(c["dx"], 6) for c in cells})
    zs = sorted({round(c["dz"], 6) for c in cells})
    image = np.full((len(zs), len(xs)), np.nan)
    for c in cells:
        image[zs.index(round(c["dz"], 6)), xs.index(round(c["dx"], 6))] = c["quality"]
    step = row["step_m"]
    fig, ax = plt.subplots(figsize=(6.4, 5.2))
    shown = ax.imshow(image, origin="lower", cmap="jet",
                      extent=[xs[0] - step / 2, xs[-1] + step / 2, zs[0] - step / 2, zs[-1] + step / 2])
    ax.plot([row["best_dx"]], [row["best_dz"]], "w*", markersize=14, markeredgecolor="k", label="best")
    if "best_negative_dx" in row:
        ax.plot([row["best_negative_dx"]], [row["best_negative_dz"]], "wo", markeredgecolor="k",
                label="best with dx, dz < 0")
    ax.set_xlabel("dx [m]")
    ax.set_ylabel("dz [m]")
    ax.legend(loc="lower left", fontsize=8)
    ax.set_title("%s\n%.2f m voxels, %d orientations, L = 0.4 +- 0.1 m" % (SETTINGS.get(name, name),
                 row["resolution_m"], row["orientations"]), fontsize=9)
    fig.colorbar(shown, ax=ax, label="placement quality F (3.41) [m^3]")
    fig.tight_layout()
    fig.savefig(os.path.join(out, name + ".png"), dpi=110)
    plt.close(fig)


def plot_search(out, rows):
    curves = {}
    with open(os.path.join(out, "placement.csv")) as f:
        for r in csv.DictReader(f):
            curves.setdefault(r["method"], {}).setdefault(int(r["run"]), []).append(float(r["best_quality"]))
    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    for method, runs in curves.items():
        length = max(len(c) for c in runs.values())
        padded = np.array([c + [c[-1]] * (length - len(c)) for c in runs.values()])
        ax.plot(np.arange(1, length + 1), padded.mean(axis=0), label="%s (%d runs)" % (method, len(runs)))
    ax.set_xlabel("evaluations of F")
    ax.set_ylabel("best placement quality F so far [m^3] (mean over runs)")
    ax.set_title("Search for the best placement of fig39's setting (dx, dz)", fontsize=10)
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(os.path.join(out, "placement.png"), dpi=110)
    plt.close(fig)


def main():
    out = output_directory(__doc__)
    summary = read_summary(out)
    rows = summary["results"]
    searches = [r for r in rows if r["experiment"] == "placement"]
    with open(os.path.join(out, "tables.md"), "w") as f:
        f.write("# workspace_benchmark (seed %d%s)\n\n" % (summary["seed"], ", quick" if summary["quick"] else ""))
        for row in rows:
            if row["experiment"] == "placement":
                continue
            if row["experiment"] == "map":
                plot_map(out, row)
                f.write("| resolution | orientations | IK restarts | threads | voxels | reachable |"
                        " ruled out by the wrist test | s |\n")
                f.write("|---:|---:|---:|---:|---:|---:|---:|---:|\n")
                f.write("| %.3f m | %d | %d | %d | %d | %d | %.1f %% | %.1f |\n\n" % (
                    row["resolution_m"], row["orientations"], row["ik_attempts"], row["threads"], row["voxels"],
                    row["reachable_voxels"], 100 * row["pruned_fraction"], row["seconds"]))
            elif row["experiment"] == "quality":
                f.write("## quality: one evaluation of F (fig39 at dx = dz = 0.8 m)\n\n")
                f.write("| resolution | reachable voxels | threads | runs | median s | max s | brute force s |"
                        " speed-up | relative difference |\n|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n")
                f.write("| %.3f m | %d | %d | %d | %.3f | %.3f | %.1f | %.0fx | %.1e |\n\n" % (
                    row["resolution_m"], row["reachable_voxels"], row["threads"], row["runs"], row["median_seconds"],
                    row["max_seconds"], row["brute_force_seconds"], row["brute_force_seconds"] / row["median_seconds"],
                    row["relative_difference"]))
            else:
                plot_placements(out, row)
                f.write("## %s: %s\n\n" % (row["experiment"], SETTINGS.get(row["experiment"], "")))
                f.write("| placement | dx [m] | dz [m] | F [m^3] |\n|---|---:|---:|---:|\n")
                f.write("| best | %.2f | %.2f | %.4g |\n" % (row["best_dx"], row["best_dz"], row["quality"]))
                if "best_negative_dx" in row:
                    f.write("| best with dx, dz < 0 (DARPA robot's quadrant) | %.2f | %.2f | %.4g |\n" % (
                        row["best_negative_dx"], row["best_negative_dz"], row["negative_quality"]))
                f.write("| humanoid-like, bases back to back, torso %.1f m | - | - | %.4g |\n\n" % (
                    row["humanoid_width_m"], row["humanoid_quality"]))
                f.write("%d placements, %.3f s per evaluation of F (max %.3f s), %.2f m voxels.\n\n" % (
                    row["evaluations"], row["seconds_per_evaluation"], row["max_seconds_per_evaluation"],
                    row["resolution_m"]))
        if searches:
            plot_search(out, searches)
            f.write("## placement: the search for fig39's best (dx, dz)\n\n")
            f.write("| method | runs | budget | mean best F [m^3] | best F of the runs at dx, dz [m] |"
                    " runs reaching the GA's best | mean evaluations to it | s per run |\n"
                    "|---|---:|---:|---:|---|---:|---:|---:|\n")
            for r in searches:
                f.write("| %s | %d | %d | %.4g | %.4g at %.2f, %.2f | %d | %s | %.1f |\n" % (
                    r["method"], r["runs"], r["budget"], r["mean_quality"], r["best_quality"], r["best_dx"],
                    r["best_dz"],
                    r["runs_reaching_ga_best"],
                    "%.0f" % r["mean_evaluations_to_ga_best"] if r["mean_evaluations_to_ga_best"] > 0 else "-",
                    r["mean_seconds"]))
            f.write("\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())

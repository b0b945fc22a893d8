#!/usr/bin/python3
"""Plots of workspace_benchmark: DIR/map_slices.png (the solution ratio of the WAM's workspace map in the vertical
plane nearest y = 0 and in the horizontal plane with the most reachable voxels, cf. thesis Fig. 3.7) and
DIR/tables.md, from DIR/summary.json and DIR/map.csv. Usage: plot_workspace_benchmark.py DIR"""
import csv
import json
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402


def main():
    if len(sys.argv) != 2 or sys.argv[1] in ("-h", "--help"):
        print(__doc__)
        return 0 if len(sys.argv) == 2 else 2
    out = sys.argv[1]
    with open(os.path.join(out, "summary.json")) as f:
        summary = json.load(f)
    row = summary["results"][0]
    with open(os.path.join(out, "map.csv")) as f:
        voxels = [{k: float(v) for k, v in r.items()} for r in csv.DictReader(f)]
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
    with open(os.path.join(out, "tables.md"), "w") as f:
        f.write("# workspace_benchmark (seed %d%s)\n\n" % (summary["seed"], ", quick" if summary["quick"] else ""))
        f.write("| resolution | orientations | IK restarts | threads | voxels | reachable | ruled out by the wrist test | s |\n")
        f.write("|---:|---:|---:|---:|---:|---:|---:|---:|\n")
        f.write("| %.3f m | %d | %d | %d | %d | %d | %.1f %% | %.1f |\n" % (
            h, row["orientations"], row["ik_attempts"], row["threads"], row["voxels"], row["reachable_voxels"],
            100 * row["pruned_fraction"], row["seconds"]))
    return 0


if __name__ == "__main__":
    sys.exit(main())

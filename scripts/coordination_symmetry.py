#!/usr/bin/env python3
"""The learned fold's coordination by arm (thesis Fig. 7.9d: "the z component of both robots is strongly
correlated"): reads a fold_learner directory's coordination.csv (every run's final coordination matrices) and
initial_coordination.csv (its first policy's: the demonstration's PCA) and writes DIR/coordination_symmetry.md and
DIR/coordination_symmetry.png.

A coordination matrix Omega (12 DMP DoF x r latent) couples DoF i and j through the excitation it lets through,
Omega Omega^T: their coupling is corr_ij = (Omega Omega^T)_ij / sqrt((Omega Omega^T)_ii (Omega Omega^T)_jj). For
each DoF k of the left tool (x, y, z, v1, v2, v3) the mirrored pair is (left k, right k). Per run (averaged over a
learner's matrices) two figures: |corr| of the pair, and its contrast, |corr| of the pair minus the mean |corr| of
left k and right k with the other DoF of the other arm. Two claims, each Holm-corrected over its 6 pairs x the
learners: (1) in the learned matrices the mirrored pairs are coupled more than the other cross-arm pairs (the
contrast, one-sample t, two-sided); (2) learning changed the pairs' coupling (final |corr| - initial, paired t,
two-sided).

Usage: coordination_symmetry.py DIR
"""
import csv
import math
import os
import sys
from collections import defaultdict

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from plot_common import holm, mean_ci  # noqa: E402
from scipy import stats  # noqa: E402

DOF = ["x", "y", "z", "v1", "v2", "v3"]
NAMES = ["L " + d for d in DOF] + ["R " + d for d in DOF]


def read(path):
    """{algorithm: {run: [Omega_s, ...]}}"""
    rows = defaultdict(lambda: defaultdict(lambda: defaultdict(dict)))
    with open(path) as f:
        reader = csv.reader(f)
        next(reader)
        for row in reader:
            rows[row[0]][int(row[1])][int(row[2])][int(row[3])] = [float(v) for v in row[4:]]
    out = defaultdict(dict)
    for algorithm, runs in rows.items():
        for run, matrices in runs.items():
            out[algorithm][run] = [np.array([m[i] for i in sorted(m)]) for _, m in sorted(matrices.items())]
    return out


def correlation(omega):
    g = omega @ omega.T
    d = np.sqrt(np.clip(np.diag(g), 0.0, None))
    with np.errstate(invalid="ignore", divide="ignore"):
        c = g / np.outer(d, d)
    return np.nan_to_num(c)


def per_run(matrices):
    """Mean over a run's matrices of |corr| (12 x 12), the signed corr, and per left DoF the pair's |corr| and
    contrast."""
    a = np.mean([np.abs(correlation(m)) for m in matrices], axis=0)
    signed = np.mean([correlation(m) for m in matrices], axis=0)
    pair, contrast = [], []
    for k in range(6):
        cross = a[k, 6:12]
        other = [cross[j] for j in range(6) if j != k] + [a[j, 6 + k] for j in range(6) if j != k]
        pair.append(cross[k])
        contrast.append(cross[k] - sum(other) / len(other))
    return a, signed, pair, contrast


def main():
    if len(sys.argv) != 2 or sys.argv[1] in ("-h", "--help"):
        print(__doc__)
        sys.exit(0 if len(sys.argv) == 2 else 2)
    directory = sys.argv[1]
    for name in ("coordination.csv", "initial_coordination.csv"):
        if not os.path.exists(os.path.join(directory, name)):
            sys.exit("coordination_symmetry: %s has no %s (a fold_learner output directory)" % (directory, name))
    final, initial = (read(os.path.join(directory, name)) for name in ("coordination.csv", "initial_coordination.csv"))
    learners = [a for a in final if final[a] and any(m.shape[1] < m.shape[0] or not np.allclose(m, np.eye(m.shape[0]))
                                                      for run in final[a].values() for m in run)]
    if not learners:
        sys.exit("coordination_symmetry: no learner with a coordination other than the identity in " + directory)
    results = {}
    for algorithm in learners:
        runs = sorted(final[algorithm])
        f = [per_run(final[algorithm][r]) for r in runs]
        i = [per_run(initial[algorithm][r]) for r in runs if r in initial.get(algorithm, {})]
        results[algorithm] = (f, i)
    tests_contrast, tests_change, rows = [], [], []
    for algorithm, (f, i) in results.items():
        for k in range(6):
            pair = [r[2][k] for r in f]
            contrast = [r[3][k] for r in f]
            signed = [r[1][k, 6 + k] for r in f]
            before = [r[2][k] for r in i]
            tests_contrast.append(stats.ttest_1samp(contrast, 0.0).pvalue if len(contrast) > 1 else 1.0)
            tests_change.append(stats.ttest_rel(pair, before).pvalue if len(before) == len(pair) > 1 else 1.0)
            rows.append((algorithm, DOF[k], len(pair), mean_ci(before) if before else (math.nan, math.nan),
                         mean_ci(pair), sum(signed) / len(signed), mean_ci(contrast)))
    tests_contrast = [1.0 if math.isnan(p) else p for p in tests_contrast]
    tests_change = [1.0 if math.isnan(p) else p for p in tests_change]
    adjusted_contrast, adjusted_change = holm(tests_contrast), holm(tests_change)
    lines = ["### The learned fold's coordination by arm (cf. Fig. 7.9d)\n",
             "| learner | pair (left, right) | runs | first policy: abs corr | learned: abs corr (mean ± 95 % t) | "
             "learned: signed corr | contrast with the other cross-arm pairs (mean ± 95 % t) | contrast: Holm p | "
             "learned - first: Holm p |",
             "|---|---|---:|---:|---:|---:|---:|---:|---:|"]
    for n, (algorithm, dof, count, before, pair, signed, contrast) in enumerate(rows):
        lines.append("| %s | %s | %d | %.3f | %.3f ± %.3f | %+.3f | %+.3f ± %.3f | %.3g | %.3g |" % (
            algorithm, dof, count, before[0], pair[0], pair[1], signed, contrast[0], contrast[1],
            adjusted_contrast[n], adjusted_change[n]))
    lines += ["", "Holm over the %d pairs of each claim. Contrast: the pair's abs corr minus the mean abs corr of its two "
              "DoF with the other DoF of the other arm." % len(rows), ""]
    text = "\n".join(lines) + "\n"
    with open(os.path.join(directory, "coordination_symmetry.md"), "w") as out:
        out.write(text)
    print(text, end="")

    fig, axes = plt.subplots(len(results), 2, figsize=(9, 4.2 * len(results)), squeeze=False)
    for row, (algorithm, (f, i)) in zip(axes, results.items()):
        for ax, data, when in ((row[0], i, "first policy (the demonstration's PCA)"), (row[1], f, "learned")):
            if not data:
                ax.axis("off")
                continue
            mean = np.mean([r[0] for r in data], axis=0)
            image = ax.imshow(mean, cmap="Greys", vmin=0.0, vmax=1.0)
            ax.set_xticks(range(12))
            ax.set_xticklabels(NAMES, rotation=90, fontsize=7)
            ax.set_yticks(range(12))
            ax.set_yticklabels(NAMES, fontsize=7)
            ax.axhline(5.5, color="tab:red", lw=0.8)
            ax.axvline(5.5, color="tab:red", lw=0.8)
            ax.set_title("%s, %s:\nabs corr, mean over %d runs" % (algorithm, when, len(data)), fontsize=9)
            fig.colorbar(image, ax=ax, fraction=0.046)
    fig.suptitle("Coupling of the DMP's DoF through the coordination matrices, by arm (cf. Fig. 7.9d)", fontsize=10)
    fig.tight_layout()
    fig.savefig(os.path.join(directory, "coordination_symmetry.png"), dpi=100)
    plt.close(fig)


if __name__ == "__main__":
    main()

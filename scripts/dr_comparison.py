#!/usr/bin/env python3
"""Does dimensionality reduction help the fold? Reads the fold_learner directories of config/fold_dr_comparison.yaml
run under four settings (the policy's weights only or weights and goals, REPS with the thesis' update lambda = 0 or
the covariance memory 0.8) and writes OUT/dr_comparison.md and OUT/dr_comparison.png: per setting and algorithm the
noise-free policy's q and reward R after 5 updates and after the last (mean and 95 % Student-t interval over the
runs; q's median and stalls: runs ending below q 0.7), and the rollouts until it first reaches q >= 0.8 (median
over the runs, one that never did ranked last); and, per lambda, each IDR variant against the standard DMP in both
policies, at update 5 and at the end (Welch, two-sided), Holm-corrected over the tests of that lambda, on q (what a
user gets) and on R (what the thesis plots) apart: "does DR help when the update collapses (lambda = 0) / when it
does not (lambda = 0.8)".

Usage: dr_comparison.py OUT weights,0=DIR goals,0=DIR weights,0.8=DIR goals,0.8=DIR
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

STANDARD = "DR-DMP0(12)"
EARLY = 5
Q_TARGET = 0.8
STALL = 0.7
ROLLOUTS_PER_EPOCH = 12


def read(directory, column):
    """algorithm -> run -> epoch -> the noise-free policy's `column` (policy_fold_quality or policy_reward), of the
    DR-DMP learners."""
    q = defaultdict(lambda: defaultdict(dict))
    with open(os.path.join(directory, "epochs.csv")) as f:
        for row in csv.DictReader(f):
            if not row["algorithm"].startswith(("DR-", "IDR-")):
                continue  # Table 7.5's peers, in its directory
            q[row["algorithm"]][int(row["run"])][int(row["epoch"])] = float(row[column])
    return q


def rollouts_to_target(epochs):
    """Exploring rollouts drawn before the noise-free policy first reached q >= 0.8 (None: never)."""
    for epoch in sorted(epochs):
        if epochs[epoch] >= Q_TARGET:
            return epoch * ROLLOUTS_PER_EPOCH
    return None


def main():
    if len(sys.argv) < 3 or sys.argv[1] in ("-h", "--help"):
        print(__doc__)
        return 0 if len(sys.argv) > 1 else 2
    out = sys.argv[1]
    settings = []
    for arg in sys.argv[2:]:
        label, directory = arg.split("=", 1)
        policy, memory = label.split(",")
        settings.append((policy, memory, read(directory, "policy_fold_quality"), read(directory, "policy_reward")))
    lines = ["| policy | λ | algorithm | runs | q after 5 updates | q after 15 | median | stalls (q < 0.7) | "
             "rollouts to q ≥ 0.8, median | R after 5 | R after 15 |",
             "|---|---:|---|---:|---:|---:|---:|---:|---|---:|---:|"]
    finals = {}
    for policy, memory, q, reward in settings:
        for algorithm in sorted(q, key=lambda a: (a != STANDARD, a)):
            runs = q[algorithm]
            last = max(max(e) for e in runs.values())
            early = [runs[r][EARLY] for r in sorted(runs)]
            final = [runs[r][last] for r in sorted(runs)]
            needed = [rollouts_to_target(runs[r]) for r in sorted(runs)]
            reached = [n for n in needed if n is not None]
            r_early = [reward[algorithm][r][EARLY] for r in sorted(runs)]
            r_final = [reward[algorithm][r][last] for r in sorted(runs)]
            finals[(policy, memory, algorithm)] = {"q": (early, final), "R": (r_early, r_final)}
            m5, h5 = mean_ci(early)
            m, h = mean_ci(final)
            rm5, rh5 = mean_ci(r_early)
            rm, rh = mean_ci(r_final)
            # As plot_fold_learning's Table 7.5: the median over every run, one that never reached it ranked last.
            median = np.median([n if n is not None else math.inf for n in needed])
            to = f"{'never' if math.isinf(median) else int(median)} ({len(reached)}/{len(needed)} reached)"
            lines.append(f"| {policy} | {memory} | {algorithm} | {len(final)} | {m5:.3f} ± {h5:.3f} | "
                         f"**{m:.3f} ± {h:.3f}** | {np.median(final):.3f} | {sum(v < STALL for v in final)} | {to} | "
                         f"{rm5:.3f} ± {rh5:.3f} | {rm:.3f} ± {rh:.3f} |")
    for metric, name in (("q", "the noise-free policy's q (what a user gets)"),
                         ("R", "the noise-free policy's reward R (what the thesis plots)")):
        lines += ["", f"Each IDR variant against the standard DMP on {name}: difference of the means, Welch two-sided, "
                  "Holm-corrected over the tests of each λ:", "",
                  "| λ | policy | algorithm | after 5: difference | p | Holm | after 15: difference | p | Holm |",
                  "|---:|---|---|---:|---:|---:|---:|---:|---:|"]
        for memory in sorted({s[1] for s in settings}):
            tests = []
            for policy in sorted({s[0] for s in settings if s[1] == memory}):
                others = sorted(a for (p, m, a) in finals if p == policy and m == memory and a != STANDARD)
                base_early, base_final = finals[(policy, memory, STANDARD)][metric]
                for algorithm in others:
                    early, final = finals[(policy, memory, algorithm)][metric]
                    d5 = np.mean(early) - np.mean(base_early)
                    d = np.mean(final) - np.mean(base_final)
                    p5 = stats.ttest_ind(early, base_early, equal_var=False).pvalue
                    p = stats.ttest_ind(final, base_final, equal_var=False).pvalue
                    tests.append((policy, algorithm, d5, p5, d, p))
            adjusted = holm([t[3] for t in tests] + [t[5] for t in tests])
            n = len(tests)
            for k, (policy, algorithm, d5, p5, d, p) in enumerate(tests):
                lines.append(f"| {memory} | {policy} | {algorithm} | {d5:+.3f} | {p5:.3g} | {adjusted[k]:.3g} | "
                             f"{d:+.3f} | {p:.3g} | {adjusted[n + k]:.3g} |")
    with open(os.path.join(out, "dr_comparison.md"), "w") as f:
        f.write("\n".join(lines) + "\n")
    print("\n".join(lines))

    fig, axes = plt.subplots(1, len(settings), figsize=(4 * len(settings), 3.4), sharey=True)
    for ax, (policy, memory, q, _) in zip(np.atleast_1d(axes), settings):
        for algorithm in sorted(q, key=lambda a: (a != STANDARD, a)):
            runs = q[algorithm]
            epochs = sorted(next(iter(runs.values())))
            values = np.array([[runs[r][e] for e in epochs] for r in sorted(runs)])
            mean = values.mean(axis=0)
            half = np.array([mean_ci(list(values[:, k]))[1] for k in range(len(epochs))])
            ax.plot(epochs, mean, label=algorithm)
            ax.fill_between(epochs, mean - half, mean + half, alpha=0.2)
        ax.axhline(Q_TARGET, color="grey", linestyle="--", linewidth=0.8)
        ax.set_title(f"{policy}, λ = {memory}")
        ax.set_xlabel("update")
    np.atleast_1d(axes)[0].set_ylabel("noise-free policy's q")
    np.atleast_1d(axes)[0].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(os.path.join(out, "dr_comparison.png"), dpi=110)
    print(f"dr_comparison: wrote {out}/dr_comparison.md and dr_comparison.png")
    return 0


if __name__ == "__main__":
    sys.exit(main())

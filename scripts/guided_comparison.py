#!/usr/bin/env python3
"""Human guidance against REPS and DREPS on the simulated WAM's bottle task (thesis Fig. 6.13): does a policy learnt
from 20 guided runs pass the bottles (satisfactory: crossing between them, none down) more often than REPS' or
DREPS' final policy after 20 updates of 50 rollouts? Fisher's exact test on the satisfactory counts (two-sided),
Holm over the two comparisons; with a wam_bottles directory also Welch on the final rewards, in the same Holm family.

The guided side is a `ps_benchmark --experiment wam_guided` directory; the other side either a `ps_benchmark
--experiment wam_bottles` directory (--against DIR) or the counts it measured (--counts REPS=1/20,DREPS=5/20, as
docs/RESULTS.md gives them). Writes GUIDED_DIR/guided_comparison.md and prints it.

Usage: guided_comparison.py GUIDED_DIR (--against WAM_BOTTLES_DIR | --counts NAME=K/N,...)
"""
import argparse
import csv
import json
import math
import os
import sys
from collections import defaultdict

from plot_common import holm, mean_ci
from scipy import stats


def guided(directory):
    with open(os.path.join(directory, "summary.json")) as f:
        summary = json.load(f)
    rows = [r for r in summary["results"] if r["experiment"] == "wam_guided"]
    if not rows:
        sys.exit("guided_comparison: %s/summary.json has no wam_guided result" % directory)
    rewards = {}
    with open(os.path.join(directory, "wam_guided_paths.csv")) as f:
        for row in csv.DictReader(f):
            rewards[int(row["run"])] = float(row["reward"])
    return summary["seed"], rows[0], [rewards[k] for k in sorted(rewards)]


def against_directory(directory):
    with open(os.path.join(directory, "summary.json")) as f:
        summary = json.load(f)
    finals = defaultdict(dict)
    with open(os.path.join(directory, "wam_bottles.csv")) as f:
        for row in csv.DictReader(f):
            run, update = int(row["run"]), int(row["update"])
            if update >= finals[row["algorithm"]].get(run, (-1, 0.0))[0]:
                finals[row["algorithm"]][run] = (update, float(row["policy_reward"]))
    out = []
    for r in summary["results"]:
        if r["experiment"] == "wam_bottles":
            values = [v for _, v in finals[r["algorithm"]].values()]
            out.append((r["algorithm"], int(r["satisfactory_runs"]), int(r["runs"]), values))
    if not out:
        sys.exit("guided_comparison: %s/summary.json has no wam_bottles result" % directory)
    return "ps_benchmark --experiment wam_bottles --seed %d" % summary["seed"], out


def against_counts(text):
    out = []
    for item in text.split(","):
        try:
            name, fraction = item.split("=")
            k, n = (int(x) for x in fraction.split("/"))
        except ValueError:
            sys.exit("guided_comparison: --counts takes NAME=K/N,..., not '%s'" % item)
        if not 0 <= k <= n or n < 1:
            sys.exit("guided_comparison: %s: %d of %d is not a count" % (name, k, n))
        out.append((name, k, n, None))
    return "the counts given", out


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("guided_dir", help="a ps_benchmark --experiment wam_guided output directory")
    source = parser.add_mutually_exclusive_group(required=True)
    source.add_argument("--against", metavar="DIR", help="a ps_benchmark --experiment wam_bottles output directory")
    source.add_argument("--counts", metavar="NAME=K/N,...", help="satisfactory runs of the others, e.g. REPS=1/20")
    args = parser.parse_args()
    seed, g, g_rewards = guided(args.guided_dir)
    where, others = against_directory(args.against) if args.against else against_counts(args.counts)
    gk, gn = int(g["satisfactory_runs"]), int(g["runs"])
    m, h = mean_ci(g_rewards)
    lines = ["### Human guidance against REPS and DREPS (cf. Fig. 6.13)\n",
             "Guided: `ps_benchmark --experiment wam_guided --seed %d` (%d sets of %d guided runs); the others: %s.\n"
             % (seed, gn, int(g["rollouts_per_update"]), where),
             "| policy | satisfactory | final reward (mean ± 95 % t) |", "|---|---:|---:|",
             "| Guided (%d guided runs each) | %d of %d | %.3f ± %.3f |" % (int(g["rollouts_per_update"]), gk, gn, m, h)]
    tests = []
    for name, k, n, rewards in others:
        reward = "%.3f ± %.3f" % mean_ci(rewards) if rewards else "–"
        lines.append("| %s | %d of %d | %s |" % (name, k, n, reward))
        tests.append(("%s: satisfactory %+d" % (name, gk - k), stats.fisher_exact([[gk, gn - gk], [k, n - k]]).pvalue,
                      "Fisher"))
        if rewards:
            welch = stats.ttest_ind(g_rewards, rewards, equal_var=False).pvalue
            tests.append(("%s: final reward %+.3f" % (name, m - sum(rewards) / len(rewards)),
                          1.0 if math.isnan(welch) else welch, "Welch"))
    adjusted = holm([p for _, p, _ in tests])
    lines += ["", "Guided against each (two-sided; Holm over the %d tests):" % len(tests), ""]
    for (what, p, test), a in zip(tests, adjusted):
        lines.append("- %s: %s p %.3g, Holm p %.3g%s" % (what, test, p, a, " (significant at 0.05)" if a < 0.05 else ""))
    text = "\n".join(lines) + "\n"
    with open(os.path.join(args.guided_dir, "guided_comparison.md"), "w") as f:
        f.write(text)
    print(text, end="")


if __name__ == "__main__":
    main()

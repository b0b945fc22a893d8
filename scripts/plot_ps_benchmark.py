#!/usr/bin/env python3
"""Learning curves and markdown tables for ps_benchmark output: reads DIR/*.csv and DIR/summary.json, writes
DIR/<experiment>.png (reward of the mean policy per update, mean ± 2 std over runs, per algorithm) and DIR/tables.md
(measured figures next to the thesis' Sec. 6.1.3 numbers; for DREPS at scale, the final rewards' t-intervals and
DREPS against REPS per dimension, Welch on the final reward and Fisher's exact test on the runs reaching the
threshold, Holm over the six).

For wam_guided: DIR/wam_guided_alignment.png (Fig. 6.9 for the first set: the guided runs in their own time with
the take and the release, their aligned parts, the reward-weighted average) and DIR/wam_guided_paths.png (every
set's learned policy as the arm ran it); scripts/guided_comparison.py sets them against REPS and DREPS.

Usage: plot_ps_benchmark.py DIR
"""
import csv
import math
import os
from collections import defaultdict

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from plot_common import holm, mean_ci, output_directory, read_summary, t975  # noqa: E402
from scipy import stats  # noqa: E402

TITLES = {
    "multimodal2d": "Multimodal 2-D reward (6.16), 100 rollouts/update (cf. Fig. 6.7)",
    "multimodal20": "Reward (6.16) in 20 dimensions, 100 rollouts/update (Appendix B.5)",
    "multimodal50": "Reward (6.16) in 50 dimensions, 100 rollouts/update (Appendix B.5)",
    "multimodal100": "Reward (6.16) in 100 dimensions, 100 rollouts/update (Appendix B.5)",
    "bottles617": "Bottle avoidance, reward (6.17), 50 rollouts/update (cf. Fig. 6.10)",
    "bottles": "Bottle avoidance, reward (6.18), 50 rollouts/update (cf. Fig. 6.12)",
    "wam_bottles617": "Bottles on the simulated WAM, reward (6.17) (cf. Fig. 6.10)",
    "wam_bottles": "Bottles on the simulated WAM, reward (6.18) (cf. Fig. 6.12)",
    "wam_guided": "Bottles on the simulated WAM from 20 human-guided runs (cf. Fig. 6.13)",
    "circle": "Circle with a 7-DoF WAM DMP, 50 rollouts/update (cf. Fig. 6.14)",
    "pi2viapoint": "1-D DMP via-point task, 10 rollouts/update",
}
SCALE = ("multimodal20", "multimodal50", "multimodal100")
# Thesis Sec. 6.1.3, bottle task with (6.18): satisfactory runs of 50 and mean reward of the others.
THESIS_BOTTLES = {"REPS": (35, -4.12), "DREPS": (47, -2.80)}


def curves(path):
    by = defaultdict(lambda: defaultdict(dict))
    with open(path) as f:
        for row in csv.DictReader(f):
            by[row["algorithm"]][int(row["run"])][int(row["update"])] = float(row["policy_reward"])
    return by


def plot(directory, experiment):
    path = os.path.join(directory, experiment + ".csv")
    if not os.path.exists(path):
        return
    fig, ax = plt.subplots(figsize=(7, 4.2))
    for algorithm, runs in curves(path).items():
        updates = sorted(next(iter(runs.values())).keys())
        mean, std = [], []
        for u in updates:
            values = [run[u] for run in runs.values() if u in run]
            m = sum(values) / len(values)
            mean.append(m)
            std.append(math.sqrt(sum((v - m) ** 2 for v in values) / len(values)))
        ax.plot(updates, mean, label="%s (%d runs)" % (algorithm, len(runs)))
        ax.fill_between(updates, [m - 2 * s for m, s in zip(mean, std)], [m + 2 * s for m, s in zip(mean, std)],
                        alpha=0.2)
    ax.set_xlabel("policy update")
    ax.set_ylabel("reward of the mean policy")
    ax.set_title(TITLES.get(experiment, experiment), fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(os.path.join(directory, experiment + ".png"), dpi=110)
    plt.close(fig)


def scale_table(directory, by):
    """DREPS at scale: per dimension and algorithm the final reward's t-interval and the runs reaching the threshold;
    DREPS against REPS per dimension (Welch on the final reward, Fisher's exact test on the runs reaching it), Holm
    over the six tests."""
    rows = [r for e in SCALE for r in by.get(e, [])]
    if not rows:
        return []
    lines = ["### multimodal_scale\n", "| dimension | algorithm | runs | runs reaching threshold | mean updates to "
             "threshold | runs ending at an optimum | final distance to the nearest optimum | final exploration "
             "(√(tr Σ / d)) | final reward (mean ± 95 % t) |", "|---:|---|---:|---:|---:|---:|---:|---:|---:|"]
    finals, tests = {}, []
    for r in rows:
        runs = curves(os.path.join(directory, r["experiment"] + ".csv"))[r["algorithm"]]
        values = [run[max(run)] for run in runs.values()]
        finals[(r["experiment"], r["algorithm"])] = (values, r)
        m, h = mean_ci(values)
        lines.append("| %d | %s | %d | %d | %.1f | %d | %.3f | %.4f | %.3f ± %.3f |" % (
            r["dimension"], r["algorithm"], r["runs"], r["runs_reaching_threshold"], r["mean_updates_to_threshold"],
            r["runs_ending_at_an_optimum"], r["mean_final_distance_to_nearest_optimum"], r["mean_final_stddev"], m,
            h))
    for e in SCALE:
        if (e, "REPS") not in finals or (e, "DREPS") not in finals:
            continue
        (reps, rr), (dreps, dr) = finals[(e, "REPS")], finals[(e, "DREPS")]
        welch = stats.ttest_ind(dreps, reps, equal_var=False).pvalue if len(reps) > 1 and len(dreps) > 1 else 1.0
        welch = 1.0 if math.isnan(welch) else welch
        table = [[dr["runs_reaching_threshold"], dr["runs"] - dr["runs_reaching_threshold"]],
                 [rr["runs_reaching_threshold"], rr["runs"] - rr["runs_reaching_threshold"]]]
        fisher = stats.fisher_exact(table).pvalue
        tests.append((dr["dimension"], sum(dreps) / len(dreps) - sum(reps) / len(reps), welch,
                      dr["runs_reaching_threshold"] - rr["runs_reaching_threshold"], fisher))
    adjusted = holm([t[2] for t in tests] + [t[4] for t in tests])
    lines += ["", "DREPS against REPS (two-sided; Holm over the %d tests):\n" % (2 * len(tests)),
              "| dimension | final reward: difference, p, Holm p | runs reaching threshold: difference, Fisher p, "
              "Holm p |", "|---:|---:|---:|"]
    for i, (dimension, difference, welch, reached, fisher) in enumerate(tests):
        lines.append("| %d | %+.3f, %.3g, %.3g | %+d, %.3g, %.3g |" % (
            dimension, difference, welch, adjusted[i], reached, fisher, adjusted[len(tests) + i]))
    return lines + [""]


def wam_paths(directory, experiment, rows):
    """Fig. 6.11 on the WAM: every run's final mean policy as the arm ran it, coloured by what it did (blue: between
    the bottles, none down; magenta: crossing, one down; orange: crossing, both down; red: not crossing), the
    bottles drawn to scale where they stood."""
    path = os.path.join(directory, experiment + "_paths.csv")
    if not os.path.exists(path) or not rows:
        return
    runs = defaultdict(lambda: {"along": [], "left": []})
    kinds = {}
    with open(path) as f:
        for row in csv.DictReader(f):
            key = (row["algorithm"], int(row["run"]))
            runs[key]["along"].append(float(row["along"]))
            runs[key]["left"].append(float(row["left"]))
            kinds[key] = ("failed" if row["outcome"] != "Ok" else "not crossing" if row["crossed"] != "1" else
                          {"0": "none down", "1": "one down"}.get(row["bottles_down"], "both down"))
    algorithms = [r["algorithm"] for r in rows]
    fig, axes = plt.subplots(len(algorithms), 1, figsize=(7, 2.9 * len(algorithms)), squeeze=False)
    for ax, r in zip(axes[:, 0], rows):
        for b in (1, 2):
            ax.add_patch(plt.Circle((r["bottle_%d_along" % b], r["bottle_%d_left" % b]), r["bottle_radius"],
                                    color="black"))
        counts = defaultdict(int)
        colours = {"none down": "tab:blue", "one down": "m", "both down": "tab:orange", "not crossing": "tab:red",
                   "failed": "0.5"}
        for (algorithm, run), p in sorted(runs.items()):
            if algorithm != r["algorithm"]:
                continue
            kind = kinds[(algorithm, run)]
            counts[kind] += 1
            ax.plot(p["along"], p["left"], color=colours[kind], lw=1, alpha=0.8)
        ax.plot([0, r["line_length"]], [0, 0], "k--", lw=0.6)
        ax.set_aspect("equal")
        ax.set_ylim(-0.25, 0.25)
        ax.set_xlabel("along the line [m]")
        ax.set_ylabel("to its left [m]")
        ax.set_title("%s, %d %s: %s" % (r["algorithm"], r["runs"], "sets" if experiment == "wam_guided" else "runs", ", ".join(
            "%d %s (%s)" % (counts[k], k, colours[k].replace("tab:", "")) for k in colours if counts[k])), fontsize=9)
        ax.grid(alpha=0.3)
    fig.suptitle(("Each set's learned policy on the simulated WAM (cf. Fig. 6.13), " if experiment == "wam_guided" else
                  "Final mean policies on the simulated WAM (cf. Fig. 6.11), ") + experiment, fontsize=10)
    fig.tight_layout()
    fig.savefig(os.path.join(directory, experiment + "_paths.png"), dpi=110)
    plt.close(fig)


def guided_alignment(directory, set_index=0):
    """Fig. 6.9 for one set of guided runs: the measured tool's offset from the line against time, each run in its own
    time with the take and the release in red (top); the three parts aligned by gradient descent, in green, on a
    common phase (middle); the reward-weighted average against its time, and its weights' spread (bottom)."""
    runs_path = os.path.join(directory, "wam_guided_runs.csv")
    aligned_path = os.path.join(directory, "wam_guided_aligned.csv")
    if not (os.path.exists(runs_path) and os.path.exists(aligned_path)):
        return
    runs = defaultdict(lambda: {"time": [], "left": [], "part": []})
    with open(runs_path) as f:
        for row in csv.DictReader(f):
            if int(row["set"]) != set_index or row["outcome"] != "Ok":
                continue
            r = runs[int(row["run"])]
            r["time"].append(float(row["time"]))
            r["left"].append(float(row["left"]))
            r["part"].append(int(row["part"]))
    aligned = defaultdict(lambda: defaultdict(list))
    weights, average = {}, {"time": [], "left": []}
    with open(aligned_path) as f:
        for row in csv.DictReader(f):
            if int(row["set"]) != set_index:
                continue
            if int(row["part"]) < 0:
                average["time"].append(float(row["time"]))
                average["left"].append(float(row["left"]))
            else:
                aligned[int(row["run"])][int(row["part"])].append(float(row["left"]))
                weights[int(row["run"])] = float(row["weight"])
    if not runs:
        return
    fig, axes = plt.subplots(3, 1, figsize=(7, 7.5))
    for run, r in sorted(runs.items()):
        axes[0].plot(r["time"], r["left"], color="tab:blue", lw=0.8, alpha=0.7)
        for part in (1, 2):
            i = r["part"].index(part)
            axes[0].plot(r["time"][i], r["left"][i], "o", color="tab:red", ms=3)
    axes[0].set_title("set %d: %d guided runs, measured tool (take and release in red)" % (set_index, len(runs)),
                      fontsize=9)
    for run, parts in sorted(aligned.items()):
        phase, left = [], []
        for part in sorted(parts):
            n = len(parts[part])
            phase += [part + i / (n - 1) for i in range(n)]
            left += parts[part]
        axes[1].plot(phase, left, color="tab:green", lw=0.6 + 6 * weights[run], alpha=0.7)
    axes[1].set_xlabel("aligned phase (0-1 before the take, 1-2 guided, 2-3 after the release)")
    axes[1].set_title("aligned by gradient descent (line width: the run's weight)", fontsize=9)
    axes[2].plot(average["time"], average["left"], "k", lw=2)
    axes[2].set_title("reward-weighted average (h = 10; largest weight %.2f)" % max(weights.values()), fontsize=9)
    for ax in axes:
        ax.set_ylabel("to the line's left [m]")
        ax.grid(alpha=0.3)
    axes[0].set_xlabel("time from the motion's start [s]")
    axes[2].set_xlabel("time [s]")
    fig.suptitle("Time alignment of guided runs on the simulated WAM (cf. Fig. 6.9)", fontsize=10)
    fig.tight_layout()
    fig.savefig(os.path.join(directory, "wam_guided_alignment.png"), dpi=110)
    plt.close(fig)


def guided_table(rows):
    """Human-guided learning: the learned policies (one per set of guided runs) and the guided runs themselves."""
    lines = []
    for r in rows:
        finals_mean, finals_std = r["final_reward_mean"], r["final_reward_std"]
        h = t975(r["runs"] - 1) * finals_std / math.sqrt(r["runs"]) if r["runs"] > 1 else float("nan")
        lines += ["### wam_guided\n",
                  "| sets × guided runs | learned policies satisfactory | mean reward of the others | learned policy "
                  "reward (mean ± 95 % t) | guided runs satisfactory | guided runs' mean reward | alignment: spread "
                  "of the guided parts before → after | s per set |",
                  "|---|---:|---:|---:|---:|---:|---:|---:|",
                  "| %d × %d | %d of %d | %.2f | %.3f ± %.3f | %d of %d | %.3f | %.2e → %.2e | %.1f |" % (
                      r["runs"], r["rollouts_per_update"], r["satisfactory_runs"], r["runs"],
                      r["mean_unsatisfactory_reward"], finals_mean, h, r["guided_runs_satisfactory"],
                      r["guided_runs_ran"], r["guided_mean_reward"], r["guided_alignment_cost_before"],
                      r["guided_alignment_cost_after"], r["seconds_per_update"]), ""]
    return lines


def wam_table(directory, experiment, rows):
    """The WAM bottle task: per algorithm the satisfactory runs (6.18) or the runs knocking none (6.17), the final
    reward's t-interval; DREPS against REPS by Fisher's exact test on the counts and Welch on the final reward, Holm
    over the two."""
    if not rows:
        return []
    count = "satisfactory_runs" if experiment == "wam_bottles" else "runs_knocking_no_bottle"
    lines = ["### %s\n" % experiment,
             "| algorithm | runs × updates × rollouts | %s | %s | failed rollouts | final reward (mean ± 95 %% t) | "
             "s per update |" % (count.replace("_", " "), "mean reward of the others" if experiment == "wam_bottles"
                                 else "mean updates until the mean policy knocks none"),
             "|---|---:|---:|---:|---:|---:|---:|"]
    finals = {}
    for r in rows:
        runs = curves(os.path.join(directory, experiment + ".csv"))[r["algorithm"]]
        finals[r["algorithm"]] = ([run[max(run)] for run in runs.values()], r)
        m, h = mean_ci(finals[r["algorithm"]][0])
        other = r["mean_unsatisfactory_reward"] if experiment == "wam_bottles" else r["mean_updates_to_knock_no_bottle"]
        lines.append("| %s | %d × %d × %d | %d | %.2f | %.1f %% | %.3f ± %.3f | %.2f |" % (
            r["algorithm"], r["runs"], r["updates"], r["rollouts_per_update"], r[count], other,
            100 * r["failed_rollout_share"], m, h, r["seconds_per_update"]))
    if "REPS" in finals and "DREPS" in finals:
        (reps, rr), (dreps, dr) = finals["REPS"], finals["DREPS"]
        welch = stats.ttest_ind(dreps, reps, equal_var=False).pvalue if len(reps) > 1 and len(dreps) > 1 else 1.0
        welch = 1.0 if math.isnan(welch) else welch
        fisher = stats.fisher_exact([[dr[count], dr["runs"] - dr[count]], [rr[count], rr["runs"] - rr[count]]]).pvalue
        adjusted = holm([fisher, welch])
        lines += ["", "DREPS against REPS (two-sided; Holm over the 2 tests): %s %+d, Fisher p %.3g, Holm p %.3g; "
                  "final reward %+.3f, Welch p %.3g, Holm p %.3g" % (
                      count.replace("_", " "), dr[count] - rr[count], fisher, adjusted[0],
                      sum(dreps) / len(dreps) - sum(reps) / len(reps), welch, adjusted[1])]
    return lines + [""]


def tables(summary, directory):
    rows = summary["results"]
    lines = ["ps_benchmark, seed %d%s\n" % (summary["seed"], " (quick)" if summary["quick"] else "")]
    by = defaultdict(list)
    for r in rows:
        by[r["experiment"]].append(r)
    if "multimodal2d" in by:
        lines += ["### multimodal2d\n", "| algorithm | runs | plateau runs | runs reaching threshold | mean updates to "
                  "threshold | final reward (mean ± std) |", "|---|---:|---:|---:|---:|---:|"]
        for r in by["multimodal2d"]:
            lines.append("| %s | %d | %d | %d | %.1f | %.3f ± %.3f |" % (
                r["algorithm"], r["runs"], r["plateau_runs"], r["runs_reaching_threshold"],
                r["mean_updates_to_threshold"], r["final_reward_mean"], r["final_reward_std"]))
        lines.append("")
    lines += scale_table(directory, by)
    if "bottles617" in by:
        lines += ["### bottles617\n", "| algorithm | runs | runs knocking no bottle | mean updates until the mean "
                  "policy knocks none | final reward (mean ± std) |", "|---|---:|---:|---:|---:|"]
        for r in by["bottles617"]:
            lines.append("| %s | %d | %d | %.1f | %.3f ± %.3f |" % (
                r["algorithm"], r["runs"], r["runs_knocking_no_bottle"], r["mean_updates_to_knock_no_bottle"],
                r["final_reward_mean"], r["final_reward_std"]))
        lines.append("")
    if "bottles" in by:
        lines += ["### bottles\n", "| algorithm | runs | satisfactory runs | mean reward of the others | thesis "
                  "(of 50) | thesis mean of the others | s per update |", "|---|---:|---:|---:|---:|---:|---:|"]
        for r in by["bottles"]:
            thesis = THESIS_BOTTLES.get(r["algorithm"], (None, None))
            lines.append("| %s | %d | %d | %.2f | %s | %s | %.4f |" % (
                r["algorithm"], r["runs"], r["satisfactory_runs"], r["mean_unsatisfactory_reward"],
                thesis[0] if thesis[0] is not None else "–", thesis[1] if thesis[1] is not None else "–",
                r["seconds_per_update"]))
        lines.append("")
    for experiment in ("wam_bottles617", "wam_bottles"):
        lines += wam_table(directory, experiment, by.get(experiment, []))
    lines += guided_table(by.get("wam_guided", []))
    for experiment, extra in (("circle", "initial_reward"), ("pi2viapoint", "mean_final_via_point_error")):
        if experiment in by:
            lines += ["### %s\n" % experiment, "| algorithm | runs | updates | final reward (mean ± std) | %s |"
                      % extra.replace("_", " "), "|---|---:|---:|---:|---:|"]
            for r in by[experiment]:
                lines.append("| %s | %d | %d | %.4g ± %.3g | %.4g |" % (
                    r["algorithm"], r["runs"], r["updates"], r["final_reward_mean"], r["final_reward_std"],
                    r[extra]))
            lines.append("")
    return "\n".join(lines) + "\n"


def main():
    directory = output_directory(__doc__)
    summary = read_summary(directory)
    for experiment in ("multimodal2d",) + SCALE + ("bottles617", "bottles", "wam_bottles617", "wam_bottles", "circle",
                                                   "pi2viapoint"):
        plot(directory, experiment)
    by = defaultdict(list)
    for r in summary["results"]:
        by[r["experiment"]].append(r)
    for experiment in ("wam_bottles617", "wam_bottles", "wam_guided"):
        wam_paths(directory, experiment, by.get(experiment, []))
    guided_alignment(directory)
    with open(os.path.join(directory, "tables.md"), "w") as f:
        f.write(tables(summary, directory))


if __name__ == "__main__":
    main()

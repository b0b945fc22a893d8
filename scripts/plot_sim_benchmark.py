#!/usr/bin/env python3
"""Plots and markdown tables for sim_benchmark's Chapter 4 experiments: reads DIR/friction_*.csv and DIR/payload*.csv
(whichever exist), writes DIR/friction_table41.png (Table 4.1 per joint and the tracking RMS), DIR/friction_example.png
(cf. Fig. 4.6), DIR/payload.png (cf. Fig. 4.2), DIR/payload_joints.png (Fig. 4.3: per joint, our observer's external
torques against the truth, 1 kg), DIR/payload_wrench.png (Fig. 4.4: the estimated wrench against the truth, 0.5 kg)
and DIR/tables.md (measured figures beside the thesis').

Usage: plot_sim_benchmark.py DIR
"""
import csv
import os
import sys
from collections import defaultdict

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from plot_common import output_directory  # noqa: E402

MODELS = ["initial", "basic", "advanced"]
# Thesis Table 4.1 (real WAM, joint 1, averaged over 8 validation trajectories).
THESIS_TABLE41 = {"MAE": (0.5907, 0.5115, 0.4277), "MSE": (0.7613, 0.5611, 0.3511), "Max error": (4.7281, 3.6624, 2.5849)}


def rows(path):
    with open(path) as f:
        return list(csv.DictReader(f))


def grouped_bars(ax, joints, series, ylabel, title):
    """One bar per joint and series, side by side, on a log scale."""
    width = 0.8 / len(series)
    for i, (label, values) in enumerate(series):
        ax.bar([j + (i - (len(series) - 1) / 2) * width for j in joints], values, width, label=label)
    ax.set_yscale("log")
    ax.set_xlabel("joint")
    ax.set_ylabel(ylabel)
    ax.set_title(title, fontsize=10)
    ax.set_xticks(joints)
    ax.grid(alpha=0.3, axis="y")
    ax.set_ylim(top=ax.get_ylim()[1] * 4)  # room for the legend above the bars
    ax.legend(loc="upper center", ncol=len(series), fontsize=8)


def friction(directory, md):
    path = os.path.join(directory, "friction_errors.csv")
    if not os.path.exists(path):
        return
    errors = defaultdict(dict)
    for r in rows(path):
        errors[r["model"]][int(r["joint"])] = r
    joints = sorted(errors["advanced"].keys())
    tracking = defaultdict(dict)
    tracking_path = os.path.join(directory, "friction_tracking.csv")
    if os.path.exists(tracking_path):
        for r in rows(tracking_path):
            tracking[r["compensation"]][int(r["joint"])] = float(r["rms_rad"])

    fig, axes = plt.subplots(1, 2, figsize=(12, 4.2))
    grouped_bars(axes[0], joints, [(m, [float(errors[m][j]["mae"]) for j in joints]) for m in MODELS],
                 "validation MAE [N m]", "Friction models on validation runs (cf. Table 4.1)")
    grouped_bars(axes[1], joints, [(c + " compensation", [1000 * tracking[c][j] for j in joints])
                                   for c in ["none", "basic", "advanced"] if c in tracking],
                 "tracking RMS error [mrad]", "Computed-torque control at low gains on the validation runs")
    fig.tight_layout()
    fig.savefig(os.path.join(directory, "friction_table41.png"), dpi=110)
    plt.close(fig)

    example = os.path.join(directory, "friction_example.csv")
    if os.path.exists(example):
        data = rows(example)
        t = [float(r["t"]) for r in data]
        fig, ax = plt.subplots(figsize=(9, 4.2))
        ax.plot(t, [float(r["observed"]) for r in data], color="0.6", lw=2.5, label="observed (2.12)")
        for model, style in zip(MODELS, ["--", "-.", "-"]):
            ax.plot(t, [float(r[model]) for r in data], style, lw=1.2, label=model)
        ax.set_xlabel("t [s]")
        ax.set_ylabel("joint 1 friction [N m]")
        ax.set_title("A validation run of joint 1 on the simulated plant (cf. Fig. 4.6)", fontsize=10)
        ax.grid(alpha=0.3)
        low, high = ax.get_ylim()
        ax.set_ylim(low, high + 0.25 * (high - low))  # room for the legend above the curves
        ax.legend(loc="upper center", ncol=4, fontsize=8)
        fig.tight_layout()
        fig.savefig(os.path.join(directory, "friction_example.png"), dpi=110)
        plt.close(fig)

    md.append("## Friction (thesis Table 4.1, Sec. 4.2)\n")
    md.append("Joint 1, validation runs (simulated plant) beside the thesis' Table 4.1 (real WAM):\n")
    md.append("| joint 1 | initial | basic | advanced | thesis initial | thesis basic | thesis advanced |")
    md.append("|---|---:|---:|---:|---:|---:|---:|")
    for label, key in [("MAE [N m]", "mae"), ("MSE [N² m²]", "mse"), ("Max error [N m]", "max_error")]:
        thesis = THESIS_TABLE41[label.split(" [")[0]]
        md.append("| %s | %s | %.4f | %.4f | %.4f |" % (
            label, " | ".join("%.4f" % float(errors[m][1][key]) for m in MODELS), *thesis))
    md.append("\nEvery joint, validation MAE / MSE / max [N m, N² m², N m] (runs averaged):\n")
    md.append("| joint | runs | initial | basic | advanced |")
    md.append("|---|---:|---|---|---|")
    for j in joints:
        cells = ["%.4f / %.4f / %.3f" % (float(errors[m][j]["mae"]), float(errors[m][j]["mse"]),
                                         float(errors[m][j]["max_error"])) for m in MODELS]
        md.append("| %d | %s | %s |" % (j, errors["advanced"][j]["validation_runs"], " | ".join(cells)))
    if tracking:
        md.append("\nTracking RMS error [mrad], computed-torque control at low gains, all validation runs:\n")
        md.append("| compensation | " + " | ".join("J%d" % j for j in joints) + " | mean |")
        md.append("|---|" + "---:|" * (len(joints) + 1))
        for comp in ["none", "basic", "advanced"]:
            values = [1000 * tracking[comp][j] for j in joints]
            md.append("| %s | %s | %.2f |" % (comp, " | ".join("%.2f" % v for v in values), sum(values) / len(values)))
    md.append("")


def payload(directory, md):
    path = os.path.join(directory, "payload.csv")
    if not os.path.exists(path):
        return
    series = defaultdict(lambda: defaultdict(list))
    for r in rows(path):
        s = series[float(r["load_kg"])]
        for key in ("t", "true_weight_n", "ours_n", "kdl_n", "ours_learned_n"):
            if key in r:
                s[key].append(float(r[key]))
    panels = [("ours_n", "our observer (4.15)"), ("kdl_n", "KDL ChainExternalWrenchEstimator")]
    if all(s["ours_learned_n"] for s in series.values()):
        panels.append(("ours_learned_n", "our observer on the learned dynamics"))
    fig, axes = plt.subplots(1, len(panels), figsize=(6 * len(panels), 4.6), sharey=True)
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for ax, (key, title) in zip(axes, panels):
        for i, (load, s) in enumerate(sorted(series.items())):
            c = colours[i % len(colours)]
            ax.plot(s["t"], s[key], color=c, lw=1.0, label="%.1f kg" % load)
            ax.axhline(s["true_weight_n"][0], color=c, lw=0.8, ls="--")
        ax.axvline(5.0, color="0.5", lw=0.6, ls=":")
        ax.axvline(10.0, color="0.5", lw=0.6, ls=":")
        ax.set_xlabel("t [s]  (joint 1 reverses at 5 s, the motion stops at 10 s)")
        ax.set_title("Estimated weight at the tool, " + title, fontsize=10)
        ax.grid(alpha=0.3)
        ax.set_ylim(-8, 28)
    axes[0].set_ylabel("-F_z estimated [N] (dashed: true weight)")
    axes[0].legend(loc="upper left", fontsize=8)
    fig.tight_layout()
    fig.savefig(os.path.join(directory, "payload.png"), dpi=110)
    plt.close(fig)

    summary = os.path.join(directory, "payload_summary.csv")
    if os.path.exists(summary):
        md.append("## Payload estimation (thesis Fig. 4.2)\n")
        md.append("| observer | load [kg] | weight [N] | steady estimate [N] | steady error | transient peak [N] "
                  "(reversal / stop) | at rest error |")
        md.append("|---|---:|---:|---:|---:|---:|---:|")
        for r in rows(summary):
            md.append("| %s | %.1f | %.2f | %.2f | %+.3f N (%.2f %%) | %.2f (%.2f / %.2f) | %+.3f N (%.2f %%) |" % (
                r["observer"], float(r["load_kg"]), float(r["true_weight_n"]), float(r["steady_estimate_n"]),
                float(r["steady_error_n"]), float(r["steady_error_pct"]), float(r["transient_peak_n"]),
                float(r["reversal_peak_n"]), float(r["stop_peak_n"]), float(r["rest_error_n"]),
                float(r["rest_error_pct"])))
        md.append("")


def observer_truth(directory, md):
    """Figs. 4.3 and 4.4: our observer's per-joint external torques (1 kg) and wrench (0.5 kg) against the
    simulation's truth, with the rms error over the motion (t in [1, 10) s)."""
    path = os.path.join(directory, "payload_joints.csv")
    if os.path.exists(path):
        joints = defaultdict(lambda: defaultdict(list))
        for r in rows(path):
            j = joints[int(r["joint"])]
            for key in ("t", "estimated_nm", "true_nm"):
                j[key].append(float(r[key]))
        fig, axes = plt.subplots(7, 1, figsize=(8, 12), sharex=True)
        md += ["## Fig. 4.3: external torques per joint, 1 kg\n", "| joint | rms error [N m] | mean true [N m] |",
               "|---:|---:|---:|"]
        for ax, (joint, j) in zip(axes, sorted(joints.items())):
            ax.plot(j["t"], j["estimated_nm"], lw=0.7, label="estimated (4.15)")
            ax.plot(j["t"], j["true_nm"], lw=1.0, color="k", ls="--", label="true")
            ax.set_ylabel("joint %d [N m]" % joint, fontsize=8)
            ax.grid(alpha=0.3)
            motion = [(e - t) ** 2 for tt, e, t in zip(j["t"], j["estimated_nm"], j["true_nm"]) if 1.0 <= tt < 10.0]
            true = [t for tt, t in zip(j["t"], j["true_nm"]) if 1.0 <= tt < 10.0]
            md.append("| %d | %.3f | %+.3f |" % (joint, (sum(motion) / len(motion)) ** 0.5, sum(true) / len(true)))
        md.append("")
        axes[0].legend(fontsize=8, loc="upper right")
        axes[0].set_title("External torques for a 1 kg load (cf. Fig. 4.3)", fontsize=10)
        axes[-1].set_xlabel("t [s]  (joint 1 reverses at 5 s, the motion stops at 10 s)")
        fig.tight_layout()
        fig.savefig(os.path.join(directory, "payload_joints.png"), dpi=110)
        plt.close(fig)
    path = os.path.join(directory, "payload_wrench.csv")
    if os.path.exists(path):
        data = defaultdict(list)
        for r in rows(path):
            for key, value in r.items():
                data[key].append(float(value))
        fig, axes = plt.subplots(6, 1, figsize=(8, 10), sharex=True)
        md += ["## Fig. 4.4: the estimated wrench, 0.5 kg\n", "| component | rms error | mean true |", "|---|---:|---:|"]
        for ax, c in zip(axes, ("fx", "fy", "fz", "mx", "my", "mz")):
            ax.plot(data["t"], data[c + "_est"], lw=0.7, label="estimated")
            ax.plot(data["t"], data[c + "_true"], lw=1.0, color="k", ls="--", label="true")
            unit = "N" if c[0] == "f" else "N m"
            ax.set_ylabel("%s [%s]" % (c, unit), fontsize=8)
            ax.grid(alpha=0.3)
            pairs = [(e, t) for tt, e, t in zip(data["t"], data[c + "_est"], data[c + "_true"]) if 1.0 <= tt < 10.0]
            md.append("| %s [%s] | %.3f | %+.3f |" % (c, unit, (sum((e - t) ** 2 for e, t in pairs) / len(pairs)) ** 0.5,
                                                   sum(t for _, t in pairs) / len(pairs)))
        md.append("")
        axes[0].legend(fontsize=8, loc="upper right")
        axes[0].set_title("Wrench on the tool for a 0.5 kg load, base frame (cf. Fig. 4.4)", fontsize=10)
        axes[-1].set_xlabel("t [s]")
        fig.tight_layout()
        fig.savefig(os.path.join(directory, "payload_wrench.png"), dpi=110)
        plt.close(fig)


def main():
    directory = output_directory(__doc__)
    md = []
    friction(directory, md)
    payload(directory, md)
    observer_truth(directory, md)
    with open(os.path.join(directory, "tables.md"), "w") as f:
        f.write("\n".join(md) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())

#!/usr/bin/env python3
"""The cloth fold driven step by step (bimanual_skills/ClothFoldJoint-v0): joint-space actions at the control rate
(1 kHz), episode by episode on seeded resets, against the episodic rollout (bimanual_skills.FoldTask.run) of the same
seed. Two step-by-step policies:

- demonstration: the demonstration's planned joint velocities (FoldTask.plan), streamed period by period;
- noisy: the same plus uniform noise in [-spread, spread] of the action box, drawn anew every period.

Per episode: outcome, reward, the fold quality q, SoftGym's normalised performance, the episodic rollout's q, and
the periods per second; their means with 95 % Student-t intervals, and the demonstration's paired difference to the
episodic rollout (t-test). --out writes DIR/episodes.csv, DIR/summary.json and DIR/tools.png (both tools' heights
over the first episode of each policy).

    build/venv/bin/python scripts/fold_joint_example.py --episodes 10 --seed 1 [--spread 0.05] [--out DIR]

Run it with build/venv's Python (gymnasium), after `source install/setup.bash`."""
import csv
import json
import os
import sys
import time

import numpy as np

from fold_gym_example import episode_arguments, interval  # the same command line and intervals


def episode(env, seed, velocities, spread, rng):
    """One episode streaming `velocities` (periods x 14 [rad/s]) with uniform action noise; its record and the tools'
    heights per period."""
    _, start = env.reset(seed=seed)
    scale = env.unwrapped.velocity_scale
    heights = []
    began = time.perf_counter()
    k = 0
    while True:
        action = velocities[min(k + 1, len(velocities) - 1)] / scale
        if spread > 0.0:
            action = action + rng.uniform(-spread, spread, 14)
        obs, reward, terminated, _, info = env.step(action.astype(np.float32))
        heights.append(obs["tool_position"][[2, 5]])
        k += 1
        if terminated:
            break
    wall = time.perf_counter() - began
    return start["seed"], reward, info, k, wall, np.array(heights)


def main():
    args = episode_arguments(__doc__, "reset seeds seed, seed+1, ...; noise from seed", 0.05,
                             "the noisy policy's noise, uniform in [-spread, spread] of the action box",
                             "a directory for episodes.csv, summary.json and tools.png")

    import bimanual_skills as bs

    bs.pin_numerics()
    import gymnasium
    from scipy import stats

    import bimanual_skills.gym_env  # noqa: F401  (registers the environments)

    kwargs = {"config": args.config} if args.config else {}
    # action_scale 1: an action of 1 is the velocity limit, so the plan's velocities are actions within the box.
    env = gymnasium.make("bimanual_skills/ClothFoldJoint-v0", action_scale=1.0, **kwargs)
    task = env.unwrapped.task
    plan = task.plan(task.initial_parameters())
    if plan["outcome"] != "Ok":
        print("fold_joint_example: the demonstration has no plan: %s" % plan["reason"], file=sys.stderr)
        return 1
    names = task.term_names()
    rng = np.random.default_rng(args.seed)
    print("fold_joint_example: seed %d, %d episodes per policy of %d periods (dt %.3f s), noise spread %.2f, "
          "numerics %s" % (args.seed, args.episodes, task.stepped_periods, task.dt, args.spread, bs.numerics()),
          flush=True)
    rows, heights = [], {}
    for policy in ("demonstration", "noisy"):
        spread = 0.0 if policy == "demonstration" else args.spread
        for k in range(args.episodes):
            seed, reward, info, steps, wall, h = episode(env, args.seed + k, plan["velocity"], spread, rng)
            heights.setdefault(policy, h)
            direct = task.run(task.initial_parameters(), seed)
            direct_q = float(dict(zip(names, direct.terms))["fold_quality"])
            rows.append({"policy": policy, "episode": k, "reset_seed": args.seed + k, "rollout_seed": seed,
                         "outcome": info["outcome"], "reward": reward, "q": info["q"],
                         "normalized_performance": info["normalized_performance"], "episodic_q": direct_q,
                         "episodic_reward": direct.reward, "steps": steps, "periods_per_second": steps / wall})
            print("  %-13s %3d/%d  %-16s R %+.3f  q %.3f (episodic %.3f)  normalised %.3f  %.0f periods/s" %
                  (policy, k + 1, args.episodes, info["outcome"], reward, info["q"], direct_q,
                   info["normalized_performance"], steps / wall), flush=True)
    summary = {"program": "fold_joint_example", "seed": args.seed, "episodes": args.episodes, "spread": args.spread,
               "periods": task.stepped_periods, "dt": task.dt, "numerics": bs.numerics(), "results": []}
    for policy in ("demonstration", "noisy"):
        mine = [r for r in rows if r["policy"] == policy]
        entry = {"policy": policy, "ok": sum(r["outcome"] == "Ok" for r in mine), "episodes": len(mine)}
        for key in ("reward", "q", "normalized_performance", "episodic_q", "periods_per_second"):
            entry[key], entry[key + "_ci95"] = interval([r[key] for r in mine])
        difference = [r["q"] - r["episodic_q"] for r in mine]
        entry["q_minus_episodic"], entry["q_minus_episodic_ci95"] = interval(difference)
        entry["q_minus_episodic_p"] = float(stats.ttest_rel([r["q"] for r in mine],
                                                            [r["episodic_q"] for r in mine]).pvalue)
        summary["results"].append(entry)
        print("%s: %d of %d Ok, R %.3f ± %.3f, q %.3f ± %.3f (episodic %.3f ± %.3f; paired difference %+.4f ± %.4f, "
              "p %.3g), normalised %.3f ± %.3f, %.0f ± %.0f periods/s (95 %% t intervals)" %
              (policy, entry["ok"], len(mine), entry["reward"], entry["reward_ci95"], entry["q"], entry["q_ci95"],
               entry["episodic_q"], entry["episodic_q_ci95"], entry["q_minus_episodic"],
               entry["q_minus_episodic_ci95"], entry["q_minus_episodic_p"], entry["normalized_performance"],
               entry["normalized_performance_ci95"], entry["periods_per_second"],
               entry["periods_per_second_ci95"]))
    if args.out:
        os.makedirs(args.out, exist_ok=True)
        with open(os.path.join(args.out, "episodes.csv"), "w", newline="") as f:
            writer = csv.DictWriter(f, fieldnames=list(rows[0]))
            writer.writeheader()
            writer.writerows(rows)
        with open(os.path.join(args.out, "summary.json"), "w") as f:
            json.dump(summary, f, indent=2)
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(figsize=(8, 4))
        for policy, style in (("demonstration", "-"), ("noisy", "--")):
            h = heights[policy]
            t = np.arange(1, len(h) + 1) * task.dt
            for arm, colour in ((0, "tab:blue"), (1, "tab:orange")):
                ax.plot(t, h[:, arm], style, color=colour, label="%s, %s tool" % (policy, ("left", "right")[arm]))
        ax.set_xlabel("time after the grasp [s]")
        ax.set_ylabel("tool height (world) [m]")
        ax.set_title("ClothFoldJoint-v0, reset seed %d: joint velocities streamed at %.0f Hz" %
                     (args.seed, 1.0 / task.dt))
        ax.legend(fontsize=8)
        fig.tight_layout()
        fig.savefig(os.path.join(args.out, "tools.png"), dpi=100)
    return 0


if __name__ == "__main__":
    sys.exit(main())

#!/usr/bin/env python3
"""The cloth fold as a Gymnasium environment (bimanual_skills/ClothFold-v0), episode by episode: the demonstration
(action 0) and random actions (uniform in the action box times --spread) on seeded resets, with the fold quality q,
SoftGym's normalised performance and the reward per episode, and their means with 95 % Student-t intervals.

    build/venv/bin/python scripts/fold_gym_example.py --episodes 10 --seed 1 [--spread 0.3] [--out DIR]

Run it with build/venv's Python (gymnasium), after `source install/setup.bash`. --out writes DIR/episodes.csv and
DIR/summary.json."""
import argparse
import csv
import json
import math
import os
import sys

import numpy as np


def interval(values):
    """Mean and the half-width of its 95 % Student-t interval."""
    from scipy import stats  # noqa: PLC0415 - only for the summary

    v = np.asarray(values, dtype=float)
    half = stats.t.ppf(0.975, v.size - 1) * v.std(ddof=1) / math.sqrt(v.size) if v.size > 1 else float("nan")
    return float(v.mean()), float(half)


def episode_arguments(doc, seed_help, spread, spread_help, out_help):
    """The episode examples' command line (--episodes, --seed, --spread, --config, --out), checked."""
    parser = argparse.ArgumentParser(description=doc, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--episodes", type=int, default=10, help="episodes per policy (default 10)")
    parser.add_argument("--seed", type=int, default=1, help=seed_help + " (default 1)")
    parser.add_argument("--spread", type=float, default=spread, help="%s (default %g)" % (spread_help, spread))
    parser.add_argument("--config", default="", help="a fold learning file (default config/fold_demo.yaml)")
    parser.add_argument("--out", default="", help=out_help)
    args = parser.parse_args()
    if args.episodes < 2 or args.episodes > 10000:
        parser.error("--episodes: 2 to 10000")
    if not (0.0 <= args.spread <= 1.0):
        parser.error("--spread: in [0, 1]")
    if not (0 <= args.seed < 2**32 - args.episodes):
        parser.error("--seed: a non-negative integer")
    return args


def main():
    args = episode_arguments(__doc__, "reset seeds seed, seed+1, ...", 0.3,
                             "random actions uniform in [-spread, spread] of the action box",
                             "a directory for episodes.csv and summary.json")

    import bimanual_skills as bs

    bs.pin_numerics()
    import gymnasium

    import bimanual_skills.gym_env  # noqa: F401  (registers the environment)

    kwargs = {"config": args.config} if args.config else {}
    env = gymnasium.make("bimanual_skills/ClothFold-v0", **kwargs)
    actions = np.random.default_rng(args.seed)
    print("fold_gym_example: seed %d, %d episodes per policy, random spread %.2f, numerics %s" %
          (args.seed, args.episodes, args.spread, bs.numerics()), flush=True)
    rows = []
    for policy in ("demonstration", "random"):
        for k in range(args.episodes):
            _, start = env.reset(seed=args.seed + k)
            if policy == "demonstration":
                action = np.zeros(env.action_space.shape, dtype=np.float32)
            else:
                action = (args.spread * actions.uniform(-1.0, 1.0, env.action_space.shape)).astype(np.float32)
            _, reward, _, _, info = env.step(action)
            rows.append({"policy": policy, "episode": k, "reset_seed": args.seed + k, "rollout_seed": start["seed"],
                         "outcome": info["outcome"], "reward": reward, "q": info["q"],
                         "normalized_performance": info["normalized_performance"]})
            print("  %-13s %3d/%d  %-8s R %+.3f  q %.3f  normalised %.3f" %
                  (policy, k + 1, args.episodes, info["outcome"], reward, info["q"], info["normalized_performance"]),
                  flush=True)
    summary = {"program": "fold_gym_example", "seed": args.seed, "episodes": args.episodes, "spread": args.spread,
               "numerics": bs.numerics(), "results": []}
    for policy in ("demonstration", "random"):
        mine = [r for r in rows if r["policy"] == policy]
        entry = {"policy": policy}
        for key in ("reward", "q", "normalized_performance"):
            entry[key], entry[key + "_ci95"] = interval([r[key] for r in mine])
        entry["ok"] = sum(r["outcome"] == "Ok" for r in mine)
        summary["results"].append(entry)
        print("%s: R %.3f ± %.3f, q %.3f ± %.3f, normalised %.3f ± %.3f (%d of %d Ok; 95 %% t intervals)" %
              (policy, entry["reward"], entry["reward_ci95"], entry["q"], entry["q_ci95"],
               entry["normalized_performance"], entry["normalized_performance_ci95"], entry["ok"], len(mine)))
    if args.out:
        os.makedirs(args.out, exist_ok=True)
        with open(os.path.join(args.out, "episodes.csv"), "w", newline="") as f:
            writer = csv.DictWriter(f, fieldnames=list(rows[0]))
            writer.writeheader()
            writer.writerows(rows)
        with open(os.path.join(args.out, "summary.json"), "w") as f:
            json.dump(summary, f, indent=2)
    return 0


if __name__ == "__main__":
    sys.exit(main())

#!/usr/bin/env python3
"""Learns the cloth fold with CMA-ES from Python: the C++ fold (bimanual_skills.make_task("fold")), CMA-ES's update
(bimanual_skills.CmaEs), the rollouts of each generation on Python threads, one task (one simulator) per thread (a
rollout releases Python's lock, so the threads run in parallel), or on Ray (--ray: a local Ray, or --ray HOST:PORT a
cluster; build/venv/bin/python). The search is over the demonstration's latent
forcing weights (the coordination kept at its start, Omega = I), from the demonstration with the learning file's
initial_stddev.

    source install/setup.bash
    /usr/bin/python3 scripts/learn_fold_cma.py --config config/fold_demo.yaml --generations 10 --population 12 \\
        --threads 2 --seed 1 --out build/fold_cma
    build/venv/bin/python scripts/learn_fold_cma.py --ray --threads 2 --generations 10 --out build/fold_cma_ray

Writes OUT/generations.csv (a row per generation: the mean's reward and fold quality q on the evaluation seed, the
samples' mean and best reward, sigma) as it goes and OUT/summary.json at the end. Same seed, same results, for any
number of threads (each rollout's seed is drawn with its sample)."""
import argparse
import concurrent.futures
import csv
import json
import os
import queue
import sys
import time

import numpy as np
import yaml

import bimanual_skills as bs

bs.pin_numerics()  # the same rollouts as the C++ programs, bit for bit (re-executes once)


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--config", default=bs.config_path("fold_demo.yaml"), help="a fold learning file")
    p.add_argument("--generations", type=int, default=10)
    p.add_argument("--population", type=int, default=12, help="rollouts per generation (>= 2)")
    p.add_argument("--threads", type=int, default=2, help="rollouts at once, one simulator each")
    p.add_argument("--seed", type=int, default=1, help="the samples' and the rollouts' seeds, in [0, 2^32)")
    p.add_argument("--ray", nargs="?", const="local", default=None, metavar="ADDRESS",
                   help="the rollouts on Ray instead of threads: a local Ray of --threads CPUs, or a cluster at "
                        "ADDRESS (HOST:PORT or auto); needs build/venv's Python (make venv)")
    p.add_argument("--out", required=True)
    a = p.parse_args()
    if a.generations < 1 or a.population < 2 or a.threads < 1 or not 0 <= a.seed < 2**32:
        p.error("--generations >= 1, --population >= 2, --threads >= 1 and --seed in [0, 2^32)")
    with open(a.config) as f:
        learning = (yaml.safe_load(f) or {}).get("learning", {})
    stddev = float(learning.get("initial_stddev", 2.0))
    os.makedirs(a.out, exist_ok=True)
    print("learn_fold_cma: %s, %d generations x %d rollouts on %d threads, seed %d, numerics %s"
          % (a.config, a.generations, a.population, a.threads, a.seed, bs.numerics()), flush=True)

    ray_evaluator = None
    if a.ray is not None:
        from bimanual_skills.ray_backend import RayEvaluator

        ray_evaluator = RayEvaluator("fold", os.path.abspath(a.config), address=None if a.ray == "local" else a.ray,
                                     workers=a.threads)
    tasks = queue.Queue()
    for _ in range(a.threads):
        tasks.put(bs.make_task("fold", a.config))
    probe = tasks.get()
    theta0 = probe.initial_parameters()
    names = probe.term_names()
    tasks.put(probe)
    # [N_s, r, latent weights (r x basis), Omega ...]: the latent weights are searched, the rest kept.
    matrices, latent = int(theta0[0]), int(theta0[1])
    weights = slice(2, len(theta0) - matrices * 12 * latent)
    rng = np.random.default_rng(a.seed)
    evaluation_seed = int(rng.integers(0, 2**32))

    def run(theta, seed):
        task = tasks.get()
        try:
            return task.run(theta, seed)
        finally:
            tasks.put(task)

    def policy(w):
        theta = theta0.copy()
        theta[weights] = w
        return theta

    mean = theta0[weights].copy()
    cma = bs.CmaEs(stddev**2 * np.eye(mean.size))
    rows = []
    with concurrent.futures.ThreadPoolExecutor(a.threads) as pool, open(os.path.join(a.out, "generations.csv"), "w") as out:
        writer = csv.writer(out)
        writer.writerow(["generation", "mean_reward", "mean_q", "samples_mean_reward", "samples_best_reward", "sigma",
                         "seconds"])
        for g in range(a.generations + 1):
            start = time.monotonic()
            r_mean = run(policy(mean), evaluation_seed)
            q = dict(zip(names, r_mean.terms))["fold_quality"]
            if g == a.generations:
                rows.append((g, r_mean.reward, q, float("nan"), float("nan"), cma.step_size, 0.0))
                writer.writerow(rows[-1])
                break
            samples = rng.multivariate_normal(mean, cma.covariance, size=a.population)
            seeds = rng.integers(0, 2**32, size=a.population)
            if ray_evaluator is not None:
                results = ray_evaluator.map([(policy(s), int(k)) for s, k in zip(samples, seeds)])
            else:
                results = list(pool.map(run, [policy(s) for s in samples], [int(s) for s in seeds]))
            rewards = np.array([x.reward for x in results])
            mean = cma.step(mean, samples, rewards)
            rows.append((g, r_mean.reward, q, rewards.mean(), rewards.max(), cma.step_size, time.monotonic() - start))
            writer.writerow(rows[-1])
            out.flush()
            print("learn_fold_cma: generation %d: the mean's R %.4f, q %.4f; rollouts' R %.4f (best %.4f), "
                  "sigma %.3f, %.1f s" % rows[-1], flush=True)
    first, last = rows[0], rows[-1]
    print("learn_fold_cma: the mean policy's fold quality %.4f -> %.4f (R %.4f -> %.4f) in %d rollouts"
          % (first[2], last[2], first[1], last[1], a.generations * a.population), flush=True)
    with open(os.path.join(a.out, "summary.json"), "w") as f:
        json.dump({"program": "learn_fold_cma", "config": a.config, "seed": a.seed, "threads": a.threads,
                   "generations": a.generations, "population": a.population, "numerics": bs.numerics(),
                   "initial": {"reward": first[1], "fold_quality": first[2]},
                   "final": {"reward": last[1], "fold_quality": last[2]}}, f, indent=2)
    return 0


if __name__ == "__main__":
    sys.exit(main())

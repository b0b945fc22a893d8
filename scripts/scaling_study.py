#!/usr/bin/env python3
"""Table 7.5's fold learning (config/fold_table75.yaml) on each rollout backend, timed side by side: the learning's
wall time, rollouts per second, speed-up and efficiency against one thread, and whether every rollout (reward, terms,
policy) equals the one-thread run's.

    source install/setup.bash
    build/venv/bin/python scripts/scaling_study.py --experiment table75 --seed 90168 --out build/scaling [--quick]
        [--backends threads1,threads2,ros2,ros_two_hosts,ray1,ray2,ray_two_hosts]

Backends (each a fresh learning into OUT/BACKEND, in this order; the cluster is started before its timer starts):
  threads1, threads2  bimanual_skills.learn_fold in one process, rollouts on 1 or 2 threads
  ros2                fold_learner (C++) dispatching to 2 rollout_worker processes (rollout_workers.launch) over a
                      ROS master of its own on loopback
  ros_two_hosts       the same on two "hosts" (the network namespaces below): the master, fold_learner and worker_0
                      in bs_ray_head, worker_1 in bs_ray_node (root)
  ray1, ray2          learn_fold with bimanual_skills.ray_backend.RayEvaluator on a local Ray of 1 or 2 CPUs
  ray_two_hosts       the same on a Ray cluster of two "hosts": network namespaces bs_ray_head (Ray's head and the
                      learner) and bs_ray_node (a worker node, `ray start --address`), one CPU each, joined by a veth
                      pair on 10.77.0.0/24 (root; the namespaces are removed at the end)

--quick: IDR-DMP_CMU and CMA-ES, 1 run x 4 updates x 12 rollouts, no repetitions (130 rollouts per backend with each
epoch's noise-free policy, about 10 min on 2 cores in all); without it the file's whole study (5 algorithms x 10 runs x
16 epochs x (12 rollouts + the noise-free policy) and 12 repetitions: 10412 rollouts, about 2.5 h per backend on one
core). --seed replaces the file's learning seed. --resume continues every backend's learning where it stopped (the learners
resume from their records; each backend's wall time is the sum of its segments, OUT/BACKEND/segments.csv, a killed
segment counting up to its last record, so the rollouts in flight when it died count only when they run again), so
the whole study can run in parts.
Writes OUT/study.yaml (the learning file run), OUT/scaling.csv (a row per backend as it finishes) and
OUT/summary.json."""
import argparse
import csv
import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import time

import yaml

ALL = ["threads1", "threads2", "ros2", "ros_two_hosts", "ray1", "ray2", "ray_two_hosts"]
PROCESSES = {"threads1": 1, "threads2": 2, "ros2": 2, "ros_two_hosts": 2, "ray1": 1, "ray2": 2, "ray_two_hosts": 2}
HEAD, NODE, HEAD_IP, NODE_IP, RAY_PORT = "bs_ray_head", "bs_ray_node", "10.77.0.1", "10.77.0.2", 6390


def study_file(out, quick, seed):
    """OUT/study.yaml: fold_table75.yaml with its simulation file's path made absolute (the workers read it)."""
    import bimanual_skills as bs

    source = bs.config_path("fold_table75.yaml")
    with open(source) as f:
        study = yaml.safe_load(f)
    study["sim"] = os.path.join(os.path.dirname(source), study["sim"])
    learning = study["learning"]
    if seed is not None:
        learning["seed"] = seed
    if quick:
        learning.update(algorithms=["IDR-DMP_CMU", "CMA-ES"], runs=1, updates=4, repetitions=0)
    path = os.path.join(out, "study.yaml")
    with open(path, "w") as f:
        yaml.safe_dump(study, f, sort_keys=False)
    return path


def rollouts(out):
    """rollouts.csv's rows without the wall time, in the learning's order (the file has them as they finished)."""
    with open(os.path.join(out, "rollouts.csv")) as f:
        rows = [{k: v for k, v in r.items() if k != "wall_seconds"} for r in csv.DictReader(f)]
    return sorted(rows, key=lambda r: (r["algorithm"], int(r["run"]), int(r["epoch"]), r["kind"], int(r["index"])))


def inner(args):
    """One learning in this process (threads or Ray): prints its wall time as JSON."""
    import bimanual_skills as bs

    bs.pin_numerics()
    evaluator = None
    if args.inner == "ray":
        from bimanual_skills import ray_backend

        evaluator = ray_backend.RayEvaluator("fold", args.config, address=args.address, workers=args.jobs or None)
        # Ray starts its worker processes with their first tasks: started here before the timer, as the ROS
        # workers are before theirs (each builds its simulator with its first rollout, as the threads do).
        import ray

        @ray.remote
        def warm():
            import bimanual_skills  # noqa: F401

            time.sleep(0.5)
            return os.getpid()

        ray.get([warm.remote() for _ in range(4)])
    start = time.monotonic()
    summary = bs.learn_fold(args.config, args.out, evaluator=evaluator, jobs=args.jobs)
    print(json.dumps({"seconds": time.monotonic() - start, "simulated": summary["simulated"]}), flush=True)


def run_inner(kind, config, out, jobs=0, address=None, prefix=()):
    command = list(prefix) + [sys.executable, os.path.abspath(__file__), "--inner", kind, "--config", config,
                              "--run-out", out, "--jobs", str(jobs)]
    if address:
        command += ["--address", address]
    done = subprocess.run(command, check=True, stdout=subprocess.PIPE, text=True)
    return json.loads(done.stdout.strip().splitlines()[-1])["seconds"]


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def run_ros(config, out, two_hosts=False):
    """fold_learner against 2 rollout_worker processes on a master of its own: all on loopback, or (two_hosts) the
    master, the learner and worker_0 in the namespace bs_ray_head, worker_1 in bs_ray_node (two_hosts_up())."""
    if two_hosts:
        master = "http://%s:11311" % HEAD_IP
        env = {k: v for k, v in os.environ.items() if k not in ("ROS_HOSTNAME", "ROS_IP")}
        env["ROS_MASTER_URI"] = master
        head = ["ip", "netns", "exec", HEAD, "env", "ROS_IP=" + HEAD_IP]
        launches = [(head, 1, 0), (["ip", "netns", "exec", NODE, "env", "ROS_IP=" + NODE_IP], 1, 1)]
    else:
        master = "http://127.0.0.1:%d" % free_port()
        env = dict(os.environ, ROS_MASTER_URI=master, ROS_HOSTNAME="127.0.0.1")
        head = []
        launches = [([], 2, 0)]
    port = master.rsplit(":", 1)[1]
    logs = open(os.path.join(out, "ros.log"), "w")
    core = subprocess.Popen(head + ["roscore", "-p", port], env=env, stdout=logs, stderr=subprocess.STDOUT,
                            start_new_session=True)
    started = [core]
    try:
        for _ in range(100):
            if subprocess.run(head + ["rostopic", "list"], env=env, capture_output=True).returncode == 0:
                break
            time.sleep(0.2)
        else:
            raise RuntimeError("roscore did not come up on port %s (see %s)" % (port, logs.name))
        for prefix, workers, first in launches:
            started.append(subprocess.Popen(prefix + ["roslaunch", "bimanual_skills", "rollout_workers.launch",
                                                      "workers:=%d" % workers, "first:=%d" % first],
                                            env=env, stdout=logs, stderr=subprocess.STDOUT, start_new_session=True))
        for _ in range(300):
            nodes = subprocess.run(head + ["rosnode", "list"], env=env, capture_output=True, text=True).stdout.split()
            if sum(n.startswith("/rollout_workers/worker_") for n in nodes) == 2:
                break
            time.sleep(0.2)
        else:
            raise RuntimeError("the rollout workers did not come up (see %s)" % logs.name)
        start = time.monotonic()
        subprocess.run(head + ["rosrun", "bimanual_skills", "fold_learner", "_config:=" + config, "_out:=" + out,
                               "_worker_namespace:=/rollout_workers"], env=env, check=True, stdout=logs,
                       stderr=subprocess.STDOUT)
        return time.monotonic() - start
    finally:
        for p in reversed(started):
            if p.poll() is None:
                os.killpg(p.pid, signal.SIGINT)
                try:
                    p.wait(timeout=20)
                except subprocess.TimeoutExpired:
                    os.killpg(p.pid, signal.SIGKILL)
        logs.close()


def sh(*command, check=True):
    done = subprocess.run(list(command), capture_output=True, text=True)
    if check and done.returncode != 0:
        raise RuntimeError("%s: exit %d\n%s" % (" ".join(command), done.returncode, done.stderr[-2000:]))
    return done


def two_hosts_down():
    """Ray's processes in the two namespaces (only theirs: `ray stop` would stop every Ray on the machine), then the
    namespaces."""
    for ns in (HEAD, NODE):
        pids = [int(p) for p in sh("ip", "netns", "pids", ns, check=False).stdout.split()]
        for sig in (signal.SIGTERM, signal.SIGKILL):
            for pid in pids:
                try:
                    os.kill(pid, sig)
                except ProcessLookupError:
                    pass
            deadline = time.monotonic() + 5.0
            while sig == signal.SIGTERM and time.monotonic() < deadline and any(os.path.exists("/proc/%d" % p)
                                                                                for p in pids):
                time.sleep(0.1)
        sh("ip", "netns", "del", ns, check=False)


def two_hosts_up():
    """Two "hosts": the network namespaces bs_ray_head (10.77.0.1) and bs_ray_node (10.77.0.2) joined by a veth pair,
    made anew (root)."""
    if os.geteuid() != 0:
        raise RuntimeError("the two-host backends make network namespaces: run as root")
    two_hosts_down()
    sh("ip", "link", "del", "bs_veth_h", check=False)
    sh("ip", "netns", "add", HEAD)
    sh("ip", "netns", "add", NODE)
    sh("ip", "link", "add", "bs_veth_h", "type", "veth", "peer", "name", "bs_veth_n")
    sh("ip", "link", "set", "bs_veth_h", "netns", HEAD)
    sh("ip", "link", "set", "bs_veth_n", "netns", NODE)
    for ns, dev, ip in ((HEAD, "bs_veth_h", HEAD_IP), (NODE, "bs_veth_n", NODE_IP)):
        sh("ip", "netns", "exec", ns, "ip", "addr", "add", ip + "/24", "dev", dev)
        sh("ip", "netns", "exec", ns, "ip", "link", "set", dev, "up")
        sh("ip", "netns", "exec", ns, "ip", "link", "set", "lo", "up")


def run_ray_two_hosts(config, out):
    """A Ray head in one network namespace, a worker node in another, one CPU each; the learner beside the head."""
    ray = [sys.executable, "-m", "ray.scripts.scripts"]
    try:
        two_hosts_up()
        # Ray's token authentication, as `ray start` sets it up (the token in ~/.ray/auth_token, one home here).
        env_prefix = ["env", "RAY_USAGE_STATS_ENABLED=0", "RAY_AUTH_MODE=token"]
        sh("ip", "netns", "exec", HEAD, *env_prefix, *ray, "start", "--head", "--node-ip-address", HEAD_IP, "--port",
           str(RAY_PORT), "--num-cpus", "1", "--include-dashboard", "false", "--disable-usage-stats")
        sh("ip", "netns", "exec", NODE, *env_prefix, *ray, "start", "--address", "%s:%d" % (HEAD_IP, RAY_PORT),
           "--node-ip-address", NODE_IP, "--num-cpus", "1", "--disable-usage-stats")
        return run_inner("ray", config, out, address="%s:%d" % (HEAD_IP, RAY_PORT),
                         prefix=["ip", "netns", "exec", HEAD] + env_prefix)
    finally:
        two_hosts_down()


def run_ros_two_hosts(config, out):
    """The ROS master, fold_learner and one rollout_worker in one network namespace, the other worker in another."""
    try:
        two_hosts_up()
        return run_ros(config, out, two_hosts=True)
    finally:
        two_hosts_down()


def _write_segments(out, rows):
    path = os.path.join(out, "segments.csv")
    with open(path + ".tmp", "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=["start", "seconds"])
        writer.writeheader()
        writer.writerows(rows)
    os.replace(path + ".tmp", path)


def earlier_segments(out):
    """A backend's earlier segments (OUT/BACKEND/segments.csv: each one's start [Unix s] and seconds). A segment
    that never ended (killed; seconds -1) is given the time up to its last record (rollouts.csv's, before this
    segment writes one) and written so."""
    path = os.path.join(out, "segments.csv")
    if not os.path.exists(path):
        return []
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    records = os.path.join(out, "rollouts.csv")
    last_record = os.path.getmtime(records) if os.path.exists(records) else 0.0
    for row in rows:
        if float(row["seconds"]) < 0.0:
            row["seconds"] = "%.3f" % max(0.0, last_record - float(row["start"]))
    _write_segments(out, rows)
    return rows


def segment(out, rows, run):
    """Runs `run()` (the learning's seconds) as a new segment after `rows`, recorded in OUT/BACKEND/segments.csv
    before it starts (seconds -1) and once it ends."""
    rows = rows + [{"start": "%.3f" % time.time(), "seconds": "-1"}]
    _write_segments(out, rows)
    seconds = run()
    rows[-1]["seconds"] = "%.3f" % seconds
    _write_segments(out, rows)
    return seconds


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--experiment", default="table75", choices=["table75"])
    p.add_argument("--seed", type=int, default=None, help="the learning's seed (default: the file's, 90168)")
    p.add_argument("--out", help="results directory")
    p.add_argument("--quick", action="store_true", help="a small study (about 100 rollouts per backend)")
    p.add_argument("--backends", default=",".join(ALL), help="comma-separated, from " + ",".join(ALL))
    p.add_argument("--resume", action="store_true",
                   help="continue each backend's learning in OUT/BACKEND where it stopped (killed, or a machine "
                        "stopped), its wall time summed over its segments; without it each backend starts afresh")
    p.add_argument("--inner", choices=["threads", "ray"], help=argparse.SUPPRESS)
    p.add_argument("--config", help=argparse.SUPPRESS)
    p.add_argument("--run-out", help=argparse.SUPPRESS)
    p.add_argument("--jobs", type=int, default=0, help=argparse.SUPPRESS)
    p.add_argument("--address", default=None, help=argparse.SUPPRESS)
    args = p.parse_args()
    if args.inner:
        args.out = args.run_out
        return inner(args)
    if not args.out:
        p.error("--out DIR is needed")
    backends = [b for b in args.backends.split(",") if b]
    unknown = [b for b in backends if b not in ALL]
    if unknown or not backends:
        p.error("--backends: %s unknown; from %s" % (",".join(unknown) or "none given", ",".join(ALL)))
    if args.seed is not None and not 0 <= args.seed < 2**32:
        p.error("--seed: an integer in [0, 2^32)")
    if "threads1" in backends:
        backends.remove("threads1")
    backends.insert(0, "threads1")  # the reference every other backend is compared with, run first
    os.makedirs(args.out, exist_ok=True)
    config = study_file(args.out, args.quick, args.seed)
    with open(config) as f:
        seed = yaml.safe_load(f)["learning"]["seed"]
    print("scaling_study: %s%s, seed %d, backends %s, into %s" %
          (args.experiment, " --quick" if args.quick else "", seed, ",".join(backends), args.out), flush=True)
    rows, reference, reference_seconds = [], None, None
    table = open(os.path.join(args.out, "scaling.csv"), "w", newline="")
    writer = csv.DictWriter(table, fieldnames=["backend", "processes", "rollouts", "seconds", "rollouts_per_second",
                                               "speedup", "efficiency", "identical"])
    writer.writeheader()
    for backend in backends:
        out = os.path.join(args.out, backend)
        if not args.resume:
            shutil.rmtree(out, ignore_errors=True)
        os.makedirs(out, exist_ok=True)
        earlier = earlier_segments(out)
        before = sum(float(r["seconds"]) for r in earlier)
        print("  %-14s ...%s" % (backend, " (resumed after %d segments, %.1f s)" % (len(earlier), before)
                                 if earlier else ""), end="", flush=True)

        def run(backend=backend, out=out):
            if backend.startswith("threads"):
                return run_inner("threads", config, out, jobs=PROCESSES[backend])
            if backend == "ros2":
                return run_ros(config, out)
            if backend == "ros_two_hosts":
                return run_ros_two_hosts(config, out)
            if backend == "ray_two_hosts":
                return run_ray_two_hosts(config, out)
            return run_inner("ray", config, out, jobs=PROCESSES[backend])

        seconds = before + segment(out, earlier, run)
        done = rollouts(out)
        if reference is None:
            reference, reference_seconds = done, seconds
        speedup = reference_seconds / seconds
        row = {"backend": backend, "processes": PROCESSES[backend], "rollouts": len(done),
               "seconds": round(seconds, 2), "rollouts_per_second": round(len(done) / seconds, 3),
               "speedup": round(speedup, 3), "efficiency": round(speedup / PROCESSES[backend], 3),
               "identical": done == reference}
        rows.append(row)
        writer.writerow(row)
        table.flush()
        print(" %d rollouts in %.1f s: %.2f/s, %.2fx, efficiency %.2f, %s" %
              (row["rollouts"], seconds, row["rollouts_per_second"], speedup, row["efficiency"],
               "identical to threads1" if row["identical"] else "DIFFERENT from threads1"), flush=True)
    table.close()
    with open(os.path.join(args.out, "summary.json"), "w") as f:
        json.dump({"program": "scaling_study", "experiment": args.experiment, "seed": seed, "quick": args.quick,
                   "machine_cores": os.cpu_count(), "results": rows}, f, indent=2)
    return 0 if all(r["identical"] for r in rows) else 1


if __name__ == "__main__":
    sys.exit(main())

"""Ray as the learners' rollout backend (bimanual_skills.ray_backend): the fold's learning on a local Ray of 1 and 2
workers, and the scarf's and the bottles' DR-DMP learning on 2, give the in-process results exactly; Ctrl-C stops a
learning between rollouts and it resumes; a Ray worker killed mid-rollout has its rollout run again, nothing
lost or doubled. Run by make test with build/venv's Python (Ray from PyPI, python/requirements.txt)."""
import csv
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time

import pytest

import bimanual_skills as bs

ray = pytest.importorskip("ray", reason="Ray is in build/venv (make venv); make test runs this file with it")
from bimanual_skills import ray_backend  # noqa: E402

SOURCE = os.environ.get("BIMANUAL_SKILLS_SOURCE_DIR", os.path.join(os.path.dirname(__file__), "..", ".."))
SMALL = os.path.join(SOURCE, "test", "fold_learner_small.yaml")


def test_this_process_runs_the_pinned_numerics():
    # The in-process references below run here, Ray's workers start pinned: test/python/run.py pins this process.
    assert bs.numerics() == "pinned", "run the tests through test/python/run.py"


def rollouts(out):
    """rollouts.csv's rows without the wall time, in the learning's order (the file has them as they finished)."""
    with open(os.path.join(out, "rollouts.csv")) as f:
        rows = [{k: v for k, v in r.items() if k != "wall_seconds"} for r in csv.DictReader(f)]
    return sorted(rows, key=lambda r: (r["algorithm"], int(r["run"]), int(r["epoch"]), r["kind"], int(r["index"])))


@pytest.fixture
def out():
    d = tempfile.mkdtemp(prefix="ray_backend_")
    yield d
    shutil.rmtree(d, ignore_errors=True)


def learn(out, name, evaluator=None):
    path = os.path.join(out, name)
    summary = bs.learn_fold(SMALL, path, evaluator=evaluator, updates=2, rollouts=4, jobs=2)
    return summary, rollouts(path)


@pytest.fixture(scope="module")
def threads_learning():
    """The fold's learning on 2 threads, once for the module: the reference of every backend here."""
    d = tempfile.mkdtemp(prefix="ray_backend_threads_")
    yield learn(d, "threads")
    shutil.rmtree(d, ignore_errors=True)


def test_ray_gives_the_in_process_learning_for_one_and_two_workers(out, threads_learning):
    reference, reference_rows = threads_learning
    assert reference["simulated"] == len(reference_rows) > 8
    for workers in (1, 2):
        ray.shutdown()
        summary, rows = learn(out, "ray%d" % workers, ray_backend.RayEvaluator("fold", SMALL, workers=workers))
        assert rows == reference_rows, "%d workers" % workers
        timeless = [{k: v for k, v in r.items() if k != "seconds"} for r in summary["runs"]]
        assert timeless == [{k: v for k, v in r.items() if k != "seconds"} for r in reference["runs"]]
    ray.shutdown()


@pytest.mark.parametrize("task,config", [("scarf", "scarf_learning.yaml"), ("bottles_learning", "bottles_learning.yaml")])
def test_ray_gives_the_in_process_dmp_learning_of_the_scarf_and_the_bottles(out, task, config):
    path = bs.config_path(config)

    def learn_dmp(name, evaluator=None):
        summary = bs.learn_dmp(task, path, os.path.join(out, name), evaluator=evaluator, runs=1, updates=2,
                               rollouts=4, jobs=2)
        return summary, rollouts(os.path.join(out, name))

    reference, reference_rows = learn_dmp("threads")
    assert reference["simulated"] == len(reference_rows) > 8
    assert reference["runs"][0]["final_reward"] != reference["runs"][0]["initial_reward"]  # it learned something
    ray.shutdown()  # 2 workers (1 worker's equality: the fold's test above)
    summary, rows = learn_dmp("ray2", ray_backend.RayEvaluator(task, path, workers=2))
    assert rows == reference_rows
    timeless = [{k: v for k, v in r.items() if k != "seconds"} for r in summary["runs"]]
    assert timeless == [{k: v for k, v in r.items() if k != "seconds"} for r in reference["runs"]]
    ray.shutdown()
    with pytest.raises(ValueError, match="'scarf' or 'bottles_learning'"):
        bs.learn_dmp("fold", path, os.path.join(out, "bad"))


def _rollout_workers():
    """PIDs of Ray worker processes running a rollout (Ray names them after the task they run)."""
    pids = []
    for pid in os.listdir("/proc"):
        if not pid.isdigit():
            continue
        try:
            with open("/proc/%s/cmdline" % pid, "rb") as f:
                if f.read().startswith(b"ray::_rollout"):
                    pids.append(int(pid))
        except OSError:
            pass
    return pids


def test_a_killed_worker_has_its_rollout_run_again_nothing_lost_or_doubled(out, threads_learning):
    _, reference_rows = threads_learning
    ray.shutdown()
    evaluator = ray_backend.RayEvaluator("fold", SMALL, workers=2)
    killed = []

    def killer():
        # Killed only while Ray still names it after the rollout it runs (an idle worker is "ray::IDLE"): that
        # rollout gives no result, so the learning can only complete, rows equal, by Ray running it again.
        deadline = time.monotonic() + 120.0
        while not killed and time.monotonic() < deadline:
            for pid in _rollout_workers():
                time.sleep(0.2)  # into the rollout (one takes about 0.5 s)
                if pid in _rollout_workers():
                    os.kill(pid, signal.SIGKILL)
                    killed.append(pid)
                    break
            time.sleep(0.02)

    watcher = threading.Thread(target=killer)
    watcher.start()
    summary, rows = learn(out, "killed", evaluator)
    watcher.join()
    ray.shutdown()
    assert killed, "no worker was killed mid-rollout"
    assert rows == reference_rows
    keys = [(r["algorithm"], r["run"], r["epoch"], r["index"], r["kind"]) for r in rows]
    assert len(keys) == len(set(keys))


def _interrupted_learning(out, name, ray_workers):
    """A learn_fold in a child process interrupted by SIGINT (Ctrl-C) once two rollouts are on disk: how long it took
    to stop, its exit, its stderr."""
    path = os.path.join(out, name)
    evaluator = ("ray_backend.RayEvaluator('fold', %r, workers=%d)" % (SMALL, ray_workers)) if ray_workers else "None"
    code = ("import bimanual_skills as bs\nfrom bimanual_skills import ray_backend\n"
            "bs.learn_fold(%r, %r, evaluator=%s, updates=2, rollouts=4, jobs=2)\n" % (SMALL, path, evaluator))
    child = subprocess.Popen([sys.executable, "-c", code], env=dict(os.environ, **bs.pinned_environment()),
                             stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 120.0
    while time.monotonic() < deadline and child.poll() is None:
        try:
            with open(os.path.join(path, "rollouts.csv")) as f:
                if len(f.readlines()) >= 3:  # the header and two rollouts
                    break
        except OSError:
            pass
        time.sleep(0.05)
    assert child.poll() is None, "the learning ended before it was interrupted"
    child.send_signal(signal.SIGINT)
    sent = time.monotonic()
    try:
        _, err = child.communicate(timeout=30.0)
    finally:
        child.kill()
    return time.monotonic() - sent, child.returncode, err


@pytest.mark.parametrize("ray_workers", [0, 2], ids=["threads", "ray"])
def test_ctrl_c_stops_the_learning_between_rollouts_and_it_resumes(out, ray_workers, threads_learning):
    _, reference_rows = threads_learning
    stopped_after, code, err = _interrupted_learning(out, "interrupted", ray_workers)
    assert code != 0 and "KeyboardInterrupt" in err, err[-2000:]
    assert stopped_after < 10.0, stopped_after  # a rollout takes about 0.5 s; Ray's shutdown the rest
    path = os.path.join(out, "interrupted")
    with open(os.path.join(path, "rollouts.csv"), newline="") as f:
        lines = list(csv.reader(f))
    assert 3 <= len(lines) < len(reference_rows) + 1  # stopped before the end
    assert {len(line) for line in lines} == {len(lines[0])}  # every record whole
    summary, rows = learn(out, "interrupted")  # resumed in process: nothing lost or doubled
    assert summary["resumed"] == len(lines) - 1 and rows == reference_rows
    assert not _rollout_workers()

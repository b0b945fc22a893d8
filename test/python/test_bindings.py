"""The Python module bimanual_skills (python/bindings.cpp): its tasks against the C++ programs' own rollout bit for
bit, rollouts on Python threads, the policy updates, and errors as Python exceptions with the C++ reason. Run by
make test (CMakeLists.txt, catkin_run_tests_target pytest) in the devel space's environment."""
import os
import subprocess
import sys
import threading

import numpy as np
import pytest

import bimanual_skills as bs

SOURCE = os.environ.get("BIMANUAL_SKILLS_SOURCE_DIR", os.path.join(os.path.dirname(__file__), "..", ".."))
FOLD = os.path.join(SOURCE, "config", "fold_demo.yaml")
REFERENCE = os.environ.get("BIMANUAL_SKILLS_PYTHON_REFERENCE")


def test_the_registry_lists_the_tasks_with_their_files():
    names = [t["name"] for t in bs.tasks()]
    for name in ("fold", "scarf", "wam_bottles", "quadratic", "multimodal"):
        assert name in names
    assert all(t["description"] for t in bs.tasks())


def test_a_rollout_round_trips_numpy_and_names_its_terms():
    task = bs.make_task("fold", FOLD)
    theta = task.initial_parameters()
    assert isinstance(theta, np.ndarray) and theta.dtype == np.float64 and theta.ndim == 1
    r = task.run(theta, seed=3)
    assert r.ok and r.outcome == "Ok" and r.reason == ""
    assert len(task.term_names()) == r.terms.shape[0] == 19
    terms = dict(zip(task.term_names(), r.terms))
    assert 0.0 < terms["fold_quality"] <= 1.0
    # the fold's trajectory summary: both tools' paths, 3 rows each
    assert r.trajectory.shape[0] == 6 and r.trajectory.shape[1] > 100
    again = task.run(theta, seed=3)
    assert again.reward == r.reward and np.array_equal(again.terms, r.terms)


def _hex_rollout_in_python(name, config, seed):
    code = (
        "import bimanual_skills as bs\n"
        "t = bs.make_task(%r, %r)\n"
        "r = t.run(t.initial_parameters(), %d)\n"
        "print('outcome', r.outcome)\n"
        "print('reward', float(r.reward).hex())\n"
        "[print('term', float(v).hex()) for v in r.terms]\n"
        "print('numerics', bs.numerics())\n" % (name, config, seed)
    )
    env = dict(os.environ)
    env.update(bs.pinned_environment())
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
    return out.stdout.split("\n")


def _hex_rollout_in_cpp(name, config, seed):
    out = subprocess.run([REFERENCE, name, config, str(seed)], capture_output=True, text=True, check=True)
    return out.stdout.split("\n")


def _floats(lines):
    """The lines' values as floats (C's %a and Python's float.hex() spell some values differently)."""
    out = []
    for line in lines:
        key, _, value = line.partition(" ")
        out.append((key, float.fromhex(value) if key in ("reward", "term") else value))
    return out


@pytest.mark.skipif(REFERENCE is None, reason="BIMANUAL_SKILLS_PYTHON_REFERENCE (make test sets it) not set")
@pytest.mark.parametrize(
    "name,config,seed", [("fold", FOLD, 11), ("wam_bottles", os.path.join(SOURCE, "config", "bottles_wam.yaml"), 5)]
)
def test_a_rollout_from_python_equals_the_cpp_one_bit_for_bit(name, config, seed):
    python = _floats(_hex_rollout_in_python(name, config, seed))
    cpp = _floats(_hex_rollout_in_cpp(name, config, seed))
    assert ("numerics", "pinned") in python and ("numerics", "pinned") in cpp
    assert python == cpp


def test_rollouts_on_python_threads_run_together_and_equal_the_serial_ones():
    tasks = [bs.make_task("fold", FOLD) for _ in range(2)]
    theta = tasks[0].initial_parameters()
    seeds = [21, 22, 23, 24]
    serial = [tasks[0].run(theta, s).reward for s in seeds]
    parallel = [None] * len(seeds)
    inside = [0, 0]  # rollouts running at once, the most seen
    lock = threading.Lock()

    def worker(k):
        for i in range(k, len(seeds), 2):
            with lock:
                inside[0] += 1
                inside[1] = max(inside[1], inside[0])
            parallel[i] = tasks[k].run(theta, seeds[i]).reward
            with lock:
                inside[0] -= 1

    threads = [threading.Thread(target=worker, args=(k,)) for k in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert parallel == serial
    assert inside[1] == 2


def test_one_task_on_two_threads_at_once_is_refused_not_raced():
    task = bs.make_task("fold", FOLD)
    theta = task.initial_parameters()
    errors = []

    def run():
        try:
            task.run(theta, 1)
        except RuntimeError as e:
            errors.append(str(e))

    threads = [threading.Thread(target=run) for _ in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert len(errors) == 1 and "one task per thread" in errors[0]


def test_errors_arrive_as_python_exceptions_with_the_reason():
    with pytest.raises(ValueError, match="unknown"):
        bs.make_task("no_such_task")
    with pytest.raises(ValueError):
        bs.make_task("fold", "/nonexistent/fold.yaml")
    task = bs.make_task("quadratic")
    with pytest.raises(ValueError, match="2\\^32"):
        task.run(task.initial_parameters(), -1)
    # a bad policy is a failed rollout with its reason, not an exception
    r = task.run(np.array([np.nan] * task.initial_parameters().shape[0]), 0)
    assert not r.ok and r.reason
    r = bs.make_task("fold", FOLD).run(np.zeros(3), 0)
    assert not r.ok and r.outcome == "InvalidPolicy" and "coordinated policy" in r.reason
    with pytest.raises(ValueError):
        bs.Reps(epsilon=-1.0)
    with pytest.raises(ValueError):
        bs.Reps().update(np.zeros((5, 2)), np.zeros(4))


def test_reps_and_cma_es_climb_the_quadratic():
    rng = np.random.default_rng(7)
    task = bs.make_task("quadratic")
    n = task.initial_parameters().shape[0]
    for update in ("reps", "cma"):
        mean, cov = np.full(n, 2.0), np.eye(n)
        reps, cma = bs.Reps(epsilon=0.5), bs.CmaEs(cov)
        start = task.run(mean, 0).reward
        for _ in range(30):
            samples = rng.multivariate_normal(mean, cov if update == "reps" else cma.covariance, size=20)
            rewards = np.array([task.run(s, 0).reward for s in samples])
            if update == "reps":
                u = reps.update(samples, rewards)
                mean, cov = u.mean, u.covariance
                assert u.kl <= 0.5 + 1e-6 and abs(u.weights.sum() - 1.0) < 1e-12
            else:
                mean = cma.step(mean, samples, rewards)
        assert task.run(mean, 0).reward > 0.7 * start, update  # 30 % of the way to the optimum (0) at least


def test_a_dmp_fitted_from_python_reproduces_its_demonstration():
    t = np.linspace(0.0, 1.0, 201)
    demo = np.column_stack([10 * t**3 - 15 * t**4 + 6 * t**5, np.sin(np.pi * t) ** 2])  # minimum jerk; a bump
    dmp = bs.Dmp.fit(demo, 0.005, kernels=30)
    assert dmp.weights.shape == (2, 30) and dmp.duration == pytest.approx(1.0)
    assert np.allclose(dmp.start, demo[0]) and np.allclose(dmp.goal, demo[-1])
    path = dmp.path(0.005)
    assert path.shape == demo.shape
    assert np.abs(path - demo).max() < 0.02
    # Without its forcing term the DMP is a spring to the goal: no bump.
    spring = dmp.with_weights(np.zeros((2, 30))).path(0.005)
    assert np.abs(spring[:, 1] - demo[:, 1]).max() > 0.5
    with pytest.raises(ValueError, match="unstable"):
        dmp.path(0.5)
    with pytest.raises(ValueError):
        bs.Dmp.fit(demo[:5], 0.005)
    with pytest.raises(ValueError):
        dmp.with_weights(np.zeros((3, 30)))


def test_dual_reps_without_clusters_is_the_reps_update_and_with_them_takes_the_better_mode():
    rng = np.random.default_rng(5)
    mean, covariance = np.zeros(2), np.eye(2)
    samples = rng.multivariate_normal(mean, covariance, size=40)
    # Two modes, at (1.5, 0) (the higher) and (-1.5, 0).
    rewards = np.maximum(np.exp(-np.sum((samples - [1.5, 0.0]) ** 2, axis=1)),
                         0.7 * np.exp(-np.sum((samples + [1.5, 0.0]) ** 2, axis=1)))
    plain = bs.DualReps(epsilon=0.5, clusters=0).update(mean, covariance, samples, rewards)
    assert plain.plain_reps or not plain.clusters
    reps = bs.Reps(epsilon=0.5).update(samples, rewards)
    assert np.allclose(plain.policy.mean, reps.mean, atol=1e-9)
    dual = bs.DualReps(epsilon=0.5).update(mean, covariance, samples, rewards)
    attractive = [c for c in dual.clusters if c.attractive]
    assert len(attractive) == 1 and attractive[0].mean[0] > 0.8  # the cluster at the higher mode
    assert any(not c.attractive for c in dual.clusters)
    assert dual.policy.mean[0] > 0.0  # towards the higher mode
    with pytest.raises(ValueError):
        bs.DualReps().update(mean, covariance, samples, rewards[:3])


def test_pi2_lowers_the_cost_of_a_policy_linear_in_its_basis():
    rng = np.random.default_rng(2)
    steps, kernels = 50, 5
    t = np.linspace(0.0, 1.0, steps)
    centres = np.linspace(0.0, 1.0, kernels)
    basis = np.exp(-0.5 * (t[:, None] - centres[None, :]) ** 2 / 0.02)
    basis /= basis.sum(axis=1, keepdims=True)
    target = np.sin(2 * np.pi * t)

    def cost(w):
        return (basis @ w - target) ** 2

    mean, covariance = np.zeros(kernels), np.eye(kernels)
    for _ in range(15):
        samples = rng.multivariate_normal(mean, covariance, size=10)
        costs = np.array([cost(w) for w in samples])
        mean, covariance, probabilities = bs.pi2_update(mean, covariance, samples, costs, basis,
                                                        covariance_adaptation=True)
        assert probabilities.shape == (steps, 10)
        assert np.allclose(probabilities.sum(axis=1), 1.0)
    assert cost(mean).sum() < 0.5 * cost(np.zeros(kernels)).sum()
    with pytest.raises(ValueError):
        bs.pi2_update(mean, covariance, samples, costs[:, :3], basis)


def test_a_promp_fitted_from_python_has_the_demonstrations_mean_and_spread_and_takes_a_via_point():
    rng = np.random.default_rng(4)
    t = np.linspace(0.0, 1.0, 101)
    amplitudes = rng.normal(1.0, 0.1, size=12)
    demos = [np.column_stack([a * np.sin(np.pi * t), 0.5 * t]) for a in amplitudes]
    promp = bs.ProMp.fit(demos, duration=2.0, kernels=15)
    assert promp.dofs == 2 and promp.kernels == 15 and promp.weight_mean.shape == (30,)
    position, velocity, deviation = promp.path(101)
    assert np.abs(position[:, 0] - amplitudes.mean() * np.sin(np.pi * t)).max() < 0.01
    # the spread at the middle is the amplitudes' (their sample standard deviation), none on the second DoF's line
    assert deviation[50, 0] == pytest.approx(amplitudes.std(ddof=1), rel=0.05)
    assert deviation[50, 1] < 0.01
    # velocities in time: d/dt of 0.5 t over 2 s is 0.25 per second
    assert velocity[50, 1] == pytest.approx(0.25, rel=0.02)
    via = promp.conditioned(0.5, np.array([1.3, 0.25]), 1e-6 * np.eye(2))
    assert np.allclose(via.path(101)[0][50], [1.3, 0.25], atol=1e-3)
    assert np.array_equal(promp.sample(seed=3), promp.sample(seed=3))
    assert not np.array_equal(promp.sample(seed=3), promp.sample(seed=4))
    with pytest.raises(ValueError):
        bs.ProMp.fit(demos[:1], duration=2.0)
    with pytest.raises(ValueError):
        promp.with_mean(np.zeros(3))


def test_a_robot_file_reads_as_bullet_sim_reads_it():
    sim = os.path.join(SOURCE, "config", "sim.yaml")
    wam = bs.robot(sim)
    assert [a["name"] for a in wam["arms"]] == ["left", "right"]
    assert all(a["start"].shape == (7,) for a in wam["arms"]) and wam["has_cloth"]
    assert wam["urdf"].endswith(".urdf") and os.path.exists(wam["urdf"])
    other = bs.robot(sim, os.path.join(SOURCE, "config", "robots", "offset_wrist.yaml"))
    assert other["robot_file"].endswith("offset_wrist.yaml") and other["urdf"] != wam["urdf"]
    with pytest.raises(ValueError, match="nope.yaml"):
        bs.robot(sim, "/nope.yaml")

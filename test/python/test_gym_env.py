"""The cloth fold as a Gymnasium environment (bimanual_skills.gym_env.FoldEnv): Gymnasium's own checker, seeded
resets that perturb the cloth's start, an episode that is the C++ rollout bit for bit, SoftGym's normalised
performance recomputed from the fold quality's definition, the images as views without copies, and bad calls as
errors. Run by make test with build/venv's Python (gymnasium from PyPI, python/requirements.txt)."""
import os
import warnings

import numpy as np
import pytest

import bimanual_skills as bs

gymnasium = pytest.importorskip("gymnasium", reason="gymnasium is in build/venv (make venv)")
from gymnasium.utils.env_checker import check_env  # noqa: E402

from bimanual_skills import gym_env  # noqa: E402, F401  (registers the environment)

SOURCE = os.environ.get("BIMANUAL_SKILLS_SOURCE_DIR", os.path.join(os.path.dirname(__file__), "..", ".."))
FOLD = os.path.join(SOURCE, "config", "fold_demo.yaml")


@pytest.fixture(scope="module")
def env():
    e = gymnasium.make("bimanual_skills/ClothFold-v0", config=FOLD, render_mode="rgb_array")
    yield e
    e.close()


def test_gymnasiums_checker_passes_without_a_warning(env):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(env.unwrapped)
    assert [str(w.message) for w in caught] == []


def test_a_seed_gives_one_start_and_other_seeds_move_the_cloth(env):
    first, info = env.reset(seed=7)
    again, info_again = env.reset(seed=7)
    assert info["seed"] == info_again["seed"] and info["noise"] == "robot"
    assert np.array_equal(first["rgb"], again["rgb"]) and np.array_equal(first["depth"], again["depth"])
    assert env.observation_space.contains(first)
    # The cloth (blue: B well above R) lies elsewhere for another seed: its pixels' centroid moves.
    def centroid(obs):
        rgb = obs["rgb"].astype(int)
        rows, cols = np.nonzero(rgb[:, :, 2] - rgb[:, :, 0] > 80)
        assert rows.size > 1000
        return np.array([rows.mean(), cols.mean()])

    moved = [np.linalg.norm(centroid(env.reset(seed=s)[0]) - centroid(first)) for s in (8, 9, 10)]
    assert max(moved) > 1.0, moved  # pixels; 1 cm on the table is about 2 here
    # Without the robot's noise every seed starts from the same cloth (only the camera's noise differs).
    still = gym_env.FoldEnv(config=FOLD, noise="none")
    a, _ = still.reset(seed=8)
    b, _ = still.reset(seed=9)
    assert np.linalg.norm(centroid(a) - centroid(b)) < 0.2


def test_an_episode_is_the_c_plus_plus_rollout_bit_for_bit(env):
    obs, info = env.reset(seed=11)
    action = np.linspace(-0.5, 0.5, env.action_space.shape[0]).astype(np.float32)
    final, reward, terminated, truncated, step_info = env.step(action)
    assert terminated and not truncated
    task = bs.FoldTask(FOLD, "robot")
    scale = 3.0 * np.asarray(task.latent_weight_stddev())
    parameters = task.parameters_for(action.astype(np.float64) * scale)
    assert np.array_equal(parameters, step_info["parameters"])
    direct = task.run(parameters, info["seed"])
    assert direct.reward == reward and direct.outcome == step_info["outcome"] == "Ok"
    assert step_info["q"] == dict(zip(task.term_names(), direct.terms))["fold_quality"]
    bgr, depth = task.images()
    assert np.array_equal(final["rgb"], bgr[:, :, ::-1]) and np.array_equal(final["depth"], depth)
    assert np.array_equal(env.render(), final["rgb"])
    # the start: the same seed's picture
    task.render_start(info["seed"])
    start_bgr, _ = task.start_images()
    assert np.array_equal(obs["rgb"], start_bgr[:, :, ::-1])


def test_the_normalised_performance_is_softgyms_and_agrees_with_q(env):
    _, info = env.reset(seed=12)
    _, _, _, _, out = env.step(np.zeros(env.action_space.shape, np.float32))
    terms = out["terms"]
    p = -(terms["fold_distance"] + 1.2 * terms["fold_displacement"])
    p0 = out["performance_start"]
    assert p0 < 0.0 and out["performance"] == p
    assert out["normalized_performance"] == pytest.approx((p - p0) / (0.0 - p0), abs=1e-15)
    # q = (d_flat - (d + 1.2 s)) / (d_flat - thickness) (tasks::foldQuality): SoftGym's normalisation differs from it
    # only by the ideal fold's thickness.
    thickness = env.unwrapped.task.thickness
    d_flat = -p0
    assert out["normalized_performance"] == pytest.approx(out["q"] * (d_flat - thickness) / d_flat, abs=1e-12)
    assert 0.3 < out["normalized_performance"] < 1.0


def test_the_images_are_read_only_views_of_the_tasks_buffers():
    task = bs.FoldTask(FOLD, "none")
    assert task.render_start(3) == "Ok"
    bgr, depth = task.start_images()
    again, _ = task.start_images()
    assert np.shares_memory(bgr, again) and not bgr.flags.owndata and not bgr.flags.writeable
    assert bgr.dtype == np.uint8 and bgr.shape[2] == 3 and depth.dtype == np.float32 and depth.shape == bgr.shape[:2]
    before = bgr.copy()
    task.render_start(4)  # the camera's noise of another seed, into the same buffer
    assert not np.array_equal(before, bgr)
    # The start measured against itself: q 0, nothing displaced; the halves' distance does not depend on where the
    # robot's noise lays the cloth.
    noisy = bs.FoldTask(FOLD, "robot")
    start, other = noisy.start_fold(3), noisy.start_fold(4)
    assert start["q"] == 0.0 and start["displacement"] == 0.0 and start["distance"] > 0.1
    assert other["distance"] == pytest.approx(start["distance"], abs=1e-12)


def test_bad_calls_are_errors_with_the_reason(env):
    fresh = gym_env.FoldEnv(config=FOLD)
    with pytest.raises(RuntimeError, match="reset"):
        fresh.step(np.zeros(fresh.action_space.shape, np.float32))
    fresh.reset(seed=1)
    with pytest.raises(ValueError, match="252 finite values"):
        fresh.step(np.zeros(3, np.float32))
    with pytest.raises(ValueError, match="NaN or Inf"):
        fresh.step(np.full(fresh.action_space.shape, np.nan, np.float32))
    fresh.step(np.zeros(fresh.action_space.shape, np.float32))
    with pytest.raises(RuntimeError, match="reset"):
        fresh.step(np.zeros(fresh.action_space.shape, np.float32))  # an episode is one rollout
    with pytest.raises(ValueError, match="noise"):
        gym_env.FoldEnv(config=FOLD, noise="loud")
    with pytest.raises(ValueError, match="action_scale"):
        gym_env.FoldEnv(config=FOLD, action_scale=float("nan"))
    with pytest.raises(ValueError, match="render_mode"):
        gym_env.FoldEnv(config=FOLD, render_mode="human")
    with pytest.raises(ValueError, match="seed"):
        bs.FoldTask(FOLD).render_start(-1)


# The step-by-step variant (FoldJointEnv): joint-space actions at the control rate.

def test_the_joint_space_environment_passes_gymnasiums_checker():
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(gymnasium.make("bimanual_skills/ClothFoldJoint-v0", config=FOLD).unwrapped)
    assert [str(w.message) for w in caught] == []


def test_streaming_the_plans_velocities_folds_as_the_episodic_rollout():
    env = gym_env.FoldJointEnv(config=FOLD, action_scale=1.0)
    task = env.task
    plan = task.plan(task.initial_parameters())
    assert plan["outcome"] == "Ok" and plan["release"] == task.stepped_periods == 4500

    def episode(seed):
        obs, info = env.reset(seed=seed)
        assert env.observation_space.contains(obs) and obs["progress"][0] == 0.0
        start_q = obs["joint_position"].copy()
        for k in range(task.stepped_periods):
            obs, reward, terminated, truncated, out = env.step(plan["velocity"][k + 1] / env.velocity_scale)
            assert not truncated and terminated == (k == task.stepped_periods - 1)
            if not terminated:
                assert reward == 0.0 and out == {}
        assert env.observation_space.contains(obs)
        return start_q, obs, reward, out, info["seed"]

    start_q, obs, reward, out, seed = episode(21)
    assert np.allclose(start_q, plan["position"][0], atol=1e-6)  # the arms at the start, at rest
    direct = task.run(task.initial_parameters(), seed)
    direct_q = dict(zip(task.term_names(), direct.terms))["fold_quality"]
    assert out["outcome"] == "Ok" and out["seed"] == seed
    assert abs(out["q"] - direct_q) < 0.01, (out["q"], direct_q)
    assert abs(reward - direct.reward) < 0.01, (reward, direct.reward)
    assert 0.3 < out["normalized_performance"] < 1.0
    assert obs["progress"][0] == 1.0
    # The same seed and actions, the same episode, bit for bit.
    _, again, reward_again, out_again, _ = episode(21)
    assert reward_again == reward and out_again["q"] == out["q"]
    assert all(np.array_equal(again[k], obs[k]) for k in obs)


def test_random_joint_actions_end_with_an_outcome_and_frame_skip_holds_them():
    env = gym_env.FoldJointEnv(config=FOLD, frame_skip=100)
    obs, _ = env.reset(seed=4)
    env.action_space.seed(4)
    steps = 0
    while True:
        obs, reward, terminated, truncated, out = env.step(env.action_space.sample())
        steps += 1
        assert env.observation_space.contains(obs) and np.isfinite(reward) and not truncated
        if terminated:
            break
    assert steps <= 45  # 4500 periods, 100 per step
    assert out["outcome"] in ("Ok", "ControllerFailed", "SimulationDiverged")
    assert out["outcome"] == "Ok" or out["reason"]
    assert np.isfinite(out["normalized_performance"])


def test_bad_joint_space_calls_are_errors_with_the_reason():
    env = gym_env.FoldJointEnv(config=FOLD, frame_skip=1000)
    with pytest.raises(RuntimeError, match="reset"):
        env.step(np.zeros(14, np.float32))
    env.reset(seed=1)
    with pytest.raises(ValueError, match="14 finite values"):
        env.step(np.zeros(13, np.float32))
    with pytest.raises(ValueError, match="NaN or Inf"):
        env.step(np.full(14, np.inf, np.float32))
    for _ in range(5):
        *_, terminated, _, out = env.step(np.zeros(14, np.float32))
    assert terminated and out["outcome"] == "Ok"
    with pytest.raises(RuntimeError, match="reset"):
        env.step(np.zeros(14, np.float32))
    with pytest.raises(ValueError, match="action_scale"):
        gym_env.FoldJointEnv(config=FOLD, action_scale=2.0)
    with pytest.raises(ValueError, match="frame_skip"):
        gym_env.FoldJointEnv(config=FOLD, frame_skip=0)
    task = bs.FoldTask(FOLD)
    with pytest.raises(RuntimeError, match="beginSteps"):
        task.step(np.zeros(14))
    assert task.begin_steps(1) == "Ok"
    assert task.step(np.full(14, np.nan)) == "InvalidPolicy"
    assert "NaN" in task.finish_steps().reason
    with pytest.raises(ValueError, match="coordinated policy"):
        task.plan(np.full(task.initial_parameters().shape, np.nan))
    policy = np.array(task.initial_parameters())
    policy[-1] = np.nan  # a weight: the encoding decodes, the plan fails
    bad = task.plan(policy)
    assert bad["outcome"] == "InvalidPolicy" and bad["position"] is None and bad["reason"]

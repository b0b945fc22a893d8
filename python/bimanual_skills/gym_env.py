"""The cloth fold as a Gymnasium environment (needs gymnasium: build/venv, `make venv`).

An episode is one rollout, as the learners use the task (an episodic environment for black-box policy search):

    import gymnasium as gym
    import bimanual_skills.gym_env  # registers bimanual_skills/ClothFold-v0
    env = gym.make("bimanual_skills/ClothFold-v0")
    obs, info = env.reset(seed=1)              # the camera's picture of the flat cloth where this episode lays it
    obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
    print(reward, info["q"], info["normalized_performance"])

Observation: the RGB-D camera's images, {"rgb": uint8 H x W x 3, "depth": float32 H x W [m]}; after reset() the
start (the flat cloth), after step() the fold the reward scored. Action: the policy's latent weights for the rollout
as offsets from the demonstration's, in [-1, 1] per weight, scaled by action_scale times the learning file's starting
exploration (bimanual_skills.FoldTask.latent_weight_stddev; Omega = I). Reward: the learning file's (the camera
reward, thesis (7.52)). Each step is one whole rollout, terminated after it. reset(seed=S) draws the episode's
rollout seed from S: the cloth's start perturbed by the robot's repeatability (noise="robot": 1 cm, 0.035 rad, the
grippers' release by 0.05 s) and the camera's noise; the same seed and action give the same episode.

info after step(): q (the fold quality, 1 the ideal fold, 0 the flat start), terms (every reward term by name),
outcome and reason, SoftGym's ClothFold performance -(distance + 1.2 displacement) [m] and normalized_performance
(performance - performance_start) / (0 - performance_start) (Lin et al. 2020: 0 the start, 1 the halves on each
other), seed (the rollout's) and parameters (the policy run). A rollout that failed before its cloth was measured
scores as its start (performance_start, normalized 0).

The step-by-step variant, bimanual_skills/ClothFoldJoint-v0 (FoldJointEnv), drives the same rollout one control
period (1 ms) at a time with joint-space actions, for step-by-step policies (reinforcement learning, imitation):

    env = gym.make("bimanual_skills/ClothFoldJoint-v0")
    obs, info = env.reset(seed=1)                  # the arms at the start, the cloth grasped at its far corners
    while True:
        obs, reward, terminated, truncated, info = env.step(policy(obs))
        if terminated: break                      # the grippers opened, the cloth settled, the fold scored

Action: both arms' commanded joint velocities, 14 values in [-1, 1] (left arm's joints 1-7, then the right's) times
action_scale times the URDF's velocity limits; the reference reaches them at most at the task's step acceleration
(4 rad/s^2), slows to stop at a position limit, and the controllers (the robot path's computed-torque law) track it
from the next period on. Each step holds an action for frame_skip periods (1: the control rate). Observation:
joint_position and joint_velocity (14 each, as the controllers measured them at the start of the last period, one
period older than the rest), tool_position (both tools, 6, world [m]), cloth_corners (the mesh's four corners, 12, world [m], the ground truth SoftGym's key-point observation gives)
and progress (the fraction of the driven periods done). The episode drives hold_before + duration + hold_after
(4.5 s: 4500 periods at frame_skip 1); then, in the same step, the cloth settles and the camera reward scores it.
The grippers open when the episodic rollout's would: at the end of the driven periods moved by the robot's noise
(noise="robot": sigma 0.05 s, cut at 3 sigma), so up to 0.15 s early, while the last actions still drive the arms. Reward: 0 until then, the learning file's reward in the last step
(the episodic environment's for the same motion); info then has q, terms, outcome and the normalised performance as
above. A controller's stop or a diverging simulation ends the episode early with its outcome and that reward.
"""
import gymnasium
import numpy as np
from gymnasium import spaces

from bimanual_skills import FoldTask, config_path

# SoftGym's ClothFold weight of the staying half's displacement (its performance, Lin et al. 2020).
_FIXATION_WEIGHT = 1.2


class FoldEnv(gymnasium.Env):
    """The fold of a learning file (default config/fold_demo.yaml), one rollout per episode."""

    metadata = {"render_modes": ["rgb_array"], "render_fps": 1}

    def __init__(self, config=None, noise="robot", action_scale=3.0, render_mode=None):
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError("render_mode %r: FoldEnv renders only 'rgb_array'" % (render_mode,))
        if not (np.isfinite(action_scale) and action_scale > 0.0):
            raise ValueError("action_scale must be a finite number > 0, not %r" % (action_scale,))
        self.render_mode = render_mode
        self._task = FoldTask(config or config_path("fold_demo.yaml"), noise)
        self._scale = float(action_scale) * np.asarray(self._task.latent_weight_stddev(), dtype=np.float64)
        self._names = self._task.term_names()
        self._task.render_start(0)
        rgb, depth = self._task.start_images()
        height, width = depth.shape
        self.action_space = spaces.Box(-1.0, 1.0, shape=self._scale.shape, dtype=np.float32)
        self.observation_space = spaces.Dict({
            "rgb": spaces.Box(0, 255, shape=(height, width, 3), dtype=np.uint8),
            "depth": spaces.Box(0.0, 100.0, shape=(height, width), dtype=np.float32),
        })
        self._rollout_seed = None
        self._observation = None
        self._performance_start = None

    @property
    def task(self):
        """The bimanual_skills.FoldTask the episodes run on."""
        return self._task

    def parameters(self, action):
        """The policy an action runs (bimanual_skills.FoldTask.parameters_for its scaled offsets)."""
        a = np.asarray(action, dtype=np.float64)
        if a.shape != self._scale.shape or not np.all(np.isfinite(a)):
            raise ValueError("an action is %d finite values in [-1, 1], not shape %s%s" %
                             (self._scale.size, a.shape, "" if np.all(np.isfinite(a)) else " with NaN or Inf"))
        return self._task.parameters_for(np.clip(a, -1.0, 1.0) * self._scale)

    def _images(self, rgb_bgr, depth):
        # The task's buffers are views the next rollout writes over: the observation owns copies, in RGB order.
        return {"rgb": np.ascontiguousarray(rgb_bgr[:, :, ::-1]), "depth": np.array(depth, dtype=np.float32)}

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        self._rollout_seed = int(self.np_random.integers(0, 2**32))
        status = self._task.render_start(self._rollout_seed)
        if status != "Ok":
            raise RuntimeError("the camera does not see the cloth's start: %s" % status)
        self._observation = self._images(*self._task.start_images())
        self._performance_start = -self._task.start_fold(self._rollout_seed)["distance"]
        return self._observation, {"seed": self._rollout_seed, "noise": self._task.noise}

    def step(self, action):
        if self._rollout_seed is None:
            raise RuntimeError("FoldEnv: call reset() before step(): an episode is one rollout")
        parameters = self.parameters(action)
        seed, self._rollout_seed = self._rollout_seed, None
        result = self._task.run(parameters, seed)
        self._observation = self._images(*self._task.images())
        info = _fold_info(result, self._names, self._performance_start, seed)
        info["parameters"] = np.asarray(parameters)
        return self._observation, float(result.reward), True, False, info

    def render(self):
        if self.render_mode != "rgb_array" or self._observation is None:
            return None
        return self._observation["rgb"].copy()


def _fold_info(result, names, performance_start, seed):
    """What both environments tell of a finished rollout (the module's docstring)."""
    terms = dict(zip(names, (float(t) for t in result.terms)))
    if result.ok:
        performance = -(terms["fold_distance"] + _FIXATION_WEIGHT * terms["fold_displacement"])
    else:
        performance = performance_start
    return {
        "q": terms["fold_quality"],
        "terms": terms,
        "outcome": result.outcome,
        "reason": result.reason,
        "performance": performance,
        "performance_start": performance_start,
        "normalized_performance": (performance - performance_start) / (0.0 - performance_start),
        "seed": seed,
    }


class FoldJointEnv(gymnasium.Env):
    """The fold of a learning file driven period by period by joint-space actions (the module's docstring)."""

    metadata = {"render_modes": []}

    def __init__(self, config=None, noise="robot", action_scale=0.5, frame_skip=1):
        if not (np.isfinite(action_scale) and 0.0 < action_scale <= 1.0):
            raise ValueError("action_scale must be in (0, 1] (a fraction of the velocity limits), not %r" %
                             (action_scale,))
        if int(frame_skip) != frame_skip or not 1 <= frame_skip <= 1000:
            raise ValueError("frame_skip must be a whole number of periods in [1, 1000], not %r" % (frame_skip,))
        self._task = FoldTask(config or config_path("fold_demo.yaml"), noise)
        self._frame_skip = int(frame_skip)
        self._names = self._task.term_names()
        limits = self._task.joint_limits()
        self._velocity_scale = float(action_scale) * np.asarray(limits["velocity"], dtype=np.float64)
        self._periods = self._task.stepped_periods
        self._corners = self._corner_indices(*self._task.cloth_nodes)
        margin = 0.5  # [rad]: a measured position may pass a limit a little
        self.action_space = spaces.Box(-1.0, 1.0, shape=(14,), dtype=np.float32)
        self.observation_space = spaces.Dict({
            "joint_position": spaces.Box((limits["lower"] - margin).astype(np.float32),
                                         (limits["upper"] + margin).astype(np.float32), dtype=np.float32),
            "joint_velocity": spaces.Box((-3.0 * limits["velocity"]).astype(np.float32),
                                         (3.0 * limits["velocity"]).astype(np.float32), dtype=np.float32),
            "tool_position": spaces.Box(-10.0, 10.0, shape=(6,), dtype=np.float32),
            "cloth_corners": spaces.Box(-10.0, 10.0, shape=(12,), dtype=np.float32),
            "progress": spaces.Box(0.0, 1.0, shape=(1,), dtype=np.float32),
        })
        self._rollout_seed = None
        self._performance_start = None

    @staticmethod
    def _corner_indices(nodes_x, nodes_y):
        return [0, nodes_x - 1, nodes_x * (nodes_y - 1), nodes_x * nodes_y - 1]

    @property
    def task(self):
        """The bimanual_skills.FoldTask the episodes run on."""
        return self._task

    @property
    def velocity_scale(self):
        """What an action of 1 commands per joint [rad/s] (action_scale times the velocity limits)."""
        return self._velocity_scale.copy()

    def _observation(self):
        q, qd = self._task.joint_state()
        corners = np.asarray(self._task.cloth_vertices())[:, self._corners]
        obs = {
            "joint_position": q,
            "joint_velocity": qd,
            "tool_position": np.asarray(self._task.tool_positions()).reshape(6),
            "cloth_corners": corners.T.reshape(12),
            "progress": np.array([min(1.0, self._task.stepped_period / self._periods)]),
        }
        return {k: np.clip(v, self.observation_space[k].low, self.observation_space[k].high).astype(np.float32)
                for k, v in obs.items()}

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        self._rollout_seed = int(self.np_random.integers(0, 2**32))
        outcome = self._task.begin_steps(self._rollout_seed)
        if outcome != "Ok":
            result = self._task.finish_steps()
            raise RuntimeError("the episode's rollout cannot start: %s: %s" % (outcome, result.reason))
        self._performance_start = -self._task.start_fold(self._rollout_seed)["distance"]
        return self._observation(), {"seed": self._rollout_seed, "noise": self._task.noise, "periods": self._periods}

    def step(self, action):
        if self._rollout_seed is None:
            raise RuntimeError("FoldJointEnv: call reset() before step(): the episode has ended")
        a = np.asarray(action, dtype=np.float64)
        if a.shape != (14,) or not np.all(np.isfinite(a)):
            raise ValueError("an action is 14 finite values in [-1, 1], not shape %s%s" %
                             (a.shape, "" if np.all(np.isfinite(a)) else " with NaN or Inf"))
        velocity = np.clip(a, -1.0, 1.0) * self._velocity_scale
        for _ in range(self._frame_skip):
            if not self._task.stepping or self._task.step(velocity) != "Ok":
                break
        if self._task.stepping:
            return self._observation(), 0.0, False, False, {}
        seed, self._rollout_seed = self._rollout_seed, None
        result = self._task.finish_steps()
        info = _fold_info(result, self._names, self._performance_start, seed)
        return self._observation(), float(result.reward), True, False, info


# No time limit: the environments terminate each episode themselves (the episodic one after its one step).
gymnasium.register(id="bimanual_skills/ClothFold-v0", entry_point="bimanual_skills.gym_env:FoldEnv")
gymnasium.register(id="bimanual_skills/ClothFoldJoint-v0", entry_point="bimanual_skills.gym_env:FoldJointEnv")

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
        terms = dict(zip(self._names, (float(t) for t in result.terms)))
        start = self._performance_start
        if result.ok:
            performance = -(terms["fold_distance"] + _FIXATION_WEIGHT * terms["fold_displacement"])
        else:
            performance = start
        self._observation = self._images(*self._task.images())
        info = {
            "q": terms["fold_quality"],
            "terms": terms,
            "outcome": result.outcome,
            "reason": result.reason,
            "performance": performance,
            "performance_start": start,
            "normalized_performance": (performance - start) / (0.0 - start),
            "seed": seed,
            "parameters": np.asarray(parameters),
        }
        return self._observation, float(result.reward), True, False, info

    def render(self):
        if self.render_mode != "rgb_array" or self._observation is None:
            return None
        return self._observation["rgb"].copy()


# No time limit: the environment terminates each episode itself, after its one step.
gymnasium.register(id="bimanual_skills/ClothFold-v0", entry_point="bimanual_skills.gym_env:FoldEnv")

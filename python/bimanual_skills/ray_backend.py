"""Rollouts on Ray: the learners' third backend beside threads and ROS rollout workers.

    import bimanual_skills as bs
    from bimanual_skills.ray_backend import RayEvaluator
    evaluator = RayEvaluator("fold", bs.config_path("fold_demo.yaml"))      # ray.init() here, or address="HOST:PORT"
    bs.learn_fold(bs.config_path("fold_demo.yaml"), "build/fold_ray", evaluator=evaluator)

Each rollout is a Ray task; a worker process keeps one simulator per (task, file) between them. A rollout's result
depends only on its parameters and seed, so the learning's results are the in-process ones for any number of
workers. A worker that dies mid-rollout (killed, out of memory, its host gone) has its rollout run again by Ray
(max_retries); the learner records each rollout once, as it is reported. Workers start with the pinned numerics'
environment (bimanual_skills.pinned_environment()), so their rollouts equal the C++ programs' bit for bit.
Ray comes from PyPI (pinned in python/requirements.txt) into the virtual environment `make venv` makes."""
import os

import ray

import bimanual_skills as bs

_tasks = {}


@ray.remote
def _rollout(name, config, parameters, seed):
    key = (name, config)
    if key not in _tasks:
        _tasks[key] = bs.make_task(name, config)
    return _tasks[key].run(parameters, seed)


def init(address=None, workers=None, **kwargs):
    """ray.init() as the backend needs it: no dashboard, no usage statistics, the workers' numerics pinned.
    address None: a new local Ray of `workers` CPUs (None: all), even when a cluster runs on this machine; "auto" or
    "HOST:PORT": a running cluster."""
    os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")
    if ray.is_initialized():
        return
    options = dict(include_dashboard=False, runtime_env={"env_vars": bs.pinned_environment()}, log_to_driver=False)
    if address is None:
        options["address"] = "local"  # not a cluster found in RAY_ADDRESS or /tmp/ray (ray.init's default)
        options["num_cpus"] = workers
    else:
        options["address"] = address
    options.update(kwargs)
    ray.init(**options)


class RayEvaluator:
    """An evaluator for bimanual_skills.learn_fold(): the batch's rollouts as Ray tasks of the registry task `name`
    configured by `config` (a path every Ray node can read), reported as they finish."""

    def __init__(self, name, config, address=None, workers=None, max_retries=3):
        init(address=address, workers=workers)
        self.name, self.config, self.max_retries = name, config, max_retries

    def __call__(self, requests, done):
        refs = [_rollout.options(max_retries=self.max_retries).remote(self.name, self.config, p, int(s))
                for p, s in requests]
        index = {ref: i for i, ref in enumerate(refs)}
        results = [None] * len(refs)
        pending = list(refs)
        try:
            while pending:
                ready, pending = ray.wait(pending, num_returns=1)
                i = index[ready[0]]
                results[i] = ray.get(ready[0])
                done(i, results[i])  # raises RuntimeError("stopped") when the learner stops
        except BaseException:
            for ref in pending:  # a stopped learning leaves no rollouts running on the cluster
                try:
                    ray.cancel(ref, force=True)
                except Exception:  # noqa: BLE001 - the first error is the one to raise
                    pass
            raise
        return results

    def map(self, requests):
        """The results of (parameters, seed) requests, in order, without a learner."""
        return ray.get([_rollout.options(max_retries=self.max_retries).remote(self.name, self.config, p, int(s))
                        for p, s in requests])

"""bimanual_skills from Python: the C++ core's rollout tasks (the cloth fold, the scarf, the bottles on the simulated
WAM and the policy-search benchmarks), the fold with its camera images (FoldTask; the Gymnasium environment is
bimanual_skills.gym_env), DMPs and ProMPs, the policy updates (REPS, Dual REPS, PI2 and PI2-CMA, CMA-ES) and what a
robot file says (robot()), with NumPy arrays in and out. The ROS messages are bimanual_skills.msg and
bimanual_skills.srv, as for every ROS package.

    import bimanual_skills as bs
    task = bs.make_task("fold", bs.config_path("fold_demo.yaml"))
    result = task.run(task.initial_parameters(), seed=1)   # releases Python's lock while it runs
    print(result.reward, dict(zip(task.term_names(), result.terms)))
"""
import os as _os

from bimanual_skills._core import (  # noqa: F401
    CmaEs,
    Dmp,
    DualReps,
    DualRepsUpdate,
    FoldTask,
    ProMp,
    Reps,
    RepsUpdate,
    RolloutResult,
    Task,
    learn_dmp,
    learn_fold,
    make_task,
    numerics,
    pi2_update,
    pinned_environment,
    robot,
    tasks,
)

__all__ = ["CmaEs", "Dmp", "DualReps", "DualRepsUpdate", "FoldTask", "ProMp", "Reps", "RepsUpdate", "RolloutResult",
           "Task", "config_path", "learn_dmp", "learn_fold", "make_task", "numerics", "pi2_update", "pin_numerics",
           "pinned_environment", "robot", "tasks"]

_PINNED_MARKER = "BIMANUAL_SKILLS_NUMERICS_PINNED"


def pin_numerics():
    """As the C++ programs do at start: when libm or OpenCV run this CPU's own code (numerics() is not "pinned"),
    executes this Python program again with pinned_environment() set, so that its rollouts equal the C++ programs'
    bit for bit; does not return then. Call it first, before anything computes. Returns (with a warning) when the
    re-executed program is still not pinned."""
    import sys
    import warnings

    if numerics() == "pinned":
        return
    if _os.environ.get(_PINNED_MARKER):
        warnings.warn("bimanual_skills: numerics not pinned after re-executing (%s)" % numerics())
        return
    env = dict(_os.environ)
    for key, value in pinned_environment().items():
        old = env.get(key, "")
        env[key] = value if not old else old + (":" if key == "GLIBC_TUNABLES" else ",") + value
    env[_PINNED_MARKER] = "1"
    argv = sys.orig_argv if hasattr(sys, "orig_argv") else [sys.executable] + sys.argv
    sys.stdout.flush()
    sys.stderr.flush()
    _os.execve(sys.executable, argv, env)


def config_path(name):
    """The path of one of the package's configuration files (its config/ folder), e.g. "fold_demo.yaml"."""
    here = _os.path.dirname(_os.path.abspath(__file__))
    # install/bimanual_skills/lib/python3/dist-packages/bimanual_skills -> install/bimanual_skills/share/...
    prefix = _os.path.abspath(_os.path.join(here, "..", "..", "..", ".."))
    folders = [_os.path.join(prefix, "share", "bimanual_skills", "config")]
    try:  # a devel space or another layout: where ROS finds the package
        import rospkg

        folders.append(_os.path.join(rospkg.RosPack().get_path("bimanual_skills"), "config"))
    except Exception:  # noqa: BLE001 - rospkg missing or the package not on ROS_PACKAGE_PATH
        pass
    for folder in folders:
        path = _os.path.join(folder, name)
        if _os.path.exists(path):
            return path
    raise FileNotFoundError("no configuration file %s in %s" % (name, " or ".join(folders)))

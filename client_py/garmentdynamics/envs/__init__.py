"""Gymnasium environments over gd-server scenes (needs `pip install garmentdynamics[gym]`).

- GarmentEnv: one scene as a gymnasium.Env (passes gymnasium.utils.env_checker.check_env).
- GarmentVectorEnv: N scenes as a gymnasium.vector.VectorEnv, stepped in one batched call,
  autoreset NEXT_STEP.
- RayVectorEnv: the same over several servers (garmentdynamics.ray_servers' actors on a Ray
  cluster, or addresses), stepped concurrently; a lost server's episodes are cut and run again
  elsewhere (the `[ray]` extra for actors).

Actions are the arms' end-effector poses, (2, 8); in robot mode (mode="robot", the Piper arms of
a URDF) control="joints" takes each arm's joint targets and gripper opening, (2, J + 1), instead.

Both are registered with Gymnasium as "garmentdynamics/Garment-v0" (gymnasium.make) and
"garmentdynamics/Garment-v0" with gymnasium.make_vec(..., vectorization_mode="vector_entry_point").
"""

try:
    import gymnasium  # noqa: F401
except ImportError as exc:  # pragma: no cover
    raise ImportError("garmentdynamics.envs needs gymnasium: pip install 'garmentdynamics[gym]'") from exc

from gymnasium.envs.registration import register, registry

from .garment_env import GarmentEnv
from .rewards import FAILURE_REWARD, TASKS, Reward
from .ray_vector_env import RayVectorEnv
from .vector_env import GarmentVectorEnv

if "garmentdynamics/Garment-v0" not in registry:
    # One step limit: make() wraps the env (made without its own) in TimeLimit(max_episode_steps);
    # make_vec() hands the limit to the vector env, which truncates and autoresets itself.
    register(id="garmentdynamics/Garment-v0", entry_point="garmentdynamics.envs.garment_env:make_garment_env",
             vector_entry_point="garmentdynamics.envs:GarmentVectorEnv", max_episode_steps=100)

__all__ = ["GarmentEnv", "GarmentVectorEnv", "RayVectorEnv", "Reward", "TASKS", "FAILURE_REWARD"]

"""The scenes behind the Gymnasium environments: one Client, N scenes, rewards and episode
bookkeeping, shared by GarmentEnv (N = 1) and GarmentVectorEnv."""

from typing import Optional, Sequence

import numpy as np

from ..actions import arm_array_to_action, joint_array_to_action
from ..client import Client
from .rewards import FAILURE_REWARD, Reward
from .spaces import action_space, joint_action_space

CONTROLS = ("pose", "joints")


class SceneBatch:
    """N scenes of one garment on one server, stepped together.

    client: an existing Client (left open on close()), or None to connect to `target`, or, when
    that is None too, to spawn a local gd-server with `spawn_kwargs` (both closed on close()).
    client_kwargs: keyword arguments of the Client made here (Client(target, **client_kwargs) or
    Client.spawn(**spawn_kwargs, **client_kwargs)): token, token_file, tls, root_certificates,
    certificate_chain, private_key, timeout, ...
    control: "pose" (the arms' end-effector poses, (2, 8) actions; the default) or "joints"
    (mode "robot" only: each arm's joint targets and gripper opening, (2, J + 1) actions).
    urdf, grip_force, finger_friction, pad_stiffness: robot mode's settings (Client.create_scenes).
    """

    def __init__(self, count: int, client: Optional[Client] = None, target: Optional[str] = None,
                 spawn_kwargs: Optional[dict] = None, garment: str = "towel", material: str = "cotton",
                 vertices: int = 200, task: str = "lift", max_episode_steps: Optional[int] = 100, substeps: int = 1,
                 mode: str = "pseudo", dt: Optional[float] = None, self_contact: Optional[bool] = None,
                 yaw_deg: float = 10.0, offset_m: float = 0.02, client_kwargs: Optional[dict] = None,
                 control: str = "pose", urdf=None, grip_force: Optional[float] = None,
                 finger_friction: Optional[float] = None,
                 pad_stiffness: Optional[float] = None):
        if (max_episode_steps is not None and max_episode_steps < 1) or substeps < 1:
            raise ValueError("max_episode_steps (None: no limit) and substeps must be at least 1")
        if control not in CONTROLS:
            raise ValueError(f"control must be one of {CONTROLS}, got {control!r}")
        if control == "joints" and mode != "robot":
            raise ValueError(f"control='joints' drives robot arms: it needs mode='robot' (mode is {mode!r})")
        self.control = control
        self.client = None
        if client is not None and client_kwargs:
            raise ValueError("client_kwargs are for the Client the environment makes; an existing client= "
                             "already has its options")
        self._own_client = client is None
        if client is None:
            kwargs = dict(client_kwargs or {})
            client = (Client(target, **kwargs) if target is not None
                      else Client.spawn(**{**(spawn_kwargs or {}), **kwargs}))
        self.client = client
        self.count = count
        self.substeps = substeps
        self.max_episode_steps = max_episode_steps
        self.ids = []
        try:
            self.ids = client.create_scenes(garment=garment, material=material, vertices=vertices, count=count,
                                            mode=mode, dt=dt, self_contact=self_contact, yaw_deg=yaw_deg,
                                            offset_m=offset_m, urdf=urdf, grip_force=grip_force,
                                            finger_friction=finger_friction, pad_stiffness=pad_stiffness)
            self.info = client.scene_info(self.ids[0])
            self.reward = Reward(task, self.info["rest_positions"])
        except BaseException:
            self.close()
            raise
        self.vertex_count = int(self.info["vertex_count"])
        self.steps = np.zeros(count, dtype=np.int64)
        self.potential = np.zeros(count, dtype=np.float64)
        self.arms = [{} for _ in range(count)]  # per scene, its arms' states as last reported

    def action_space(self):
        """The action space of one scene: (2, 8) end-effector poses, or (2, J + 1) joint targets
        bounded by the arms' limits (control "joints")."""
        if self.control == "joints":
            return joint_action_space(self.info["joint_lower"], self.info["joint_upper"], self.info["gripper_max"])
        return action_space()

    def to_actions(self, actions: np.ndarray, k: int) -> list:
        """k scenes' array actions -> Client.step actions."""
        shape = self.action_space().shape
        actions = np.asarray(actions, dtype=np.float64).reshape((k,) + shape)
        if self.control == "joints":
            return [joint_array_to_action(a, shape[1] - 1) for a in actions]
        return [arm_array_to_action(a) for a in actions]

    def reset(self, indices: Sequence[int], seeds: Sequence[int]) -> np.ndarray:
        """Resets the scenes at `indices` with `seeds`; returns their positions (k, N, 3)."""
        indices = list(indices)
        states = self.client.reset_states([self.ids[i] for i in indices], [int(s) for s in seeds])
        x = np.stack([s.positions for s in states]).astype(np.float32, copy=False)
        for i, s in zip(indices, states):
            self.arms[i] = s.arms
        self.steps[indices] = 0
        self.potential[indices] = self.reward.potential(x)
        return x

    def step(self, indices: Sequence[int], actions: np.ndarray):
        """Steps the scenes at `indices` with (k, 2, 8) arm actions (control "joints": (k, 2, J + 1))
        in one call. Returns positions (k, N, 3), rewards (k,), terminated (k,), truncated (k,),
        infos (list of dicts)."""
        indices = list(indices)
        acts = self.to_actions(actions, len(indices))
        states = self.client.step_states([self.ids[i] for i in indices], acts, substeps=self.substeps)
        for i, s in zip(indices, states):
            self.arms[i] = s.arms
        x = np.stack([s.positions for s in states]).astype(np.float32, copy=False)
        failed = np.array([s.failed for s in states], dtype=bool)
        pot = self.reward.potential(x)
        rewards = np.where(failed, FAILURE_REWARD, pot - self.potential[indices])
        self.potential[indices] = pot
        self.steps[indices] += 1
        limit = self.max_episode_steps
        truncated = ((self.steps[indices] >= limit) if limit is not None else np.zeros(len(indices), bool)) & ~failed
        # wall_ms is left out: infos must be deterministic for a seed and actions (check_env)
        infos = [{"time": s.time, "steps": s.steps, "failed": s.failed, "failure": s.failure, "arms": s.arms,
                  "stats": {k: v for k, v in s.stats.items() if k != "wall_ms"}} for s in states]
        return x, rewards.astype(np.float64), failed, truncated, infos

    def close(self) -> None:
        if self.client is None:
            return
        try:
            if self.ids:
                self.client.destroy(self.ids)
        except Exception:
            pass  # the server may be gone already
        finally:
            self.ids = []
            if self._own_client:
                self.client.close()
            self.client = None

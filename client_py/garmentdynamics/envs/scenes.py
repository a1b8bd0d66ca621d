"""The scenes behind the Gymnasium environments: one Client, N scenes, rewards and episode
bookkeeping, shared by GarmentEnv (N = 1) and GarmentVectorEnv."""

from typing import Optional, Sequence

import numpy as np

from ..actions import arm_array_to_action
from ..client import Client
from .rewards import FAILURE_REWARD, Reward


class SceneBatch:
    """N scenes of one garment on one server, stepped together.

    client: an existing Client (left open on close()), or None to connect to `target`, or, when
    that is None too, to spawn a local gd-server with `spawn_kwargs` (both closed on close()).
    client_kwargs: keyword arguments of the Client made here (Client(target, **client_kwargs) or
    Client.spawn(**spawn_kwargs, **client_kwargs)): token, token_file, tls, root_certificates,
    certificate_chain, private_key, timeout, ...
    """

    def __init__(self, count: int, client: Optional[Client] = None, target: Optional[str] = None,
                 spawn_kwargs: Optional[dict] = None, garment: str = "towel", material: str = "cotton",
                 vertices: int = 200, task: str = "lift", max_episode_steps: Optional[int] = 100, substeps: int = 1,
                 mode: str = "pseudo", dt: Optional[float] = None, self_contact: Optional[bool] = None,
                 yaw_deg: float = 10.0, offset_m: float = 0.02, client_kwargs: Optional[dict] = None):
        if (max_episode_steps is not None and max_episode_steps < 1) or substeps < 1:
            raise ValueError("max_episode_steps (None: no limit) and substeps must be at least 1")
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
                                            offset_m=offset_m)
            self.info = client.scene_info(self.ids[0])
            self.reward = Reward(task, self.info["rest_positions"])
        except BaseException:
            self.close()
            raise
        self.vertex_count = int(self.info["vertex_count"])
        self.steps = np.zeros(count, dtype=np.int64)
        self.potential = np.zeros(count, dtype=np.float64)

    def reset(self, indices: Sequence[int], seeds: Sequence[int]) -> np.ndarray:
        """Resets the scenes at `indices` with `seeds`; returns their positions (k, N, 3)."""
        indices = list(indices)
        states = self.client.reset_states([self.ids[i] for i in indices], [int(s) for s in seeds])
        x = np.stack([s.positions for s in states]).astype(np.float32, copy=False)
        self.steps[indices] = 0
        self.potential[indices] = self.reward.potential(x)
        return x

    def step(self, indices: Sequence[int], actions: np.ndarray):
        """Steps the scenes at `indices` with (k, 2, 8) arm actions in one call. Returns
        positions (k, N, 3), rewards (k,), terminated (k,), truncated (k,), infos (list of dicts)."""
        indices = list(indices)
        acts = [arm_array_to_action(a) for a in np.asarray(actions).reshape(len(indices), 2, 8)]
        states = self.client.step_states([self.ids[i] for i in indices], acts, substeps=self.substeps)
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

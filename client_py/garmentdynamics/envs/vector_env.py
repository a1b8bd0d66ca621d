"""GarmentVectorEnv: N scenes of one gd-server as a gymnasium.vector.VectorEnv, stepped in one
batched StepScenes call."""

from typing import Optional, Sequence, Union

import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from ..client import Client
from .scenes import SceneBatch
from .spaces import observation_space


def reset_seeds_and_mask(env: VectorEnv, seed, options: Optional[dict]):
    """What reset(seed=, options=) of a vector env of garment scenes asks: per scene its seed
    (a list: one each; an int s: s + i; None: drawn from np_random) and the mask of the scenes to
    reset (options["reset_mask"], default all); seeds env.np_random as VectorEnv.reset does."""
    n = env.num_envs
    if isinstance(seed, (list, tuple, np.ndarray)):
        if len(seed) != n:
            raise ValueError(f"{len(seed)} seeds for {n} environments")
        seeds = np.asarray(seed, dtype=np.int64)
        VectorEnv.reset(env, seed=int(seeds[0]))
    else:
        VectorEnv.reset(env, seed=seed)
        seeds = (np.arange(n) + seed) if seed is not None else env.np_random.integers(1, 2**62, size=n)
    mask = np.ones(n, dtype=bool)
    if options and "reset_mask" in options:
        mask = np.asarray(options["reset_mask"], dtype=bool).reshape(n)
    return np.asarray(seeds, dtype=np.int64), mask


class StepResults:
    """A vector step's per-scene results, zeroed until stored: rewards, terminated, truncated and
    the infos' time, steps and failed."""

    def __init__(self, n: int):
        self.rewards = np.zeros(n, dtype=np.float64)
        self.terminated = np.zeros(n, dtype=bool)
        self.truncated = np.zeros(n, dtype=bool)
        self.time = np.zeros(n, dtype=np.float64)
        self.steps = np.zeros(n, dtype=np.int64)
        self.failed = np.zeros(n, dtype=bool)

    def store(self, idx, rewards, terminated, truncated, infos) -> None:
        """The results of the scenes `idx` (a batch's step: its rewards, flags and per-scene infos)."""
        self.rewards[idx] = rewards
        self.terminated[idx] = terminated
        self.truncated[idx] = truncated
        self.time[idx] = [i["time"] for i in infos]
        self.steps[idx] = [i["steps"] for i in infos]
        self.failed[idx] = [i["failed"] for i in infos]


class GarmentVectorEnv(VectorEnv):
    """`num_envs` copies of GarmentEnv's task (same spaces, rewards and episode ends; see
    GarmentEnv) on one server. step() sends all the scenes' actions in one StepScenes call.

    Autoreset: NEXT_STEP (metadata["autoreset_mode"]). A sub-environment whose episode ended
    (terminated or truncated) is reset by the following step() call instead of being stepped:
    that call returns its reset observation, reward 0 and terminated = truncated = False, and
    ignores its action. Such resets draw fresh seeds from the env's np_random.

    reset(seed=s) resets every scene, scene i with seed s + i (a list gives one seed per scene;
    None draws them from np_random). options={"reset_mask": bool array} resets only those scenes.

    infos: "time", "steps", "failed" arrays (with the "_key" masks of gymnasium's convention).

    client, target, spawn_kwargs, client_kwargs: the server, as in GarmentEnv (client_kwargs: the
    options of the Client made here, e.g. token_file= and root_certificates=).
    mode="robot" with control="joints": joint-space actions, (num_envs, 2, J + 1); urdf,
    grip_force, finger_friction, pad_stiffness: robot mode's settings (as in GarmentEnv).
    """

    metadata = {"render_modes": [], "autoreset_mode": AutoresetMode.NEXT_STEP}

    def __init__(self, num_envs: int = 8, client: Optional[Client] = None, *, target: Optional[str] = None,
                 spawn_kwargs: Optional[dict] = None, garment: str = "towel", material: str = "cotton",
                 vertices: int = 200, task: str = "lift", max_episode_steps: int = 100, substeps: int = 1,
                 mode: str = "pseudo", dt: Optional[float] = None, self_contact: Optional[bool] = None,
                 yaw_deg: float = 10.0, offset_m: float = 0.02, client_kwargs: Optional[dict] = None,
                 control: str = "pose", urdf=None, grip_force: Optional[float] = None,
                 finger_friction: Optional[float] = None,
                 pad_stiffness: Optional[float] = None):
        if num_envs < 1:
            raise ValueError("num_envs must be at least 1")
        self._scenes = SceneBatch(num_envs, client=client, target=target, spawn_kwargs=spawn_kwargs,
                                  garment=garment, material=material, vertices=vertices, task=task,
                                  max_episode_steps=max_episode_steps, substeps=substeps, mode=mode, dt=dt,
                                  self_contact=self_contact, yaw_deg=yaw_deg, offset_m=offset_m,
                                  client_kwargs=client_kwargs, control=control, urdf=urdf, grip_force=grip_force,
                                  finger_friction=finger_friction, pad_stiffness=pad_stiffness)
        self.num_envs = num_envs
        self.single_observation_space = observation_space(self._scenes.vertex_count)
        self.single_action_space = self._scenes.action_space()
        self.control = control
        self.observation_space = batch_space(self.single_observation_space, num_envs)
        self.action_space = batch_space(self.single_action_space, num_envs)
        self.task = task
        self._obs = np.zeros((num_envs, self._scenes.vertex_count, 3), dtype=np.float32)
        self._autoreset = np.zeros(num_envs, dtype=bool)

    @property
    def client(self) -> Client:
        return self._scenes.client

    @property
    def scene_ids(self):
        return list(self._scenes.ids)

    def _fresh_seeds(self, k: int) -> np.ndarray:
        return self.np_random.integers(1, 2**62, size=k)

    def reset(self, *, seed: Union[None, int, Sequence[int]] = None, options: Optional[dict] = None):
        seeds, mask = reset_seeds_and_mask(self, seed, options)
        idx = np.flatnonzero(mask)
        if len(idx):
            self._obs[idx] = self._scenes.reset(idx, seeds[idx])
        self._autoreset[idx] = False
        infos = {"seed": np.asarray(seeds, dtype=np.int64), "_seed": mask.copy()}
        return self._obs.copy(), infos

    def step(self, actions):
        actions = np.asarray(actions, dtype=np.float32).reshape((self.num_envs,) + self.single_action_space.shape)
        n = self.num_envs
        out = StepResults(n)

        to_reset = np.flatnonzero(self._autoreset)
        to_step = np.flatnonzero(~self._autoreset)
        if len(to_reset):
            self._obs[to_reset] = self._scenes.reset(to_reset, self._fresh_seeds(len(to_reset)))
        if len(to_step):
            x, r, term, trunc, infos = self._scenes.step(to_step, actions[to_step])
            self._obs[to_step] = x
            out.store(to_step, r, term, trunc, infos)
        self._autoreset = out.terminated | out.truncated
        stepped = ~np.isin(np.arange(n), to_reset)
        infos = {"time": out.time, "_time": stepped, "steps": out.steps, "_steps": stepped.copy(),
                 "failed": out.failed, "_failed": stepped.copy()}
        return self._obs.copy(), out.rewards, out.terminated, out.truncated, infos

    def close_extras(self, **kwargs):
        self._scenes.close()

"""GarmentEnv: one scene of a gd-server as a gymnasium.Env."""

from typing import Optional

import gymnasium as gym
import numpy as np

from ..client import Client
from .render import render_rgb
from .scenes import SceneBatch
from .spaces import observation_space


class GarmentEnv(gym.Env):
    """One garment on the table, driven by two arms.

    Observation: the vertex positions, Box (N, 3) float32, world frame (m, z up, table at z = 0).
    Action: Box (2, 8) float32, rows [left, right]: end-effector position (3), orientation
    quaternion w, x, y, z (4; normalised here), gripper opening (1) in [0, 0.035] m; in "pseudo"
    mode a gripper closing below 0.01 m takes the vertices within its jaw radius and they follow
    it until it opens. Each step() is `substeps` simulation steps of the scene's dt; the arm
    poses are reached at its end.
    Robot mode (mode="robot": two URDF arms, RGBench's AgileX Piper from `urdf`, a path or its
    text, or the server's --robot-urdf; the cloth is held by the fingers' contact and friction):
    control="pose" (the default) takes the (2, 8) poses above, reached by inverse kinematics (a
    pose out of reach raises grpc.RpcError INVALID_ARGUMENT); control="joints" takes Box (2, J + 1)
    float32, rows [left, right]: the J joint targets within the arms' limits (the Piper: joint1..
    joint6, rad; scene_info["joint_names"], "joint_lower", "joint_upper"), then the gripper
    opening in [0, scene_info["gripper_max"]] m, reached at the step's end. The arms start at a
    home pose 0.3 m above their bases; reset's and step's info["arms"] give each arm's joints,
    gripper opening, squeeze (N) and grip ("open", "closing", "held", "missed": the fingers
    stopped on little cloth or none, "lost": held, then the cloth left the pads). grip_force,
    finger_friction, pad_stiffness: as in Client.create_scenes.
    Reward: `task` ("lift" or "fold"), see garmentdynamics.envs.rewards.
    terminated: the scene failed (its state turned non-finite; reward -10).
    truncated: after max_episode_steps steps (None: never). gymnasium.make("garmentdynamics/Garment-v0")
    makes the env without a limit of its own and wraps it in TimeLimit(max_episode_steps, default
    100): one limit.
    render_mode "rgb_array": render() returns an (H, W, 3) uint8 image of the garment on the
    table, seen from the robots' side (garmentdynamics.envs.render); None: render() returns None.
    reset(seed=s): the scene is restored, its pose on the table randomised by seed s (yaw within
    +-yaw_deg, x/y offset within +-offset_m; s = 0: the unrandomised pose); without a seed a
    fresh one is drawn from the env's np_random.

    client: an existing Client (left open by close()); else `target` ("host:port") is connected,
    else a local gd-server is spawned with `spawn_kwargs` (Client.spawn) and stopped on close().
    client_kwargs: options of the Client made for `target` or the spawned server, e.g.
    {"token_file": "~/.config/gd/token", "root_certificates": "ca.pem"} for a server with tokens
    and TLS (see garmentdynamics.Client).
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 20}

    def __init__(self, client: Optional[Client] = None, *, target: Optional[str] = None,
                 spawn_kwargs: Optional[dict] = None, garment: str = "towel", material: str = "cotton",
                 vertices: int = 200, task: str = "lift", max_episode_steps: Optional[int] = 100, substeps: int = 1,
                 mode: str = "pseudo", dt: Optional[float] = None, self_contact: Optional[bool] = None,
                 yaw_deg: float = 10.0, offset_m: float = 0.02, client_kwargs: Optional[dict] = None,
                 render_mode: Optional[str] = None, control: str = "pose", urdf=None,
                 grip_force: Optional[float] = None, finger_friction: Optional[float] = None,
                 pad_stiffness: Optional[float] = None):
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be None or one of {self.metadata['render_modes']}, got {render_mode!r}")
        self.render_mode = render_mode
        self._scenes = SceneBatch(1, client=client, target=target, spawn_kwargs=spawn_kwargs, garment=garment,
                                  material=material, vertices=vertices, task=task,
                                  max_episode_steps=max_episode_steps, substeps=substeps, mode=mode, dt=dt,
                                  self_contact=self_contact, yaw_deg=yaw_deg, offset_m=offset_m,
                                  client_kwargs=client_kwargs, control=control, urdf=urdf, grip_force=grip_force,
                                  finger_friction=finger_friction, pad_stiffness=pad_stiffness)
        self.observation_space = observation_space(self._scenes.vertex_count)
        self.metadata = {**self.metadata, "render_fps": max(1, round(1.0 / (float(self._scenes.info["dt"]) * substeps)))}
        self._x: Optional[np.ndarray] = None
        self.action_space = self._scenes.action_space()
        self.control = control
        self.task = task

    @property
    def client(self) -> Client:
        return self._scenes.client

    @property
    def scene_id(self) -> str:
        return self._scenes.ids[0]

    @property
    def scene_info(self) -> dict:
        """Triangles, rest positions, dt, ... of the scene (Client.scene_info)."""
        return self._scenes.info

    def reset(self, *, seed: Optional[int] = None, options: Optional[dict] = None):
        super().reset(seed=seed)
        scene_seed = seed if seed is not None else int(self.np_random.integers(1, 2**62))
        x = self._scenes.reset([0], [scene_seed])[0]
        self._x = x
        return x, {"seed": scene_seed, "time": 0.0, "arms": self._scenes.arms[0]}

    def step(self, action):
        x, r, term, trunc, infos = self._scenes.step([0], np.asarray(action)[None])
        self._x = x[0]
        return x[0], float(r[0]), bool(term[0]), bool(trunc[0]), infos[0]

    def render(self) -> Optional[np.ndarray]:
        """render_mode "rgb_array": an (240, 320, 3) uint8 image of the garment as last observed
        (reset or step); render_mode None: None (Gymnasium's contract)."""
        if self.render_mode is None:
            return None
        x = self._x if self._x is not None else self._scenes.info["rest_positions"]
        return render_rgb(x, self._scenes.info["triangles"])

    def close(self):
        self._scenes.close()
        super().close()


def make_garment_env(**kwargs) -> GarmentEnv:
    """gymnasium.make's entry point: a GarmentEnv without a step limit of its own, since make wraps
    it in TimeLimit with the spec's or the caller's max_episode_steps (the one limit)."""
    kwargs.setdefault("max_episode_steps", None)
    return GarmentEnv(**kwargs)

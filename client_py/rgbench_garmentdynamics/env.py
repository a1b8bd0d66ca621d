"""GarmentDynamicsEnv: RGBench's simulator interface (rgbench.envs.base.BaseEnvWrapper) on a
gd-server scene, so that RGBench's harness (scripts/run_benchmark.py) runs on GarmentDynamics.

RGBench builds it as `GarmentDynamicsEnv(cfg=cfg.active_run)` (rgbench/envs/__init__.py, for an
env.name containing "garment_dynamics" or "mujoco_style3d") and then uses, per real frame:
get_master_start_time() once, step_to_time(t_real + camera_delay [+ 10 s for fling]),
get_sim_vertices() (N, 3) world frame, get_current_sim_time().

What it reads from cfg (an omegaconf DictConfig or a plain dict), as RGBench's fixed-point envs do:

    sim_model.type            "fixed_point" (RGBench's pseudo mode) or "robot" (the Piper arms driven
                              by their recorded joint angles, the cloth held by the fingers)
    action.type               grasp | fold | fling (fling: fixed_point only, as RGBench's harness)
    action.fling_prepare_time, action.fling_wait_time   (defaults 2.0 and 3.0, as RGBench's code)
    evaluate.start_calculate_time   grasp/fold grab time (else env.grasp.grasp_time)
    env.grab_points           {mode: auto | manual, indices: [l, r]} (default auto)
    cloth.model_path          the garment OBJ (uploaded to the server); cloth.init_pose
                              [x, y, z, qw, qx, qy, qz] (default [0.1, 0, 0.01, 1, 0, 0, 0]);
                              cloth.init_pose_path, a JSON {"pos": [x, y, z], "quat": [w, x, y, z]},
                              replaces init_pose when the file exists (as RGBench's MuJoCo env)
    env.timestep, env.sim_timestep  the step when env.garment_dynamics.dt is unset (RGBench's MuJoCo
                              and PyBullet keys); default RGBench's 0.002 s
    cloth_params.shoulder_index     fling pins [left, right]
    cloth_params.{stretch, bending, density, friction, poisson}   RGBench's fitted fabric (see
                              cloth_material_params), over the material's values
    data.robot_joints.{left,right}_arm_csv_path, data.sim_start_time
    env.model_path            robot mode: the arms' URDF when it names a .urdf file (RGBench's
                              PyBullet key; other simulators' model files are not URDFs and are
                              ignored)

and its own optional block env.garment_dynamics:

    target        "host:port" of a running gd-server (default: spawn one locally)
    token_file    with target: the file of the server's token (--auth-token-file), sent on
                  every call; default $GD_TOKEN_FILE when set. (`token` works too, but a token in
                  a config ends up in the run's saved config: prefer the file.)
    tls           with target: speak TLS (system roots unless root_certificates)
    root_certificates, certificate_chain, private_key
                  with target: PEM paths: the CA to trust, and the client certificate + key for a
                  server with --tls-client-ca (mutual TLS); absolute paths, as Hydra may change
                  the working directory
    server_bin, data_dir, threads   for the spawned server
    garment, vertices               a generated garment when cloth.model_path is absent (default tshirt, 2000)
    material      fabric name (default cotton): the base that cloth_params adjust
    cloth_params  false: the library material alone, RGBench's cloth_params ignored (default true)
    dt            s per step (default env.timestep, else env.sim_timestep, else 0.002)
    self_contact  default: the server's (on)
    urdf          robot mode: the arms' URDF file (RGBench's assets/Urdf/piper_description/
                  piper_with_gripper.urdf; an absolute path), sent to the server with the scene;
                  over env.model_path. Neither: the server's own (gd-server --robot-urdf PATH),
                  and a clear error when it has none
    grip_force, finger_friction   robot mode: N at which the closing fingers stop (default the
                  URDF's finger effort limit, the Piper's 10 N) and their friction coefficient on
                  the cloth (default the material's)
    pad_stiffness robot mode: N/m, how stiffly a hand the cloth stops short is pulled along its
                  step (default the server's 3e5; 0: its pads wait; docs/robot.md)

Semantics (rgbench-format.md section 3):
- fixed_point grasp/fold, auto pins: the scene runs in the server's fixed-point mode with
  grab_time = start_calculate_time; every step sends both arms' interpolated end-effector poses
  and the server pins, at grab_time, the vertex nearest each arm and moves it with the arm.
- fixed_point grasp/fold with manual pins, and fling: the pinned vertices are driven as kinematic
  targets (fling: linear approach from their initial position to the first trajectory position
  during fling_prepare_time, hold for fling_wait_time, then follow the trajectory).
- robot: the scene runs in the server's robot mode (docs/robot.md): two Piper arms from the
  URDF at bases (0, +0.25, 0) left and (0, -0.25, 0) right (placed by the server: the CSVs'
  joint angles are each arm's own), the cloth held only by the fingers' contact and friction.
  The joints CSVs are read in RGBench's joint mode (pos_1..pos_6 = joint1..joint6 in rad,
  pos_gripper = the finger opening in m, 0 closed .. 0.035 open; trajectory.load_joint_csv) and
  each arm's whole recording goes to the server with the first call as timed joint samples
  (interpolated linearly between samples, as RGBench's PyBullet robot mode does); the gripper
  is a force-limited position joint closing toward pos_gripper (clipped to [0, gripper_max]).
  The arms start at their first recorded joints (CreateScenes' RobotSettings initial joints; an
  arm without a CSV starts at the server's home pose), gripper open. No vertex is pinned, so grab times
  and grab points are not used. The arms' states after each call (joints, finger opening,
  squeeze in N) are in `arm_states`.
Times: sim time 0 is master_start_time (the earliest first sample of the two arms); trajectory
time = sim time (minus prepare + wait for fling). step_to_time steps while sim time < target, so
it overshoots by less than one dt, like RGBench's environments.
"""

import json
import logging
import math
import time
import weakref
from pathlib import Path
from typing import Any, Optional

import grpc
import numpy as np

from garmentdynamics import Client
from garmentdynamics.actions import GRIPPER_OPEN

from .trajectory import load_joint_csv, load_pose_csv

try:  # subclass RGBench's interface when RGBench is installed; duck-typed otherwise
    from rgbench.envs.base import BaseEnvWrapper as _Base  # type: ignore
except Exception:  # noqa: BLE001 - RGBench (and its omegaconf) is optional
    _Base = object

log = logging.getLogger("rgbench_garmentdynamics")

DEFAULT_INIT_POSE = (0.1, 0.0, 0.01, 1.0, 0.0, 0.0, 0.0)
RGBENCH_TIMESTEP = 0.002  # s: the step of RGBench's MuJoCo and PyBullet environments
_MISSING = object()


def cfg_get(cfg: Any, dotted: str, default: Any = None) -> Any:
    """cfg["a"]["b"]... for dotted "a.b", on dicts or omegaconf DictConfigs; default when absent."""
    node = cfg
    for key in dotted.split("."):
        if node is None:
            return default
        try:
            node = node[key] if key in node else _MISSING
        except TypeError:
            node = getattr(node, key, _MISSING)
        if node is _MISSING:
            return default
    return default if node is None else node


def first_set(cfg: Any, *dotted: str) -> Any:
    """The first of the dotted keys that is present and not null (None when none is)."""
    for key in dotted:
        value = cfg_get(cfg, key)
        if value is not None:
            return value
    return None


# RGBench's cloth_params keys -> the server's material_params (docs/materials.md). The values are
# in the units of the RGBench paper's fabric table, which were fitted to GarmentDynamics: stretch
# g/s², bending g·mm²/s²/rad (the table heads it g·m², docs/materials.md shows why it is mm²),
# density g/m² (areal).
CLOTH_PARAMS_TO_MATERIAL = {"stretch": "stretch_g_s2", "bending": "bending_g_mm2_s2_rad",
                            "density": "areal_density_g_m2", "friction": "friction", "poisson": "poisson"}


def cloth_material_params(cfg: Any) -> dict:
    """The material parameters RGBench's cloth_params give (CLOTH_PARAMS_TO_MATERIAL).

    Not used: `mass` (0.255 kg with a "TODO: check" in every garment's file; the mass follows
    density x area), `damping`, `kinetic_friction` and `ground_friction` (the model has static
    Coulomb friction and its own damping), and `rgba`. Thickness is the base material's."""
    out = {}
    for key, param in CLOTH_PARAMS_TO_MATERIAL.items():
        value = cfg_get(cfg, f"cloth_params.{key}")
        if value is not None:
            try:
                out[param] = float(value)
            except (TypeError, ValueError):
                raise ValueError(f"cloth_params.{key} must be a number, got {value!r}") from None
    return out


def load_init_pose(path: Path) -> list:
    """RGBench's initial object pose file ({"pos": [x, y, z], "quat": [w, x, y, z]}, as its MuJoCo
    fixed-point env reads it) as [x, y, z, qw, qx, qy, qz]."""
    try:
        data = json.loads(Path(path).read_text())
        pose = [float(v) for v in data["pos"]] + [float(v) for v in data["quat"]]
    except (OSError, ValueError, KeyError, TypeError) as e:
        raise ValueError(f"cloth.init_pose_path {path}: expected JSON {{\"pos\": [x, y, z], \"quat\": "
                         f"[w, x, y, z]}} ({e})") from e
    if len(pose) != 7 or not all(math.isfinite(v) for v in pose):
        raise ValueError(f"cloth.init_pose_path {path}: pos needs 3 and quat 4 finite numbers, got {data}")
    return pose


def robot_urdf(cfg: Any) -> Optional[Path]:
    """Robot mode's URDF file from the config: env.garment_dynamics.urdf, else RGBench's
    env.model_path when it names a .urdf file; None when neither does (the server's own)."""
    key, value = "env.garment_dynamics.urdf", cfg_get(cfg, "env.garment_dynamics.urdf")
    if value is None or value == "":
        key, value = "env.model_path", cfg_get(cfg, "env.model_path")
        if value is None or not str(value).lower().endswith(".urdf"):
            return None
    path = Path(str(value)).expanduser()
    if not path.is_file():
        raise ValueError(f"{key}: no URDF file at {str(path)!r} (robot mode's arms; give an absolute path, as Hydra "
                         "may change the working directory)")
    return path


def _release(client: Client, scene_id: Optional[str], own_client: bool) -> None:
    """Destroys the env's scene and, when the env made the client, closes it (stops a spawned
    server). Run once, by close() or when the env is garbage-collected without it (RGBench's
    run_benchmark.py never calls close())."""
    try:
        if scene_id is not None:
            client.destroy([scene_id])
    except Exception:  # noqa: BLE001 - the server may be gone
        pass
    finally:
        if own_client:
            client.close()


def _quat_matrix(w, x, y, z) -> np.ndarray:
    q = np.array([w, x, y, z], dtype=np.float64)
    w, x, y, z = q / np.linalg.norm(q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def _posed_obj(path: Path, init_pose) -> bytes:
    """The OBJ's bytes, its `v` lines moved so that the server's fixed placement (a translation by
    DEFAULT_INIT_POSE's position) puts the garment at init_pose (position + quaternion wxyz)."""
    data = path.read_bytes()
    pose = [float(v) for v in init_pose]
    if len(pose) != 7:
        raise ValueError(f"cloth.init_pose must be [x, y, z, qw, qx, qy, qz], got {init_pose}")
    if np.allclose(pose, DEFAULT_INIT_POSE):
        return data
    rot = _quat_matrix(*pose[3:])
    shift = np.array(pose[:3]) - np.array(DEFAULT_INIT_POSE[:3])
    out = []
    for line in data.decode("utf-8", errors="replace").splitlines():
        parts = line.split()
        if len(parts) >= 4 and parts[0] == "v":
            p = rot @ np.array([float(c) for c in parts[1:4]]) + shift
            line = "v {:.9g} {:.9g} {:.9g}".format(*p) + ("" if len(parts) == 4 else " " + " ".join(parts[4:]))
        out.append(line)
    return ("\n".join(out) + "\n").encode()


class GarmentDynamicsEnv(_Base):
    """RGBench's BaseEnvWrapper on a gd-server scene (see the module docstring).

    Args:
        cfg: RGBench's run config (cfg.active_run), a DictConfig or a dict.
        client: an existing garmentdynamics.Client to use (left open by close()); default: connect
            to env.garment_dynamics.target, or spawn a local gd-server (stopped by close()).
        client_kwargs: more keyword arguments of the Client made here (over the config's
            token_file, tls, root_certificates, ... keys), e.g. {"token_file": "/run/gd/token"}.
    """

    def __init__(self, cfg: Any, client: Optional[Client] = None, client_kwargs: Optional[dict] = None,
                 **kwargs):
        self.cfg = cfg
        gd = cfg_get(cfg, "env.garment_dynamics", {}) or {}
        self.sim_type = str(cfg_get(cfg, "sim_model.type", "fixed_point"))
        if self.sim_type not in ("fixed_point", "robot"):
            raise ValueError(f"sim_model.type must be fixed_point or robot, got {self.sim_type!r}")
        self.robot = self.sim_type == "robot"
        self.action_type = str(cfg_get(cfg, "action.type", "grasp"))
        if self.action_type not in ("grasp", "fold", "fling"):
            raise ValueError(f"action.type must be grasp, fold or fling, got {self.action_type!r}")
        if self.robot and self.action_type == "fling":
            raise ValueError("action.type fling runs in sim_model.type fixed_point only (its approach and hold "
                             "phases drive the shoulder vertices; RGBench's run_benchmark.py refuses fling in robot "
                             "mode too)")

        # --- arm trajectories: world-frame end poses (fixed_point), joint angles (robot) -------
        start_offset = float(cfg_get(cfg, "data.sim_start_time", 0.0))
        load = load_joint_csv if self.robot else load_pose_csv
        self.tracks = {}
        for arm in ("left", "right"):
            p = cfg_get(cfg, f"data.robot_joints.{arm}_arm_csv_path")
            if p:
                self.tracks[arm] = load(p, arm, start_offset)
        if not self.tracks:
            raise ValueError("no arm trajectory: set data.robot_joints.left_arm_csv_path and/or right_arm_csv_path")
        self.master_start_time = min(t.start for t in self.tracks.values())

        # --- timing of the pseudo mode ---------------------------------------------------------
        self.prepare_time = 0.0
        self.wait_time = 0.0
        self.grab_time = math.inf
        if self.action_type == "fling":
            self.prepare_time = float(cfg_get(cfg, "action.fling_prepare_time", 2.0))
            self.wait_time = float(cfg_get(cfg, "action.fling_wait_time", 3.0))
            self.grab_time = 0.0
        else:
            gt = cfg_get(cfg, "evaluate.start_calculate_time")
            gt = gt if gt is not None else cfg_get(cfg, "env.grasp.grasp_time")
            if gt is not None:
                self.grab_time = float(gt)
            elif self.sim_type == "fixed_point":
                log.warning("no grab time (evaluate.start_calculate_time): nothing will be grabbed")

        # --- the server and the scene ------------------------------------------------------------
        self._own_client = client is None
        if client is None:
            if gd.get("target"):
                client = Client(str(gd["target"]), **self._client_options(gd, client_kwargs))
            else:
                client = Client.spawn(data_dir=gd.get("data_dir"), threads=gd.get("threads"),
                                      server_bin=gd.get("server_bin"), **(client_kwargs or {}))
        self.client = client
        self.scene_id = None
        self._finalizer = None
        try:
            self._create_scene(gd)
        except BaseException:
            self.close()
            raise
        # The scene (and a spawned server) go when the env does, closed or not.
        self._finalizer = weakref.finalize(self, _release, client, self.scene_id, self._own_client)
        self._vertices: Optional[np.ndarray] = None
        self._failed = False
        self.arm_states: dict = {}  # the arms' states after the last call (robot mode: joints, gripper, squeeze)
        self._sent_ahead = False  # server pins / robot: the arms' whole trajectories went with the first call
        self._seconds_per_step = 0.0  # measured, to keep one call within the client's deadline

    @staticmethod
    def _client_options(gd, client_kwargs: Optional[dict]) -> dict:
        """The Client's token and TLS options from env.garment_dynamics, then client_kwargs."""
        options = {}
        for key in ("token", "token_file", "root_certificates", "certificate_chain", "private_key"):
            value = gd.get(key)
            if value is not None and value != "":
                options[key] = str(value)
        if gd.get("tls") is not None:
            options["tls"] = bool(gd.get("tls"))
        client_kwargs = dict(client_kwargs or {})
        if "token" in client_kwargs or "token_file" in client_kwargs:  # one source for the token
            options.pop("token", None)
            options.pop("token_file", None)
        options.update(client_kwargs)
        return options

    @property
    def _ahead(self) -> bool:
        """Whether the arms' whole trajectories go with the first call (server pins, robot mode)
        rather than per-step kinematic targets."""
        return self.pin_mode in ("server", "robot")

    def _create_scene(self, gd) -> None:
        self.pin_mode = "server"  # the server's fixed-point pins (grasp/fold, auto)
        self.pins = []
        if self.robot:
            self.pin_mode = "robot"  # no pins: the fingers hold the cloth
        elif self.action_type == "fling":
            self.pin_mode = "targets"
            self.pins = [int(i) for i in (cfg_get(self.cfg, "cloth_params.shoulder_index") or [])]
            if len(self.pins) != 2:
                raise ValueError("fling needs cloth_params.shoulder_index = [left, right]")
        elif str(cfg_get(self.cfg, "env.grab_points.mode", "auto")) == "manual":
            self.pin_mode = "targets"
            self.pins = [int(i) for i in (cfg_get(self.cfg, "env.grab_points.indices") or [])]
            if len(self.pins) != 2:
                raise ValueError("grab_points.mode manual needs grab_points.indices = [left, right]")
        # fixed_point scenes of the server pin at grab_time; target-driven ones need no server pins
        mode = "robot" if self.robot else "fixed_point" if self.pin_mode == "server" else "pseudo"
        grab_time = self.grab_time if self.pin_mode == "server" and math.isfinite(self.grab_time) else None
        if self.pin_mode == "server" and grab_time is None:
            grab_time = 1e9  # never
        # The step: env.garment_dynamics.dt, else RGBench's own keys (env.timestep in its MuJoCo
        # config, env.sim_timestep in its PyBullet one), else RGBench's 0.002 s; a null key is unset.
        dt = first_set(self.cfg, "env.garment_dynamics.dt", "env.timestep", "env.sim_timestep")
        if dt is None:
            dt = RGBENCH_TIMESTEP
            log.info("no time step in the config (env.garment_dynamics.dt, env.timestep, env.sim_timestep): "
                     "using RGBench's %g s", dt)
        material = str(gd.get("material", "cotton"))
        self.material_params = cloth_material_params(self.cfg) if gd.get("cloth_params", True) else {}
        if self.material_params:
            log.info("material %s with RGBench's cloth_params: %s", material, self.material_params)
        common = dict(material=material, material_params=self.material_params, mode=mode, dt=float(dt),
                      self_contact=gd.get("self_contact"), grab_time=grab_time)
        self.urdf = None
        if self.robot:
            self.urdf = robot_urdf(self.cfg)
            for key in ("grip_force", "finger_friction", "pad_stiffness"):
                if gd.get(key) is not None:
                    common[key] = float(gd.get(key))
            common["urdf"] = self.urdf
            # The arms start where the recording starts (as RGBench resets its robot to the first
            # joints), not at the server's home pose: no sweep through the cloth in the first step.
            common["initial_joints"] = {arm: track.at(self._traj_time(0.0))[0] for arm, track in self.tracks.items()}
            log.info("robot mode: the arms of %s", self.urdf or "the server's --robot-urdf")
        model_path = cfg_get(self.cfg, "cloth.model_path")
        if model_path:
            init_pose = cfg_get(self.cfg, "cloth.init_pose", DEFAULT_INIT_POSE)
            pose_path = cfg_get(self.cfg, "cloth.init_pose_path")
            if pose_path:  # as RGBench's MuJoCo env: the file when it exists, else init_pose
                if Path(str(pose_path)).is_file():
                    init_pose = load_init_pose(Path(str(pose_path)))
                else:
                    log.warning("cloth.init_pose_path %s does not exist: using cloth.init_pose %s", pose_path,
                                list(init_pose))
            obj = _posed_obj(Path(str(model_path)), list(init_pose))
            mesh_id = self.client.upload_mesh(obj, name=Path(str(model_path)).stem)
            source = dict(mesh_id=mesh_id)
        else:
            source = dict(garment=str(gd.get("garment", "tshirt")), vertices=int(gd.get("vertices", 2000)))
        try:
            ids = self.client.create_scenes(**source, **common)
        except grpc.RpcError as err:
            if self.robot and self.urdf is None and err.code() == grpc.StatusCode.FAILED_PRECONDITION:
                raise ValueError(
                    "sim_model.type robot needs the arms' URDF (RGBench's assets/Urdf/piper_description/"
                    "piper_with_gripper.urdf) and the server has none: set env.garment_dynamics.urdf (or RGBench's "
                    "env.model_path) to the file's absolute path, or start the gd-server with --robot-urdf PATH "
                    f"(the server said: {err.details()})") from err
            raise
        self.scene_id = ids[0]
        info = self.client.scene_info(self.scene_id)
        self.info = info
        self.dt = float(info["dt"])
        self.initial_vertices = info["rest_positions"].astype(np.float64)
        n = len(self.initial_vertices)
        for i in self.pins:
            if not 0 <= i < n:
                raise ValueError(f"pin vertex {i} is out of range: the garment has {n} vertices")
        self.sim_time = 0.0

    # ------------------------------------------------------------------------------------------
    # RGBench's interface
    # ------------------------------------------------------------------------------------------
    def get_master_start_time(self) -> float:
        """Absolute Unix time of sim time 0: the earliest first sample of the arm CSVs."""
        return float(self.master_start_time)

    def get_current_sim_time(self) -> float:
        """Sim time, s since master_start_time (including the fling preparation)."""
        return float(self.sim_time)

    def get_sim_vertices(self) -> np.ndarray:
        """All cloth vertices (N, 3) float64, world frame (m), in the mesh's vertex order."""
        if self._vertices is None:
            self._vertices = self.client.get_state([self.scene_id])[0].positions.astype(np.float64)
        return self._vertices.copy()

    def step(self) -> dict:
        """One simulation step of dt. Returns {"sim_time", "failed", "failure"}."""
        return self._advance(1)

    def step_to_time(self, target_time: float) -> None:
        """Steps while sim time < target_time (so it ends less than one dt past it). Stops early,
        with a warning, if the scene failed. With the server's pins (fixed_point Grasp/Fold) and in
        robot mode the steps up to target_time go in one call (substeps), the arms' trajectories
        having been sent ahead; with kinematic vertex targets (Fling, manual grab points), which
        reach their positions over one step, one call per step."""
        while self.sim_time < target_time - 1e-9 and not self._failed:
            if not self._ahead:
                self._advance(1)
                continue
            k, t = 0, self.sim_time
            while t < target_time - 1e-9:
                t += self.dt
                k += 1
            self._advance(min(k, self._substeps_per_call()))

    def _substeps_per_call(self) -> int:
        """Most steps one call may take: a quarter of the client's deadline at the measured pace,
        and the server's default limit of 1000."""
        timeout = getattr(self.client, "timeout", None) or 60.0
        if self._seconds_per_step <= 0:
            return 8  # the first calls measure the pace
        return int(max(1, min(1000, 0.25 * timeout / self._seconds_per_step)))

    def _advance(self, substeps: int) -> dict:
        """substeps steps of dt in one StepScenes call."""
        if self._failed:
            return {"sim_time": self.sim_time, "failed": True, "failure": self._failure}
        if self._ahead:
            action = None if self._sent_ahead else self._trajectories_ahead()
        else:
            action = self._action(self.sim_time + self.dt * substeps)
        t0 = time.monotonic()
        state = self.client.step_states([self.scene_id], [action], substeps=substeps, omit_positions=True)[0]
        pace = (time.monotonic() - t0) / substeps
        self._seconds_per_step = pace if self._seconds_per_step <= 0 else max(pace, 0.5 * (self._seconds_per_step + pace))
        self._sent_ahead = self._sent_ahead or self._ahead
        self.sim_time = state.time
        self.arm_states = state.arms
        self._vertices = None
        if state.failed:
            self._failed, self._failure = True, state.failure
            log.warning("the simulation failed at t = %.3f s: %s", state.time, state.failure)
        return {"sim_time": self.sim_time, "failed": state.failed, "failure": state.failure}

    def close(self) -> None:
        """Destroys the scene (and stops a server the env spawned); safe to call twice."""
        client, self.client = getattr(self, "client", None), None
        finalizer = getattr(self, "_finalizer", None)
        if finalizer is not None:
            finalizer()  # runs _release once; later calls do nothing
        elif client is not None:
            _release(client, getattr(self, "scene_id", None), getattr(self, "_own_client", False))

    # ------------------------------------------------------------------------------------------
    # per-step commands
    # ------------------------------------------------------------------------------------------
    def _traj_time(self, t: float) -> float:
        """Absolute CSV time at sim time t."""
        return self.master_start_time + t - self.prepare_time - self.wait_time

    def _trajectories_ahead(self) -> dict:
        """Server pin mode and robot mode: each arm's whole trajectory as timed samples (scene
        time), sent with the first call and kept by the server: the sample at the first step's
        end, then every CSV sample after it (the server interpolates between samples as
        PoseTrack.at and JointTrack.at do, so every step ends where a per-step command would have
        put it). Pin mode sends end poses with the gripper open (RGBench's fixed-point envs ignore
        it), robot mode joint angles with the recorded gripper opening."""
        action = {}
        t_first = self.dt
        grip_max = float(self.info.get("gripper_max") or GRIPPER_OPEN)

        def sample(track, k, t):
            """The command of CSV sample k (None: interpolated at scene time t)."""
            if self.robot:
                q, g = track.at(self._traj_time(t)) if k is None else (track.joints[k], track.gripper[k])
                return {"joints": q, "gripper": float(np.clip(g, 0.0, grip_max)), "time": float(t)}
            if k is None:
                pos, quat, _ = track.at(self._traj_time(t))
            else:
                pos, quat = track.positions[k], track.quats[k]
            return {"position": pos, "orientation": quat, "gripper": GRIPPER_OPEN, "time": float(t)}

        for arm, track in self.tracks.items():
            samples = [sample(track, None, t_first)]
            sim_times = np.asarray(track.times, dtype=np.float64) - self._traj_time(0.0)
            last = t_first
            for k, t in enumerate(sim_times):
                if k + 1 < len(sim_times) and sim_times[k + 1] <= t:
                    continue  # a later sample at the same time wins (as in PoseTrack.at)
                if t <= last + 1e-9:
                    continue
                samples.append(sample(track, k, t))
                last = t
            action[arm] = samples
        return action

    def _action(self, t_end: float) -> dict:
        """Kinematic-target mode: the [left, right] pinned vertices' targets at t_end."""
        action = {}
        idx, pos = [], []
        for k, arm in enumerate(("left", "right")):
            if arm not in self.tracks:
                continue
            first = self.tracks[arm].positions[0]
            if self.action_type == "fling" and t_end < self.prepare_time:
                a = t_end / self.prepare_time
                p = (1 - a) * self.initial_vertices[self.pins[k]] + a * first
            elif self.action_type == "fling" and t_end < self.prepare_time + self.wait_time:
                p = first
            elif self.action_type != "fling" and t_end < self.grab_time:
                continue  # not grabbed yet: free
            else:
                p = self.tracks[arm].at(self._traj_time(t_end))[0]
            idx.append(self.pins[k])
            pos.append(p)
        if idx:
            action["targets"] = (np.array(idx), np.array(pos))
        return action

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

"""The GarmentDynamics client: numpy in and out over gRPC.

    from garmentdynamics import Client

    with Client.spawn() as c:                     # or Client("host:50051") for a running server
        ids = c.create_scenes(garment="towel", material="cotton", vertices=200, count=16, seed=1)
        x = c.step(ids, substeps=10)              # (16, N, 3) float32, world frame, metres
        job = c.submit_job(garment="towel", task="grasp", vertices=200)
        report = c.wait_report(job)               # dict: job, summary (parsed summary.json), files

Robot mode (two AgileX Piper arms from a URDF, the cloth held by the fingers' contact; docs/robot.md):

        ids = c.create_scenes(garment="towel", vertices=400, mode="robot", urdf="piper_with_gripper.urdf")
        info = c.scene_info(ids[0])               # joint_names, joint_lower, joint_upper, gripper_max
        c.step(ids, [{"left": {"joints": q, "gripper": 0.0}}], substeps=10)
        c.get_state(ids)[0].arms["left"]          # closed, joints, gripper (opening now), squeeze (N)

Every call has a deadline (`timeout`, seconds; streams use `stream_timeout`). Errors of the server
surface unchanged as grpc.RpcError: `err.code()` is the server's status code (NOT_FOUND,
INVALID_ARGUMENT, RESOURCE_EXHAUSTED, FAILED_PRECONDITION, ...) and `err.details()` its message.
Bad arguments detected before a call is made (wrong shapes, unknown keys, non-finite joints, a
joint count that does not match the scene's arms) raise ValueError or TypeError.

Servers with tokens and TLS (gd-server --auth-token-file, --tls-cert/--tls-key, --tls-client-ca):

    Client("gd.example.org:50051", token_file="~/.config/gd/token", root_certificates="ca.pem")

sends `authorization: Bearer <token>` with every call and speaks TLS (see Client and
garmentdynamics.credentials). Without token/token_file, $GD_TOKEN_FILE names the token file.
"""

import json
import os
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Dict, Iterator, List, Optional, Sequence, Union

import grpc
import numpy as np

from . import credentials as _creds
from . import health
from ._proto import pb, pb_grpc
from .actions import scene_action
from .arrays import from_array
from .local_server import LocalServer
from .progress import ProgressBar

_MAX_MESSAGE = 512 * 1024 * 1024

_JOB_STATUS = {pb.JOB_STATUS_UNSPECIFIED: "UNSPECIFIED", pb.JOB_QUEUED: "QUEUED", pb.JOB_RUNNING: "RUNNING",
               pb.JOB_SUCCEEDED: "SUCCEEDED", pb.JOB_FAILED: "FAILED", pb.JOB_INTERRUPTED: "INTERRUPTED",
               pb.JOB_CANCELLED: "CANCELLED"}
FINAL_JOB_STATUSES = ("SUCCEEDED", "FAILED", "INTERRUPTED", "CANCELLED")
_SCENE_STATUS = {pb.SCENE_STATUS_UNSPECIFIED: "UNSPECIFIED", pb.SCENE_READY: "READY", pb.SCENE_FAILED: "FAILED"}
_ARM_NAME = {pb.ARM_UNSPECIFIED: "unspecified", pb.ARM_LEFT: "left", pb.ARM_RIGHT: "right"}
_GRIPS = {pb.GRIP_OPEN: "open", pb.GRIP_CLOSING: "closing", pb.GRIP_HELD: "held", pb.GRIP_MISSED: "missed",
          pb.GRIP_LOST: "lost"}


@dataclass
class SceneState:
    """One scene's state as the server reported it."""
    scene_id: str
    status: str                     # "READY" | "FAILED"
    failure: str                    # why it failed ("" when READY)
    time: float                     # s of scene time
    steps: int                      # steps since the last reset
    positions: Optional[np.ndarray]  # (N, 3) float32, None when omitted
    velocities: Optional[np.ndarray]  # (N, 3) float32, None unless asked for
    # "left"/"right" -> {closed, held_vertices, position ((3,) world m), orientation ((4,) wxyz):
    # the tool at this time (pseudo: the commanded pose; robot: the end effector by forward
    # kinematics)}; robot mode also joints ((J,) float64, rad, in scene_info()["joint_names"]
    # order), gripper (the fingers' opening now, m; may stop short of the command on cloth),
    # squeeze (N, the cloth's push on the fingers: the grip), grip (what the hand does with the
    # cloth: "open", "closing", "held", "missed": its fingers stopped on little cloth or none,
    # "lost": held, then the cloth left the pads), links ((K, 3) float32, world m: the arm's
    # chain from its base through its link origins to the end effector) and pad_cuts /
    # pad_cut_depth (where its pads cut through the cloth now: cloth edges through a pad plus
    # triangles a pad's edge passes through, and how deep, m; docs/robot.md "Pads that cut
    # through the cloth").
    arms: Dict[str, dict] = field(default_factory=dict)
    # of the last step call: newton/pcg iterations, active contacts, wall_ms, intersecting_pairs
    # (the most intersecting triangle pairs after any of its steps)
    stats: dict = field(default_factory=dict)
    # Frames of a subscribing stream (steps=0) only: frames the server dropped so far because this
    # client read slower than its scenes stepped (oldest first; at most --max-queued-frames-mb queued).
    dropped_frames: int = 0
    # The scene's kinematic colliders now (robot mode: the four finger pads), each {shape ("box",
    # "capsule", ...), position (3,), orientation (4,) wxyz, half_extents (3,), radius, half_length}.
    colliders: List[dict] = field(default_factory=list)

    @property
    def failed(self) -> bool:
        return self.status == "FAILED"

    @classmethod
    def from_proto(cls, s: "pb.SceneState") -> "SceneState":
        return cls(
            scene_id=s.scene_id, status=_SCENE_STATUS.get(s.status, str(s.status)), failure=s.failure,
            time=s.time, steps=s.steps,
            positions=from_array(s.positions) if s.HasField("positions") and s.positions.data else None,
            velocities=from_array(s.velocities) if s.HasField("velocities") and s.velocities.data else None,
            arms={_ARM_NAME.get(a.arm, str(a.arm)): _arm_state(a) for a in s.arms},
            colliders=[dict(shape=c.shape, **_pose(c.pose),
                            half_extents=np.array([c.half_extents.x, c.half_extents.y, c.half_extents.z]),
                            radius=c.radius, half_length=c.half_length) for c in s.colliders],
            stats={"newton_iterations": s.stats.newton_iterations, "pcg_iterations": s.stats.pcg_iterations,
                   "active_contacts": s.stats.active_contacts, "wall_ms": s.stats.wall_ms,
                   "intersecting_pairs": s.stats.intersecting_pairs})


def _pose(p: "pb.Pose") -> dict:
    q = p.orientation if p.HasField("orientation") else pb.Quat(w=1.0)
    return {"position": np.array([p.position.x, p.position.y, p.position.z]),
            "orientation": np.array([q.w, q.x, q.y, q.z])}


def _arm_state(a: "pb.ArmState") -> dict:
    out = {"closed": a.closed, "held_vertices": a.held_vertices, **_pose(a.pose)}
    if len(a.joints):  # robot mode
        out.update(joints=np.array(a.joints, dtype=np.float64), gripper=a.gripper, squeeze=a.squeeze,
                   grip=_GRIPS.get(a.grip, ""), links=np.array(a.links, dtype=np.float32).reshape(-1, 3),
                   pad_cuts=a.pad_cuts, pad_cut_depth=a.pad_cut_depth)
    return out


def job_to_dict(j: "pb.JobInfo") -> dict:
    """A JobInfo as a plain dict (status as a name: QUEUED, RUNNING, SUCCEEDED, FAILED, INTERRUPTED)."""
    return {"job_id": j.job_id, "status": _JOB_STATUS.get(j.status, str(j.status)), "progress": j.progress,
            "sim_time": j.sim_time, "end_time": j.end_time, "message": j.message, "garment": j.garment,
            "material": j.material, "task": j.task, "label": j.label, "created_at": j.created_at,
            "finished_at": j.finished_at}


def _scene_info_to_dict(info: "pb.SceneInfo") -> dict:
    return {"vertex_count": info.vertex_count, "triangles": from_array(info.triangles),
            "rest_positions": from_array(info.rest_positions), "dt": info.dt, "backend": info.backend,
            "mode": info.mode, "left_shoulder_vertex": info.left_shoulder_vertex,
            "right_shoulder_vertex": info.right_shoulder_vertex,
            "joint_names": list(info.joint_names),
            "joint_lower": np.array(info.joint_lower, dtype=np.float64),
            "joint_upper": np.array(info.joint_upper, dtype=np.float64),
            "gripper_max": info.gripper_max,
            "table_height": info.table_height if info.HasField("table_height") else None}


MAX_URDF_BYTES = 1 << 20  # the largest URDF a request may carry (RobotSettings.urdf)


def read_urdf(urdf: Union[str, bytes, "os.PathLike[str]"]) -> bytes:
    """A URDF's bytes from its path (str or os.PathLike), its text (a str starting with "<") or
    its bytes. ValueError for a path that is no file, or a URDF over MAX_URDF_BYTES."""
    if isinstance(urdf, (bytes, bytearray)):
        data = bytes(urdf)
    elif isinstance(urdf, str) and urdf.lstrip("\ufeff \t\r\n").startswith("<"):
        data = urdf.encode()
    elif isinstance(urdf, (str, os.PathLike)):
        path = Path(os.fspath(urdf)).expanduser()
        if not path.is_file():
            raise ValueError(f"urdf: no file {str(path)!r} (give the URDF's path, its text or its bytes)")
        data = path.read_bytes()
    else:
        raise TypeError(f"urdf must be a path, the URDF's text or bytes, got {type(urdf).__name__}")
    if len(data) > MAX_URDF_BYTES:
        raise ValueError(f"urdf: {len(data)} bytes, over the {MAX_URDF_BYTES} a request may carry (send the URDF "
                         "without inlined meshes, or start the server with --robot-urdf PATH)")
    return data


def _robot_settings(mode: str, urdf, grip_force: Optional[float], finger_friction: Optional[float],
                    pad_stiffness: Optional[float] = None, lift_max_tilt_deg: Optional[float] = None,
                    place_within_reach: Optional[bool] = None) -> Optional["pb.RobotSettings"]:
    """RobotSettings of a robot-mode request (None in the other modes, which take none)."""
    given = [name for name, v in (("urdf", urdf), ("grip_force", grip_force), ("finger_friction", finger_friction),
                                  ("pad_stiffness", pad_stiffness), ("lift_max_tilt_deg", lift_max_tilt_deg),
                                  ("place_within_reach", place_within_reach))
             if v is not None]
    if mode != "robot":
        if given:
            raise ValueError(f"{', '.join(given)}: robot settings are for mode='robot' (mode is {mode!r})")
        return None
    out = pb.RobotSettings()
    if urdf is not None:
        out.urdf = read_urdf(urdf)
    for name, value in (("grip_force", grip_force), ("finger_friction", finger_friction),
                        ("pad_stiffness", pad_stiffness), ("lift_max_tilt_deg", lift_max_tilt_deg)):
        if value is not None:
            value = float(value)
            if not np.isfinite(value):
                raise ValueError(f"{name} must be finite, got {value}")
            setattr(out, name, value)
    if place_within_reach is not None:
        out.place_within_reach = bool(place_within_reach)
    return out


def _closed(target: str, call: str) -> ValueError:
    return ValueError(f"this Client is closed (its channel to {target} too); {call} needs an open one")


class _ClosedStub:
    """A closed Client's stub: every call raises ValueError. grpcio itself raises for a call on a
    closed channel, but crashes the process (SIGSEGV in _get_registered_call_handle, grpcio 1.85)
    where the channel has an interceptor, as a Client with a token has."""

    def __init__(self, target: str):
        self._target = target

    def __getattr__(self, rpc: str):
        raise _closed(self._target, rpc)


def _ids(ids: Union[str, Sequence[str]]) -> List[str]:
    if isinstance(ids, str):
        return [ids]
    return [str(i) for i in ids]


def _stack(states: List[SceneState], what: str = "positions") -> np.ndarray:
    arrays = [getattr(s, what) for s in states]
    if any(a is None for a in arrays):
        raise ValueError(f"the server returned states without {what}")
    if not arrays:
        return np.zeros((0, 0, 3), dtype=np.float32)
    if len({a.shape for a in arrays}) != 1:
        raise ValueError(f"the scenes have different vertex counts ({sorted({a.shape[0] for a in arrays})}); "
                         "use step_states() to get them one by one")
    return np.stack(arrays)


class Client:
    """A connection to one gd-server. A context manager: closing it closes the channel and stops
    a server it spawned.

    Args:
        target: "host:port" of the server.
        timeout: deadline of every unary call, s.
        stream_timeout: deadline of the streaming calls (stream, watch_job), s; None = no deadline.
        options: extra gRPC channel options [(key, value), ...] (e.g.
            ("grpc.ssl_target_name_override", "gd.example.org") when the target's address is not
            a name in the server's certificate).

    Keyword-only, for servers with tokens and TLS:
        token: the bearer token sent as `authorization: Bearer <token>` on every call (unary and
            streaming). Tokens are at least 16 printable ASCII characters without spaces.
        token_file: a file holding the token (its first line that is neither blank nor a '#'
            comment, whitespace stripped). Give token or token_file, not both; with neither,
            $GD_TOKEN_FILE names the token file when set. A missing or empty file is a ValueError
            naming it.
        tls: speak TLS, trusting the system's root certificates unless root_certificates is given.
        root_certificates: PEM bytes, PEM text or a path: the CA certificates (or the server's
            self-signed certificate) to trust; implies tls.
        certificate_chain, private_key: the client certificate and its key (PEM bytes or paths),
            for a server started with --tls-client-ca (mutual TLS); both or neither; imply tls.

    A token is sent over plaintext too when no TLS is asked for: do that on loopback only, and
    use TLS to reach a server on another machine.
    """

    def __init__(self, target: str = "127.0.0.1:50051", timeout: float = 60.0,
                 stream_timeout: Optional[float] = 24 * 3600.0, options: Sequence = (),
                 _server: Optional[LocalServer] = None, *, token: Optional[str] = None,
                 token_file: Union[None, str, "os.PathLike[str]"] = None, tls: bool = False,
                 root_certificates: Union[None, bytes, str, "os.PathLike[str]"] = None,
                 certificate_chain: Union[None, bytes, str, "os.PathLike[str]"] = None,
                 private_key: Union[None, bytes, str, "os.PathLike[str]"] = None):
        self._closed = True  # until the channel exists (close() from __del__ after a failed __init__)
        self.target = target
        self.timeout = timeout
        self.stream_timeout = stream_timeout
        self.server = _server
        # Everything that can be wrong with the options is reported before a channel exists.
        token = _creds.resolve_token(token, token_file)
        channel_creds = _creds.channel_credentials(tls=tls, root_certificates=root_certificates,
                                                   certificate_chain=certificate_chain, private_key=private_key)
        self.tls = channel_creds is not None
        self.authenticated = token is not None   # whether calls carry a token (the token is not kept here)
        opts = [("grpc.max_receive_message_length", _MAX_MESSAGE), ("grpc.max_send_message_length", _MAX_MESSAGE),
                ("grpc.keepalive_time_ms", 60000), ("grpc.keepalive_timeout_ms", 20000)]
        opts += list(options)
        if channel_creds is not None:
            channel = grpc.secure_channel(target, channel_creds, options=opts)
        else:
            channel = grpc.insecure_channel(target, options=opts)
        if token is not None:
            channel = grpc.intercept_channel(channel, _creds.TokenInterceptor(token))
        self._channel = channel
        self._stub = pb_grpc.GarmentDynamicsStub(self._channel)
        self._scene_info: Dict[str, dict] = {}
        self._closed = False

    # ---------------------------------------------------------------------------------------
    # lifecycle
    # ---------------------------------------------------------------------------------------
    @classmethod
    def spawn(cls, data_dir: Optional[str] = None, threads: Optional[int] = None,
              server_bin: Optional[str] = None, extra_args: Sequence[str] = (),
              start_timeout: float = 60.0, *, auth_token_file: Union[None, str, "os.PathLike[str]"] = None,
              tls_cert: Union[None, str, "os.PathLike[str]"] = None,
              tls_key: Union[None, str, "os.PathLike[str]"] = None,
              tls_client_ca: Union[None, str, "os.PathLike[str]"] = None, **client_kwargs) -> "Client":
        """Starts a local gd-server on a free loopback port and returns a Client connected to
        it; close() (or leaving the `with` block) stops the server.

        Args:
            data_dir: the server's data directory (reports database, uploaded meshes); default a
                temporary directory removed when the server stops.
            threads: worker threads of the server (default: the server's choice).
            server_bin: the gd-server executable; default $GD_SERVER_BIN, `gd-server` on PATH,
                or build/bin/gd-server of the checkout this package was built from.
            extra_args: more command-line arguments for gd-server.
            auth_token_file, tls_cert, tls_key, tls_client_ca: the server's --auth-token-file,
                --tls-cert, --tls-key and --tls-client-ca. Unless client_kwargs say otherwise,
                the client then uses the first token of auth_token_file (token_file=) and trusts
                tls_cert (root_certificates=; right for a self-signed certificate). With
                tls_client_ca, give the client's certificate_chain= and private_key=.
            client_kwargs: passed to Client (timeout, stream_timeout, options, token, token_file,
                tls, root_certificates, certificate_chain, private_key); the TLS ones are also
                used to wait for the server's health service.
        """
        if auth_token_file is not None and "token" not in client_kwargs and "token_file" not in client_kwargs:
            client_kwargs["token_file"] = auth_token_file
        if tls_cert is not None and "root_certificates" not in client_kwargs and not client_kwargs.get("tls"):
            client_kwargs["root_certificates"] = tls_cert
        # the client's options are checked before a server is started
        _creds.resolve_token(client_kwargs.get("token"), client_kwargs.get("token_file"))
        credentials = _creds.channel_credentials(
            tls=bool(client_kwargs.get("tls", False)), root_certificates=client_kwargs.get("root_certificates"),
            certificate_chain=client_kwargs.get("certificate_chain"), private_key=client_kwargs.get("private_key"))
        server = LocalServer(data_dir=data_dir, threads=threads, server_bin=server_bin,
                             extra_args=extra_args, start_timeout=start_timeout, auth_token_file=auth_token_file,
                             tls_cert=tls_cert, tls_key=tls_key, tls_client_ca=tls_client_ca,
                             credentials=credentials, channel_options=client_kwargs.get("options", ()))
        server.start()
        try:
            return cls(server.target, _server=server, **client_kwargs)
        except BaseException:
            server.stop()
            raise

    def close(self) -> None:
        """Closes the channel and stops a spawned server. Idempotent."""
        if self._closed:
            return
        self._closed = True
        self._stub = _ClosedStub(self.target)
        self._channel.close()
        if self.server is not None:
            self.server.stop()

    def __enter__(self) -> "Client":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def __del__(self):  # best effort; close() is the contract
        try:
            self.close()
        except Exception:
            pass

    def health(self) -> bool:
        """True when the server's health service reports SERVING."""
        if self._closed:
            raise _closed(self.target, "health")
        return health.check(self._channel, timeout=self.timeout) == health.SERVING

    # ---------------------------------------------------------------------------------------
    # scenes
    # ---------------------------------------------------------------------------------------
    def create_scenes(self, garment: Optional[str] = None, material: str = "cotton", vertices: int = 2000,
                      count: int = 1, seed: int = 0, mesh_id: Optional[str] = None, mode: str = "pseudo",
                      dt: Optional[float] = None, self_contact: Optional[bool] = None,
                      jaw_radius: Optional[float] = None, grab_time: Optional[float] = None,
                      yaw_deg: float = 0.0, offset_m: float = 0.0,
                      garment_params: Optional[Dict[str, float]] = None,
                      material_params: Optional[Dict[str, float]] = None,
                      urdf: Union[None, str, bytes, "os.PathLike[str]"] = None, grip_force: Optional[float] = None,
                      finger_friction: Optional[float] = None, pad_stiffness: Optional[float] = None,
                      initial_joints: Optional[Dict[str, Sequence[float]]] = None) -> List[str]:
        """Creates `count` identical scenes and returns their ids.

        Args:
            garment: a generated garment type (list_garments()["garments"]: towel, tshirt, ...);
                or give `mesh_id` of an uploaded mesh instead.
            material: a fabric name (list_materials()).
            vertices: target vertex count of a generated garment.
            count: number of scenes.
            seed: initial randomisation of the pose on the table (0 = none; see yaw_deg, offset_m).
            mode: "pseudo" (our grasp: vertices within the jaw radius follow a closed gripper),
                "fixed_point" (RGBench's semantics) or "robot" (two URDF arms, RGBench's Piper,
                whose fingers hold the cloth by contact and friction; docs/robot.md).
            dt, self_contact, jaw_radius, grab_time: scene settings (None = server default).
            yaw_deg, offset_m: randomisation ranges: yaw uniform in [-yaw_deg, yaw_deg] about z,
                offset uniform in [-offset_m, offset_m] along x and y (seeds other than 0).
            garment_params: sizes of a generated garment by name, e.g. {"length": 0.9,
                "hood_length": 0.25} (docs/garments.md lists the names and defaults).
            material_params: parameters of `material` replaced, by the material file's names in
                catalogue units, e.g. {"stretch_g_s2": 230000, "bending_g_mm2_s2_rad": 1000,
                "areal_density_g_m2": 220, "poisson": 0.35} (docs/materials.md).
            urdf, grip_force, finger_friction, pad_stiffness: robot mode only. urdf: the arms'
                URDF as a path, its text or its bytes (at most 1 MiB; the meshes it names are not
                read); None: the server's own (gd-server --robot-urdf), and a server without one
                answers FAILED_PRECONDITION. grip_force: N at which closing fingers stop (default
                the URDF's finger effort limit); finger_friction: the fingers' Coulomb coefficient
                on the cloth (default the material's); pad_stiffness: N/m, how stiffly a hand the
                cloth stops short is pulled along its step (default 3e5; 0: its pads wait where
                the cloth stopped them; docs/robot.md, "Pads in the solve").
            initial_joints: robot mode only: {"left": joints, "right": joints} (either may be
                left out), each arm's joints at t = 0 and after every reset, e.g. a recording's
                first row.

        What the scenes share (triangles, rest positions, dt, ...; in robot mode the arms' joint
        names and limits) is available from scene_info(id) afterwards. Robot-mode scenes start
        with each arm at `initial_joints`, else with its tool 0.25 m in front of its base and
        0.25 m up (inverse kinematics), the gripper open.
        """
        if (garment is None) == (mesh_id is None):
            raise ValueError("give exactly one of garment= and mesh_id=")
        settings = pb.SceneSettings()
        if dt is not None:
            settings.dt = float(dt)
        if self_contact is not None:
            settings.self_contact = bool(self_contact)
        if jaw_radius is not None:
            settings.jaw_radius = float(jaw_radius)
        if grab_time is not None:
            settings.grab_time = float(grab_time)
        req = pb.CreateScenesRequest(material=material, vertices=int(vertices), mode=mode, seed=int(seed),
                                     count=int(count), settings=settings,
                                     randomization=pb.Randomization(yaw_deg=yaw_deg, offset_m=offset_m),
                                     garment_params={str(k): float(v) for k, v in (garment_params or {}).items()},
                                     material_params={str(k): float(v) for k, v in (material_params or {}).items()})
        robot = _robot_settings(mode, urdf, grip_force, finger_friction, pad_stiffness)
        if initial_joints is not None:
            if mode != "robot":
                raise ValueError(f"initial_joints: robot settings are for mode='robot' (mode is {mode!r})")
            unknown = set(initial_joints) - {"left", "right"}
            if unknown:
                raise ValueError(f"initial_joints takes the arms 'left' and 'right', not {sorted(unknown)}")
            for arm, field in (("left", "left_initial_joints"), ("right", "right_initial_joints")):
                if initial_joints.get(arm) is not None:
                    q = np.asarray(initial_joints[arm], dtype=np.float64).reshape(-1)
                    if not np.isfinite(q).all():
                        raise ValueError(f"initial_joints[{arm!r}] must be finite")
                    getattr(robot, field).extend(q.tolist())
        if robot is not None:
            req.robot.SetInParent()  # present even when empty: the server's own URDF
            req.robot.MergeFrom(robot)
        if garment is not None:
            req.garment = garment
        else:
            req.mesh_id = mesh_id
        resp = self._stub.CreateScenes(req, timeout=self.timeout)
        info = _scene_info_to_dict(resp.info)
        for sid in resp.scene_ids:
            self._scene_info[sid] = info
        return list(resp.scene_ids)

    def scene_info(self, scene_id: str) -> dict:
        """What the scenes of one create_scenes call share: vertex_count, triangles (T, 3) int32,
        rest_positions (N, 3) float32 (world frame, seed 0), dt, backend, mode, the shoulder
        landmark vertices (-1 when unknown) and, in robot mode, each arm's joint_names (the order
        of an arm command's "joints"), joint_lower and joint_upper ((J,) float64, rad or m) and
        gripper_max (the largest finger opening, m; empty and 0 in the other modes). Only for
        scenes created by this client."""
        try:
            return self._scene_info[scene_id]
        except KeyError:
            raise KeyError(f"scene {scene_id!r} was not created by this client") from None

    def reset_states(self, ids, seeds: Union[None, int, Sequence[int]] = None) -> List[SceneState]:
        """Restores scenes to their initial state; seeds: None (each scene's creation seed), one
        seed for all, or one per scene."""
        ids = _ids(ids)
        if seeds is None:
            seeds = []
        elif np.isscalar(seeds):
            seeds = [int(seeds)]
        else:
            seeds = [int(s) for s in seeds]
        resp = self._stub.ResetScenes(pb.ResetScenesRequest(scene_ids=ids, seeds=seeds), timeout=self.timeout)
        return [SceneState.from_proto(s) for s in resp.states]

    def reset(self, ids, seeds: Union[None, int, Sequence[int]] = None) -> np.ndarray:
        """reset_states() returning the positions, (len(ids), N, 3) float32."""
        return _stack(self.reset_states(ids, seeds))

    def step_states(self, ids, actions: Optional[Sequence] = None, substeps: int = 1,
                    include_velocities: bool = False, omit_positions: bool = False) -> List[SceneState]:
        """Advances the scenes `substeps` steps each in one call; returns their states in `ids`
        order. A scene whose state turns non-finite comes back with status "FAILED" and the
        others carry on. See step() for the actions."""
        ids = _ids(ids)
        req = pb.StepScenesRequest(scene_ids=ids, substeps=int(substeps), include_velocities=include_velocities,
                                   omit_positions=omit_positions)
        if actions is not None:
            if isinstance(actions, dict) or isinstance(actions, pb.SceneAction):
                raise TypeError("actions must be a list with one entry (or None) per scene id")
            if len(actions) != len(ids):
                raise ValueError(f"{len(actions)} actions for {len(ids)} scene ids (give one per id, or None)")
            for sid, a in zip(ids, actions):
                if a is not None:
                    req.actions.append(scene_action(sid, a))
                    self._check_joints(req.actions[-1])
        resp = self._stub.StepScenes(req, timeout=self.timeout)
        return [SceneState.from_proto(s) for s in resp.states]

    def _check_joints(self, action: "pb.SceneAction") -> None:
        """A robot-mode scene's arm commands give as many joints as its arms have (scenes this
        client created; the server checks the others, and refuses joints in the other modes)."""
        info = self._scene_info.get(action.scene_id)
        names = info["joint_names"] if info else []
        if not names:
            return
        for c in action.arms:
            if len(c.joints) and len(c.joints) != len(names):
                raise ValueError(f"scene {action.scene_id!r}: the {_ARM_NAME.get(c.arm, c.arm)} arm's command gives "
                                 f"{len(c.joints)} joints; its arms have {len(names)} ({', '.join(names)})")

    def step(self, ids, actions: Optional[Sequence] = None, substeps: int = 1) -> np.ndarray:
        """Advances the scenes `substeps` steps each, in one call, and returns their vertex
        positions, (len(ids), N, 3) float32, world frame.

        actions: None (every arm holds its last command), or a list with one entry per id, each
        None or a dict (poses are reached at the end of the call, interpolated over the substeps):

            {"left":  {"position": (x, y, z), "orientation": (w, x, y, z), "gripper": 0.0},
             "right": {...},
             "targets": (indices (K,), positions (K, 3)),   # kinematic vertex targets
             "release_targets": False}

        Every key is optional; an arm may also be an (8,) array (position, quaternion wxyz,
        gripper). gripper is the opening in m (0 closed .. 0.035 open, default open); the
        gripper grasps when it falls below 0.01. In robot mode an arm may give "joints" (its
        joint angles in scene_info(id)["joint_names"] order, rad) instead of the pose, and the
        fingers close toward the gripper opening until they squeeze the cloth with the grip
        force. See garmentdynamics.actions.
        """
        return _stack(self.step_states(ids, actions, substeps))

    def get_state(self, ids, include_velocities: bool = False) -> List[SceneState]:
        """The current states of the scenes, in `ids` order."""
        resp = self._stub.GetState(pb.GetStateRequest(scene_ids=_ids(ids), include_velocities=include_velocities),
                                   timeout=self.timeout)
        return [SceneState.from_proto(s) for s in resp.states]

    def describe(self, ids) -> List[dict]:
        """What each scene was created with (as scene_info(): triangles, rest positions, mode, the
        arms' joints, table_height), also for scenes another client created (a viewer's), in
        `ids` order; scene_info() knows them afterwards."""
        ids = _ids(ids)
        resp = self._stub.GetState(pb.GetStateRequest(scene_ids=ids, include_info=True), timeout=self.timeout)
        infos = [_scene_info_to_dict(i) for i in resp.infos]
        for sid, info in zip(ids, infos):
            self._scene_info[sid] = info
        return infos

    def positions(self, ids) -> np.ndarray:
        """The current positions, (len(ids), N, 3) float32."""
        return _stack(self.get_state(ids))

    def stream(self, ids, every: int = 1, steps: int = 0, max_frames: int = 0,
               timeout: Optional[float] = None) -> Iterator[SceneState]:
        """Yields a SceneState of each scene every `every`-th step it makes: steps made by other
        step() calls, or, with steps > 0, by the stream itself. Ends when the steps are done,
        after max_frames frames (0 = no limit), when the scenes are destroyed, or when the
        iterator is closed (the call is then cancelled). Watching (steps = 0), it returns once the
        server has the subscription: every step made after the call, from any client, reaches
        the iterator."""
        call = self._stub.StreamFrames(
            pb.StreamFramesRequest(scene_ids=_ids(ids), every=int(every), steps=int(steps),
                                   max_frames=int(max_frames)),
            timeout=self.stream_timeout if timeout is None else timeout)
        if int(steps) == 0:
            call.initial_metadata()  # sent once the subscription is in place (an error ends the call: raised below)
        return self._frames(call)

    def stream_job(self, job_id: str, every: int = 1, max_frames: int = 0,
                   timeout: Optional[float] = None) -> Iterator[SceneState]:
        """Yields the scene of a queued or running job every `every`-th step of its run, until the
        job ends, after max_frames frames (0 = no limit), or when the iterator is closed. The
        frames carry the job id as scene_id; the job's scene (as scene_info(): triangles, table,
        joints; rest_positions are the positions at the first frame) is known as
        scene_info(job_id) from the first frame on. Returns once the server has the
        subscription. A finished job raises FAILED_PRECONDITION (its report has the run's
        animation)."""
        call = self._stub.StreamFrames(
            pb.StreamFramesRequest(job_id=str(job_id), every=int(every), max_frames=int(max_frames)),
            timeout=self.stream_timeout if timeout is None else timeout)
        call.initial_metadata()
        return self._frames(call, job_id=str(job_id))

    def _frames(self, call, job_id: Optional[str] = None) -> Iterator[SceneState]:
        """A StreamFrames call's frames; the call is cancelled when the iterator is closed."""
        try:
            for msg in call:
                if job_id is not None and msg.HasField("info"):
                    self._scene_info[job_id] = _scene_info_to_dict(msg.info)
                frame = SceneState.from_proto(msg.state)
                frame.dropped_frames = msg.dropped_frames
                yield frame
        finally:
            call.cancel()

    def destroy(self, ids) -> int:
        """Destroys scenes; returns how many were destroyed."""
        ids = _ids(ids)
        resp = self._stub.DestroyScenes(pb.DestroyScenesRequest(scene_ids=ids), timeout=self.timeout)
        for sid in ids:
            self._scene_info.pop(sid, None)
        return resp.destroyed

    # ---------------------------------------------------------------------------------------
    # jobs
    # ---------------------------------------------------------------------------------------
    def submit_job(self, garment: Optional[str] = None, material: str = "cotton", task: str = "grasp",
                   mode: str = "pseudo", vertices: int = 2000, mesh_id: Optional[str] = None,
                   trajectory: Union[None, str, bytes, Path] = None, trajectory_format: Optional[str] = None,
                   capture: str = "", dt: Optional[float] = None, time_scale: Optional[float] = None,
                   settle: Optional[float] = None, self_contact: Optional[bool] = None, icp: bool = False,
                   label: str = "", garment_params: Optional[Dict[str, float]] = None,
                   task_params: Optional[Dict[str, float]] = None,
                   material_params: Optional[Dict[str, float]] = None,
                   urdf: Union[None, str, bytes, "os.PathLike[str]"] = None, grip_force: Optional[float] = None,
                   finger_friction: Optional[float] = None, pad_stiffness: Optional[float] = None,
                   lift_max_tilt_deg: Optional[float] = None,
                   place_within_reach: Optional[bool] = None, refine_grasp_edge: Optional[float] = None,
                   refine_grasp_radius: Optional[float] = None) -> str:
        """Submits a whole rollout (garment + task) to run on the server; returns the job id.

        trajectory: a path to our trajectory CSV/JSON file (docs/tasks.md), or its text/bytes;
        trajectory_format "csv" | "json" (guessed from a path's suffix). capture: an RGBench
        capture directory under the server's capture root. garment_params: sizes of a generated
        garment by name, as in create_scenes. task_params: parameters of the generated task by
        name, e.g. {"fold_duration": 5.0} (docs/tasks.md). material_params: parameters of the
        material replaced, as in create_scenes. mode "robot": the arms of urdf (a path, its text
        or bytes; None: the server's --robot-urdf) with grip_force, finger_friction and
        pad_stiffness, as in create_scenes; lift_max_tilt_deg: a generated grasp's lift (fling's height) left to its
        default is lowered until no hand tilts more than this from pointing down (default 30,
        `gd run --lift-max-tilt`); place_within_reach: a generated task's garment first moved along
        the table to where the arms lift it highest (`gd run --place-within-reach`).
        refine_grasp_edge: the mesh refined to this edge (m, at least 0.001) within
        refine_grasp_radius (m, default 0.05) of the task's grasp points (`gd run --refine-grasp`;
        robot mode's pads hold finer cloth better); the refined garment counts against the
        server's vertex limit (RESOURCE_EXHAUSTED past it). The other arguments mirror `gd run`.
        """
        if (garment is None) == (mesh_id is None):
            raise ValueError("give exactly one of garment= and mesh_id=")
        req = pb.SubmitJobRequest(material=material, task=task, mode=mode, vertices=int(vertices),
                                  capture=capture, icp=icp, label=label,
                                  garment_params={str(k): float(v) for k, v in (garment_params or {}).items()},
                                  task_params={str(k): float(v) for k, v in (task_params or {}).items()},
                                  material_params={str(k): float(v) for k, v in (material_params or {}).items()})
        robot = _robot_settings(mode, urdf, grip_force, finger_friction, pad_stiffness, lift_max_tilt_deg,
                                place_within_reach)
        if robot is not None:
            req.robot.SetInParent()  # present even when empty: the server's own URDF
            req.robot.MergeFrom(robot)
        if garment is not None:
            req.garment = garment
        else:
            req.mesh_id = mesh_id
        if trajectory is not None:
            if isinstance(trajectory, Path) or (isinstance(trajectory, str) and "\n" not in trajectory
                                                and Path(trajectory).is_file()):
                path = Path(trajectory)
                trajectory_format = trajectory_format or path.suffix.lstrip(".").lower()
                trajectory = path.read_bytes()
            req.trajectory = trajectory.encode() if isinstance(trajectory, str) else bytes(trajectory)
            if not trajectory_format:
                raise ValueError("trajectory_format ('csv' or 'json') is required with trajectory text")
            req.trajectory_format = trajectory_format
        for name, value in (("dt", dt), ("time_scale", time_scale), ("settle", settle)):
            if value is not None:
                setattr(req, name, float(value))
        if self_contact is not None:
            req.self_contact = bool(self_contact)
        for name, value in (("refine_grasp_edge", refine_grasp_edge), ("refine_grasp_radius", refine_grasp_radius)):
            if value is not None:
                setattr(req, name, float(value))
        return self._stub.SubmitJob(req, timeout=self.timeout).job_id

    def watch_job(self, job: str, timeout: Optional[float] = None) -> Iterator[dict]:
        """Yields the job's progress (job_to_dict) until it ends; the last one has a final status
        (SUCCEEDED, FAILED, INTERRUPTED or CANCELLED)."""
        call = self._stub.WatchJob(pb.WatchJobRequest(job_id=job),
                                   timeout=self.stream_timeout if timeout is None else timeout)
        try:
            for msg in call:
                yield job_to_dict(msg.job)
        finally:
            call.cancel()

    def get_report(self, job: str, include_files: bool = False) -> dict:
        """The job's report: {"job": job dict, "summary": summary.json parsed (None if empty),
        "file_names": [...], "files": {name: bytes} (with include_files)}. FAILED_PRECONDITION
        while the job has not finished."""
        resp = self._stub.GetReport(pb.GetReportRequest(job_id=job, include_files=include_files),
                                    timeout=self.timeout)
        return {"job": job_to_dict(resp.job),
                "summary": json.loads(resp.summary_json) if resp.summary_json else None,
                "file_names": list(resp.file_names),
                "files": {f.name: f.data for f in resp.files}}

    def cancel_job(self, job: str) -> dict:
        """Cancels a job (CancelJob): a queued one ends CANCELLED at once, a running one at its
        next step (the dict returned may still say RUNNING). FAILED_PRECONDITION (grpc.RpcError)
        for a job that has already finished otherwise."""
        return job_to_dict(self._stub.CancelJob(pb.CancelJobRequest(job_id=job), timeout=self.timeout).job)

    def wait_report(self, job: str, progress: bool = True, include_files: bool = False,
                    timeout: Optional[float] = None, settle_timeout: float = 10.0) -> dict:
        """Waits for the job to end (a progress bar on stderr with progress=True: tqdm if
        installed, else a text bar) and returns get_report(job)."""
        bar = ProgressBar(desc=f"job {job}", enabled=progress)
        try:
            for info in self.watch_job(job, timeout=timeout):
                bar.update(info["progress"], f"{info['status'].lower()} t={info['sim_time']:.2f}/{info['end_time']:.2f} s")
                if info["status"] in FINAL_JOB_STATUSES:
                    break
        finally:
            bar.close()
        # A stream that ended without a final status (server shutting down) makes GetReport answer
        # FAILED_PRECONDITION, which surfaces as grpc.RpcError. A report read right after the final
        # progress message may still show the job unfinished while the server stores it; read
        # again for a short while until the stored report is final.
        deadline = time.monotonic() + settle_timeout
        report = self.get_report(job, include_files=include_files)
        while report["job"]["status"] not in FINAL_JOB_STATUSES and time.monotonic() < deadline:
            time.sleep(0.05)
            report = self.get_report(job, include_files=include_files)
        return report

    def list_reports(self, limit: int = 100, offset: int = 0) -> List[dict]:
        """Jobs with stored reports, newest first (job_to_dict each)."""
        resp = self._stub.ListReports(pb.ListReportsRequest(limit=int(limit), offset=int(offset)),
                                      timeout=self.timeout)
        return [job_to_dict(j) for j in resp.jobs]

    def count_reports(self) -> int:
        """How many reports the server stores."""
        return self._stub.ListReports(pb.ListReportsRequest(limit=1), timeout=self.timeout).total

    # ---------------------------------------------------------------------------------------
    # assets and server
    # ---------------------------------------------------------------------------------------
    def upload_mesh(self, path_or_bytes: Union[str, Path, bytes], name: Optional[str] = None) -> str:
        """Uploads a Wavefront OBJ (a path, or its bytes) for create_scenes(mesh_id=) and
        submit_job(mesh_id=); returns the mesh id."""
        if isinstance(path_or_bytes, (bytes, bytearray)):
            data = bytes(path_or_bytes)
            name = name or "mesh"
        else:
            path = Path(path_or_bytes)
            data = path.read_bytes()
            name = name or path.stem
        return self._stub.UploadMesh(pb.UploadMeshRequest(name=name, obj=data), timeout=self.timeout).mesh_id

    def list_garments(self) -> dict:
        """{"garments": [generated types], "meshes": [{mesh_id, name, vertices, triangles}]}."""
        resp = self._stub.ListGarments(pb.ListGarmentsRequest(), timeout=self.timeout)
        return {"garments": list(resp.garments),
                "meshes": [{"mesh_id": m.mesh_id, "name": m.name, "vertices": m.vertices,
                            "triangles": m.triangles} for m in resp.meshes]}

    def list_materials(self) -> List[dict]:
        """[{name, density (kg/m^2), thickness (m)}]."""
        resp = self._stub.ListMaterials(pb.ListMaterialsRequest(), timeout=self.timeout)
        return [{"name": m.name, "density": m.density, "thickness": m.thickness} for m in resp.materials]

    def server_info(self) -> dict:
        """{version, backend, threads, max_scenes, max_vertices, scenes, jobs_running}."""
        r = self._stub.GetServerInfo(pb.GetServerInfoRequest(), timeout=self.timeout)
        return {"version": r.version, "backend": r.backend, "threads": r.threads, "max_scenes": r.max_scenes,
                "max_vertices": r.max_vertices, "scenes": r.scenes, "jobs_running": r.jobs_running}

    @property
    def stub(self) -> "pb_grpc.GarmentDynamicsStub":
        """The raw gRPC stub, for requests this class does not wrap."""
        return self._stub

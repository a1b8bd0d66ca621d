"""Per-scene actions of StepScenes: plain Python/numpy values -> proto SceneAction.

An action is None (the scene carries on: arms hold their last command) or a dict with any of

    {
      "left":  {"position": (x, y, z),            # m, world frame (z up, table at z = 0)
                "orientation": (w, x, y, z),      # optional, unit quaternion, w first; default identity
                "gripper": 0.035,                 # optional opening in m, 0 = closed .. 0.035 = open;
                                                  # default 0.035 (open); grasps below 0.01
                "time": 0.5,                      # optional scene time of this sample, s; default:
                                                  # the end of the call's steps
                "joints": (q1, ..., q6)},         # robot mode: the arm's joint angles (rad, in
                                                  # scene_info()["joint_names"] order); position is
                                                  # then optional and unused
      "right": {...},                             # same as "left"
      "targets": (indices, positions),            # optional: int (K,) vertex indices and (K, 3) positions
                                                  # reached kinematically over the step, then held
      "release_targets": False,                   # optional: release every kinematic target set earlier
    }

An arm may also be given as an (8,) array: position (3), quaternion wxyz (4), gripper (1), or as
a list of such commands: samples of its trajectory in increasing "time" (an untimed one last),
each after the arm's last sample. With samples, one call of many substeps follows a sampled
motion (the arm is interpolated between samples: linear position and gripper, SLERP
orientation); samples past the call's end are kept for later calls, so a whole trajectory may be
sent with the first call.
"targets" may also be a dict {"indices": ..., "positions": ...}. A ready-made
`garmentdynamics.v1.garmentdynamics_pb2.SceneAction` is passed through (its scene_id is set).

Robot mode (create_scenes(mode="robot")): an arm's "joints" drive it directly (linearly
interpolated between samples); without them its pose is reached by the server's inverse
kinematics (of the tool frame: z the approach, x the direction the fingers close along;
INVALID_ARGUMENT when out of reach). "gripper" is then the finger opening the force-limited
fingers close toward (0 .. scene_info()["gripper_max"]). Other modes refuse joints
(INVALID_ARGUMENT). `joint_array_to_action` turns a (2, J + 1) array of joint targets and
gripper openings into an action.
"""

from typing import Optional

import numpy as np

from ._proto import pb
from .arrays import to_array

GRIPPER_OPEN = 0.035
_ARMS = {"left": pb.ARM_LEFT, "right": pb.ARM_RIGHT}
_ALLOWED = {"left", "right", "targets", "release_targets"}


def _vec(v, n, what):
    arr = np.asarray(v, dtype=np.float64).reshape(-1)
    if arr.shape != (n,):
        raise ValueError(f"{what} must have {n} numbers, got shape {np.shape(v)}")
    return arr


def _joints(v, arm) -> np.ndarray:
    """An arm's joint angles: a non-empty 1-D sequence of finite numbers."""
    try:
        arr = np.asarray(v, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"the {arm} arm's joints must be numbers (rad), got {v!r}") from None
    if arr.ndim != 1 or arr.size == 0:
        raise ValueError(f"the {arm} arm's joints must be a flat sequence of its joint angles (rad, in "
                         f"scene_info()['joint_names'] order), got shape {arr.shape}")
    if not np.isfinite(arr).all():
        raise ValueError(f"the {arm} arm's joints must be finite, got {arr.tolist()}")
    return arr


def arm_command(arm: str, cmd) -> "pb.ArmCommand":
    """One arm's command from a dict or an (8,) array (see the module docstring)."""
    joints = None
    if isinstance(cmd, dict):
        unknown = set(cmd) - {"position", "orientation", "gripper", "time", "joints"}
        if unknown:
            raise ValueError(f"unknown keys {sorted(unknown)} in the {arm} arm's command; "
                             "use position, orientation, gripper, time, joints")
        if cmd.get("joints") is not None:
            joints = _joints(cmd["joints"], arm)
        if "position" not in cmd and joints is None:
            raise ValueError(f"the {arm} arm's command needs a position (or, in robot mode, joints)")
        pos = _vec(cmd["position"], 3, f"{arm}.position") if "position" in cmd else np.zeros(3)
        quat = _vec(cmd.get("orientation", (1.0, 0.0, 0.0, 0.0)), 4, f"{arm}.orientation")
        gripper = float(cmd.get("gripper", GRIPPER_OPEN))
        time = cmd.get("time")
    else:
        v = _vec(cmd, 8, f"the {arm} arm's command (position 3, quaternion wxyz 4, gripper 1)")
        pos, quat, gripper = v[:3], v[3:7], float(v[7])
        time = None
    pose = pb.Pose(position=pb.Vec3(x=pos[0], y=pos[1], z=pos[2]),
                   orientation=pb.Quat(w=quat[0], x=quat[1], y=quat[2], z=quat[3]))
    out = pb.ArmCommand(arm=_ARMS[arm], pose=pose, gripper=gripper)
    if time is not None:
        out.time = float(time)
    if joints is not None:
        out.joints.extend(joints.tolist())
    return out


def scene_action(scene_id: str, action) -> "pb.SceneAction":
    """The proto action of one scene (see the module docstring for the accepted forms)."""
    if isinstance(action, pb.SceneAction):
        out = pb.SceneAction()
        out.CopyFrom(action)
        out.scene_id = scene_id
        return out
    if not isinstance(action, dict):
        raise TypeError(f"an action must be None, a dict or a SceneAction, got {type(action).__name__}")
    unknown = set(action) - _ALLOWED
    if unknown:
        raise ValueError(f"unknown action keys {sorted(unknown)}; use {sorted(_ALLOWED)}")
    out = pb.SceneAction(scene_id=scene_id, release_targets=bool(action.get("release_targets", False)))
    for arm in ("left", "right"):
        cmd = action.get(arm)
        if cmd is None:
            continue
        if isinstance(cmd, (list, tuple)) and len(cmd) > 0 and not np.isscalar(cmd[0]):
            out.arms.extend(arm_command(arm, c) for c in cmd)  # samples of the arm's trajectory
        else:
            out.arms.append(arm_command(arm, cmd))
    targets = action.get("targets")
    if targets is not None:
        if isinstance(targets, dict):
            idx, pos = targets["indices"], targets["positions"]
        else:
            idx, pos = targets
        idx = np.asarray(idx).reshape(-1)
        pos = np.asarray(pos, dtype=np.float64).reshape(-1, 3)
        if len(idx) != len(pos):
            raise ValueError(f"targets: {len(idx)} indices but {len(pos)} positions")
        out.targets.indices.CopyFrom(to_array(idx, "int32"))
        out.targets.positions.CopyFrom(to_array(pos, "float32"))
    return out


def arm_array_to_action(a) -> dict:
    """A (2, 8) array [left, right] x (position 3, quaternion wxyz 4, gripper 1) -> action dict.
    A quaternion of (near) zero length becomes the identity; others are normalised."""
    a = np.asarray(a, dtype=np.float64).reshape(2, 8)
    out = {}
    for i, arm in enumerate(("left", "right")):
        q = a[i, 3:7]
        n = np.linalg.norm(q)
        q = q / n if np.isfinite(n) and n > 1e-9 else np.array([1.0, 0.0, 0.0, 0.0])
        out[arm] = {"position": a[i, :3], "orientation": q, "gripper": float(a[i, 7])}
    return out


def joint_array_to_action(a, joints: Optional[int] = None) -> dict:
    """A (2, J + 1) array [left, right] x (joint angles J in rad, gripper opening 1 in m) -> the
    action dict of robot mode. joints: J when known (len(scene_info()["joint_names"])); the
    array is then checked against it (a flat array of 2 (J + 1) numbers is reshaped)."""
    a = np.asarray(a, dtype=np.float64)
    if joints is not None and a.ndim == 1 and a.size == 2 * (joints + 1):
        a = a.reshape(2, joints + 1)
    if a.ndim != 2 or a.shape[0] != 2 or a.shape[1] < 2:
        raise ValueError("joint actions must be a (2, J + 1) array: rows [left, right], the J joint angles (rad) "
                         f"then the gripper opening (m); got shape {a.shape}")
    if joints is not None and a.shape[1] != joints + 1:
        raise ValueError(f"joint actions must be (2, {joints + 1}): the arms have {joints} joints, then the gripper; "
                         f"got shape {a.shape}")
    return {arm: {"joints": a[i, :-1], "gripper": float(a[i, -1])} for i, arm in enumerate(("left", "right"))}

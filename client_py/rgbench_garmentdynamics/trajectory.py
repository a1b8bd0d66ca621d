"""RGBench's per-arm CSVs (joints/{left,right}_arm_joint_states_and_end_pose.csv) and their
interpolation.

Pose mode (load_pose_csv), as RGBench's fixed-point environments read them (rgbench-format.md
sections 1, 3):

- columns time (absolute Unix s), pos_1..pos_6, pos_gripper (m, 0 closed .. 0.035 open),
  pos_x, pos_y, pos_z (m, in the arm's own base frame), orn_w, orn_x, orn_y, orn_z;
- world position = base position + base offset (left (0, +0.25, 0), right (0, -0.25, 0); the
  bases are not rotated), orientation unchanged (w first);
- rows before first time + start_time_offset are dropped;
- interpolation between bracketing samples: linear position and gripper, SLERP orientation;
  clamped to the first/last sample outside the recorded range.

Joint mode (load_joint_csv), as RGBench's robot mode (PyBullet) reads them (section 4): columns
time, pos_1..pos_6 (joint1..joint6, rad) and pos_gripper (m, 0 closed .. 0.035 open), by name
(RGBench's loader takes every pos_* column but pos_x/y/z, pos_gripper last: the same six plus
the gripper for the Piper; the pose columns are not needed). Joint angles are the arm's own, so no
base offset applies (the simulator places each arm's base). Rows are sorted by time (stable), and
those before first time + start_time_offset are dropped; interpolation is linear (JointTrack.at),
clamped outside the recorded range.
"""

import csv
from dataclasses import dataclass
from pathlib import Path

import numpy as np

BASE_OFFSETS = {"left": np.array([0.0, 0.25, 0.0]), "right": np.array([0.0, -0.25, 0.0])}
_COLUMNS = ("time", "pos_gripper", "pos_x", "pos_y", "pos_z", "orn_w", "orn_x", "orn_y", "orn_z")
JOINT_COLUMNS = tuple(f"pos_{i}" for i in range(1, 7))  # the Piper's joint1..joint6, rad


def _bracket(ts: np.ndarray, t_abs: float):
    """(i, a): t_abs lies a of the way from sample i to i + 1 (a = 0 at or outside the ends,
    i then the nearest end)."""
    if t_abs <= ts[0]:
        return 0, 0.0
    if t_abs >= ts[-1]:
        return len(ts) - 1, 0.0
    i = int(np.searchsorted(ts, t_abs, side="right")) - 1
    span = ts[i + 1] - ts[i]
    return i, ((t_abs - ts[i]) / span if span > 0 else 0.0)


@dataclass
class PoseTrack:
    """One arm's samples: times (T,) absolute s, positions (T, 3) world m, quats (T, 4) wxyz,
    gripper (T,) m."""
    times: np.ndarray
    positions: np.ndarray
    quats: np.ndarray
    gripper: np.ndarray

    @property
    def start(self) -> float:
        return float(self.times[0])

    def at(self, t_abs: float):
        """(position (3,), quaternion wxyz (4,), gripper) at absolute time t_abs."""
        i, a = _bracket(self.times, t_abs)
        if a == 0.0:
            return self.positions[i].copy(), self.quats[i].copy(), float(self.gripper[i])
        pos = (1 - a) * self.positions[i] + a * self.positions[i + 1]
        grip = (1 - a) * self.gripper[i] + a * self.gripper[i + 1]
        return pos, slerp(self.quats[i], self.quats[i + 1], a), float(grip)


def slerp(q0: np.ndarray, q1: np.ndarray, a: float) -> np.ndarray:
    """Spherical linear interpolation of unit quaternions (wxyz), shortest arc."""
    q0 = q0 / np.linalg.norm(q0)
    q1 = q1 / np.linalg.norm(q1)
    d = float(np.dot(q0, q1))
    if d < 0:
        q1, d = -q1, -d
    if d > 0.9995:
        q = q0 + a * (q1 - q0)
        return q / np.linalg.norm(q)
    theta = np.arccos(min(d, 1.0))
    s = np.sin(theta)
    return (np.sin((1 - a) * theta) * q0 + np.sin(a * theta) * q1) / s


def _read_columns(path: Path, columns, what: str) -> np.ndarray:
    """The named columns of a CSV as a float array (rows in file order)."""
    with path.open(newline="") as f:
        reader = csv.DictReader(f)
        missing = [c for c in columns if c not in (reader.fieldnames or [])]
        if missing:
            raise ValueError(f"{path}: missing columns {missing} ({what})")
        rows = []
        for line, r in enumerate(reader, start=2):
            try:
                rows.append([float(r[c]) for c in columns])
            except (TypeError, ValueError):
                raise ValueError(f"{path}, line {line}: {', '.join(columns)} must be numbers") from None
    if not rows:
        raise ValueError(f"{path}: no samples")
    return np.array(rows, dtype=np.float64)


def load_pose_csv(path, arm: str, start_time_offset: float = 0.0) -> PoseTrack:
    """Reads one arm's CSV in pose mode (world frame). pos_gripper is optional (RGBench's pose mode
    does not read it; default open, 0.035 m). Raises FileNotFoundError or ValueError naming the
    file and what is wrong."""
    path = Path(path)
    with path.open(newline="") as f:
        has_gripper = "pos_gripper" in (csv.DictReader(f).fieldnames or [])
    columns = _COLUMNS if has_gripper else tuple(c for c in _COLUMNS if c != "pos_gripper")
    data = _read_columns(path, columns, "expected RGBench's joint-states-and-end-pose CSV")
    if not has_gripper:
        data = np.insert(data, 1, 0.035, axis=1)
    data = data[np.argsort(data[:, 0], kind="stable")]
    data = data[data[:, 0] >= data[0, 0] + float(start_time_offset)]
    if len(data) == 0:
        raise ValueError(f"{path}: no samples after start_time_offset {start_time_offset}")
    return PoseTrack(times=data[:, 0], positions=data[:, 2:5] + BASE_OFFSETS[arm], quats=data[:, 5:9],
                     gripper=data[:, 1])


@dataclass
class JointTrack:
    """One arm's joint samples: times (T,) absolute s, joints (T, 6) rad (joint1..joint6),
    gripper (T,) m."""
    times: np.ndarray
    joints: np.ndarray
    gripper: np.ndarray

    @property
    def start(self) -> float:
        return float(self.times[0])

    def at(self, t_abs: float):
        """(joints (6,), gripper) at absolute time t_abs: linear between the bracketing samples,
        clamped to the first/last sample outside the recorded range."""
        i, a = _bracket(self.times, t_abs)
        if a == 0.0:
            return self.joints[i].copy(), float(self.gripper[i])
        return ((1 - a) * self.joints[i] + a * self.joints[i + 1],
                float((1 - a) * self.gripper[i] + a * self.gripper[i + 1]))


def load_joint_csv(path, arm: str, start_time_offset: float = 0.0) -> JointTrack:
    """Reads one arm's CSV in joint mode (time, pos_1..pos_6, pos_gripper). Raises
    FileNotFoundError or ValueError naming the file and what is wrong."""
    if arm not in BASE_OFFSETS:
        raise ValueError(f"arm must be left or right, got {arm!r}")
    path = Path(path)
    columns = ("time",) + JOINT_COLUMNS + ("pos_gripper",)
    data = _read_columns(path, columns, "expected RGBench's joint-states CSV: time, pos_1..pos_6, pos_gripper")
    if not np.isfinite(data).all():
        bad = int(np.flatnonzero(~np.isfinite(data).all(axis=1))[0])
        raise ValueError(f"{path}, line {bad + 2}: not finite: {dict(zip(columns, data[bad].tolist()))}")
    data = data[np.argsort(data[:, 0], kind="stable")]
    data = data[data[:, 0] >= data[0, 0] + float(start_time_offset)]
    if len(data) == 0:
        raise ValueError(f"{path}: no samples after start_time_offset {start_time_offset}")
    return JointTrack(times=data[:, 0], joints=data[:, 1:7], gripper=data[:, 7])

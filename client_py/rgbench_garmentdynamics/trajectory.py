"""RGBench's per-arm end-pose CSVs (joints/{left,right}_arm_joint_states_and_end_pose.csv) and
their interpolation, as its fixed-point environments read them (rgbench-format.md sections 1, 3):

- columns time (absolute Unix s), pos_1..pos_6, pos_gripper (m, 0 closed .. 0.035 open),
  pos_x, pos_y, pos_z (m, in the arm's own base frame), orn_w, orn_x, orn_y, orn_z;
- world position = base position + base offset (left (0, +0.25, 0), right (0, -0.25, 0); the
  bases are not rotated), orientation unchanged (w first);
- rows before first time + start_time_offset are dropped;
- interpolation between bracketing samples: linear position and gripper, SLERP orientation;
  clamped to the first/last sample outside the recorded range.
"""

import csv
from dataclasses import dataclass
from pathlib import Path

import numpy as np

BASE_OFFSETS = {"left": np.array([0.0, 0.25, 0.0]), "right": np.array([0.0, -0.25, 0.0])}
_COLUMNS = ("time", "pos_gripper", "pos_x", "pos_y", "pos_z", "orn_w", "orn_x", "orn_y", "orn_z")


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
        ts = self.times
        if t_abs <= ts[0]:
            return self.positions[0].copy(), self.quats[0].copy(), float(self.gripper[0])
        if t_abs >= ts[-1]:
            return self.positions[-1].copy(), self.quats[-1].copy(), float(self.gripper[-1])
        i = int(np.searchsorted(ts, t_abs, side="right")) - 1
        span = ts[i + 1] - ts[i]
        a = (t_abs - ts[i]) / span if span > 0 else 0.0
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


def load_pose_csv(path, arm: str, start_time_offset: float = 0.0) -> PoseTrack:
    """Reads one arm's CSV in pose mode (world frame). Raises FileNotFoundError or ValueError
    naming the file and what is wrong."""
    path = Path(path)
    with path.open(newline="") as f:
        reader = csv.DictReader(f)
        missing = [c for c in _COLUMNS if c not in (reader.fieldnames or [])]
        if missing:
            raise ValueError(f"{path}: missing columns {missing} (expected RGBench's joint-states-and-end-pose CSV)")
        rows = [[float(r[c]) for c in _COLUMNS] for r in reader]
    if not rows:
        raise ValueError(f"{path}: no samples")
    data = np.array(rows, dtype=np.float64)
    data = data[np.argsort(data[:, 0], kind="stable")]
    data = data[data[:, 0] >= data[0, 0] + float(start_time_offset)]
    if len(data) == 0:
        raise ValueError(f"{path}: no samples after start_time_offset {start_time_offset}")
    return PoseTrack(times=data[:, 0], positions=data[:, 2:5] + BASE_OFFSETS[arm], quats=data[:, 5:9],
                     gripper=data[:, 1])

"""Task rewards of the Gymnasium environments: cheap functions of the vertex positions.

- "lift": the gain of the garment's mean height since the previous step (m). Its sum over an
  episode is the mean height gained since the reset, so a policy is paid for lifting the garment
  and holding it up, and charged for dropping it.
- "fold": the decrease of the mean distance between mirrored vertex pairs since the previous
  step (m). Pairs are fixed at construction from the rest shape: each vertex in the far half
  (larger x, away from the robots) is paired with the vertex nearest to its mirror image across
  the garment's middle line x = x_mid. A perfect fold in half along that line brings every pair
  together, so the episode's sum is how much closer the halves came.

A scene that fails (non-finite state) ends the episode with reward FAILURE_REWARD.
"""

import numpy as np

FAILURE_REWARD = -10.0
TASKS = ("lift", "fold")


class Reward:
    """potential(x) per task; reward = potential(x_t) - potential(x_{t-1})."""

    def __init__(self, task: str, rest_positions: np.ndarray):
        if task not in TASKS:
            raise ValueError(f"unknown task {task!r}; choose one of {TASKS}")
        self.task = task
        rest = np.asarray(rest_positions, dtype=np.float64)
        if task == "fold":
            x_mid = 0.5 * (rest[:, 0].min() + rest[:, 0].max())
            far = np.flatnonzero(rest[:, 0] > x_mid)
            near = np.flatnonzero(rest[:, 0] <= x_mid)
            mirror = rest[far].copy()
            mirror[:, 0] = 2 * x_mid - mirror[:, 0]
            # Nearest near-half vertex of each mirror image, in chunks (memory O(chunk * N)).
            near_xy = rest[near, :2]
            match = np.empty(len(far), dtype=np.int64)
            for i in range(0, len(far), 1024):
                d2 = ((mirror[i:i + 1024, None, :2] - near_xy[None, :, :]) ** 2).sum(axis=2)
                match[i:i + 1024] = near[np.argmin(d2, axis=1)]
            self.pairs = np.stack([far, match], axis=1)

    def potential(self, x: np.ndarray) -> np.ndarray:
        """x: (..., N, 3) -> (...,) float64."""
        x = np.asarray(x, dtype=np.float64)
        if self.task == "lift":
            return x[..., :, 2].mean(axis=-1)
        a = x[..., self.pairs[:, 0], :]
        b = x[..., self.pairs[:, 1], :]
        return -np.linalg.norm(a - b, axis=-1).mean(axis=-1)

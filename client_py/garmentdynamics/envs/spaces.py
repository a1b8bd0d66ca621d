"""Observation and action spaces shared by the single-scene and vector environments."""

import numpy as np
from gymnasium import spaces

# Per arm: position x, y, z (m, world frame), quaternion w, x, y, z, gripper opening (m).
# Positions span the table in front of the two arms (bases at y = +-0.25, garments placed from
# x = 0.1 forward) up to 0.6 m above it.
ARM_LOW = np.array([-0.2, -0.6, 0.0, -1, -1, -1, -1, 0.0], dtype=np.float32)
ARM_HIGH = np.array([1.0, 0.6, 0.6, 1, 1, 1, 1, 0.035], dtype=np.float32)


def action_space() -> spaces.Box:
    """Box (2, 8): rows [left, right], columns position (3), quaternion wxyz (4, normalised by
    the env; a zero quaternion means identity), gripper opening (1) in [0, 0.035] m (closes
    below 0.01 m)."""
    return spaces.Box(low=np.stack([ARM_LOW, ARM_LOW]), high=np.stack([ARM_HIGH, ARM_HIGH]), dtype=np.float32)


# Vertex positions stay within this many metres of the world origin: the arms reach less than a
# metre, the table is the plane z = 0 and a failing scene is restored to its last finite state.
OBSERVATION_BOUND = 5.0


def observation_space(vertex_count: int) -> spaces.Box:
    """Box (N, 3) float32: the vertex positions, m, world frame, within +-OBSERVATION_BOUND."""
    return spaces.Box(low=-OBSERVATION_BOUND, high=OBSERVATION_BOUND, shape=(vertex_count, 3), dtype=np.float32)

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


def joint_action_space(joint_lower, joint_upper, gripper_max: float) -> spaces.Box:
    """Robot mode's joint actions, Box (2, J + 1): rows [left, right], columns the J joint targets
    within the arms' limits (rad or m, scene_info()'s joint_lower .. joint_upper), then the gripper
    opening in [0, gripper_max] m (the fingers close toward it until they squeeze the cloth with
    the grip force)."""
    lower = np.asarray(joint_lower, dtype=np.float64)
    upper = np.asarray(joint_upper, dtype=np.float64)
    if lower.ndim != 1 or lower.shape != upper.shape or lower.size == 0:
        raise ValueError(f"joint limits must be two equally long, non-empty lists, got {lower.shape} and {upper.shape}")
    if not gripper_max > 0:
        raise ValueError(f"gripper_max must be > 0 m, got {gripper_max}")
    low = np.append(lower, 0.0).astype(np.float32)
    high = np.append(upper, gripper_max).astype(np.float32)
    return spaces.Box(low=np.stack([low, low]), high=np.stack([high, high]), dtype=np.float32)


# Vertex positions stay within this many metres of the world origin: the arms reach less than a
# metre, the table is the plane z = 0 and a failing scene is restored to its last finite state.
OBSERVATION_BOUND = 5.0


def observation_space(vertex_count: int) -> spaces.Box:
    """Box (N, 3) float32: the vertex positions, m, world frame, within +-OBSERVATION_BOUND."""
    return spaces.Box(low=-OBSERVATION_BOUND, high=OBSERVATION_BOUND, shape=(vertex_count, 3), dtype=np.float32)

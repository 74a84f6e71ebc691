"""Rotation vectors (LeRobot's ``ee.wx, ee.wy, ee.wz``: axis times angle, rad) to and from the
rotation matrices and unit quaternions (w first) the armctl core takes."""

from __future__ import annotations

import numpy as np


def rotvec_to_quaternion_wxyz(rotvec) -> list[float]:
    """The unit quaternion of a rotation vector."""
    w = np.asarray(rotvec, dtype=np.float64)
    angle = float(np.linalg.norm(w))
    if angle < 1e-12:
        return [1.0, 0.0, 0.0, 0.0]
    axis = w / angle
    s = np.sin(angle / 2.0)
    return [float(np.cos(angle / 2.0)), *(float(x) for x in axis * s)]


def matrix_to_rotvec(r) -> list[float]:
    """The rotation vector of a rotation matrix (angle in 0..pi)."""
    r = np.asarray(r, dtype=np.float64)
    cos = np.clip((np.trace(r) - 1.0) / 2.0, -1.0, 1.0)
    angle = float(np.arccos(cos))
    if angle < 1e-9:
        return [0.0, 0.0, 0.0]
    if np.pi - angle < 1e-6:
        # Near a half turn the antisymmetric part vanishes: the axis is the column of R + I with
        # the largest norm.
        m = r + np.eye(3)
        axis = m[:, int(np.argmax(np.linalg.norm(m, axis=0)))]
        axis = axis / np.linalg.norm(axis)
        return [float(x) for x in axis * angle]
    axis = np.array([r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1]]) / (2.0 * np.sin(angle))
    return [float(x) for x in axis * angle]

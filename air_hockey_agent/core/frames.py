"""Frame conversions (README "Frames and units"): mocap frame -> table frame, table frame <-> robot frame.

Planar poses: (x, y, yaw). The table frame's pose in the mocap frame is (tx, ty, tz, tyaw); the table
is assumed level. A robot frame equals the table frame for ``iiwa_front`` and is rotated by pi about
z for ``iiwa_back`` (x toward the opponent for both).
"""
from __future__ import annotations

import math
from typing import Sequence

from air_hockey_agent.core.puck.model import wrap_angle

ROBOT_YAW = {"iiwa_front": 0.0, "iiwa_back": math.pi}
TABLE_FRAME = "table"  # frame_id of poses and states given in the table frame
IDENTITY_POSE = (0.0, 0.0, 0.0, 0.0)  # the table frame's pose in itself
MIN_QUATERNION_NORM2 = 0.5  # squared norm below which a mocap quaternion is invalid (unit: 1; zero: lost body)


def yaw_from_quaternion(qx: float, qy: float, qz: float, qw: float) -> float:
    """Yaw (rotation about z) of a unit quaternion [rad], in (-pi, pi]."""
    return wrap_angle(math.atan2(2.0 * (qw * qz + qx * qy), 1.0 - 2.0 * (qy * qy + qz * qz)))


def quaternion_from_yaw(yaw: float) -> tuple[float, float, float, float]:
    """Unit quaternion (x, y, z, w) of a rotation by ``yaw`` about z."""
    return 0.0, 0.0, math.sin(yaw / 2.0), math.cos(yaw / 2.0)


def mocap_to_table(x: float, y: float, yaw: float, table_pose: Sequence[float]) -> tuple[float, float, float]:
    """Planar pose in the mocap frame -> table frame; ``table_pose`` = (tx, ty, tz, tyaw) in mocap."""
    tx, ty, _, tyaw = table_pose
    c, s = math.cos(tyaw), math.sin(tyaw)
    dx, dy = x - tx, y - ty
    return c * dx + s * dy, -s * dx + c * dy, wrap_angle(yaw - tyaw)


def table_to_mocap(x: float, y: float, yaw: float, table_pose: Sequence[float]) -> tuple[float, float, float]:
    """Inverse of :func:`mocap_to_table`."""
    tx, ty, _, tyaw = table_pose
    c, s = math.cos(tyaw), math.sin(tyaw)
    return tx + c * x - s * y, ty + s * x + c * y, wrap_angle(yaw + tyaw)


def pose_to_measurement(position: Sequence[float], quaternion: Sequence[float],
                        table_pose: Sequence[float], frame_id: str = "") -> tuple[float, float, float] | None:
    """Mocap pose (position x, y, z [m]; quaternion x, y, z, w) -> table-frame measurement (x, y, theta).
    A pose whose ``frame_id`` is the table frame is one already: ``table_pose`` does not apply.

    Returns None for a pose that cannot be a measurement (non-finite values or a quaternion far from
    unit length, as OptiTrack sends for a lost rigid body); the filter treats it as a lost frame.
    """
    values = (*position, *quaternion)
    if not all(math.isfinite(v) for v in values) or sum(q * q for q in quaternion) < MIN_QUATERNION_NORM2:
        return None
    qx, qy, qz, qw = quaternion
    pose = IDENTITY_POSE if frame_id == TABLE_FRAME else table_pose
    return mocap_to_table(position[0], position[1], yaw_from_quaternion(qx, qy, qz, qw), pose)


def table_to_robot(x: float, y: float, yaw: float, robot: str) -> tuple[float, float, float]:
    """Table frame -> the robot's own frame (x toward the opponent)."""
    return mocap_to_table(x, y, yaw, (0.0, 0.0, 0.0, ROBOT_YAW[robot]))


def robot_to_table(x: float, y: float, yaw: float, robot: str) -> tuple[float, float, float]:
    """The robot's own frame -> table frame."""
    return table_to_mocap(x, y, yaw, (0.0, 0.0, 0.0, ROBOT_YAW[robot]))

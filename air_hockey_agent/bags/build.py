"""rosbags messages from plain values: nested mappings of field names, every field left out at its
default (zero, empty, False), so a writer names only what it sets, as with an rclpy message; and the
fields of the messages more than one tool writes (a header, a mocap pose, a puck state).

``build("geometry_msgs/msg/PoseStamped", {"header": {"stamp": stamp_fields(1.5), "frame_id": "optitrack"}})``
gives the rosbags object :class:`air_hockey_agent.bags.writer.BagWriter` serialises. A field name the
type lacks raises ``KeyError`` naming the type and the field.
"""
from __future__ import annotations

from typing import Any, Mapping

import numpy as np
from rosbags.interfaces import Nodetype

from air_hockey_agent.bags.types import typestore

NUMPY_TYPES = {"bool": np.bool_, "byte": np.uint8, "char": np.uint8, "int8": np.int8, "uint8": np.uint8,
               "int16": np.int16, "uint16": np.uint16, "int32": np.int32, "uint32": np.uint32, "int64": np.int64,
               "uint64": np.uint64, "float32": np.float32, "float64": np.float64}


def stamp_fields(seconds: float) -> dict[str, int]:
    """builtin_interfaces/Time fields of ``seconds`` (>= 0), rounded to the nanosecond."""
    ns = int(round(seconds * 1e9))
    return {"sec": ns // 1_000_000_000, "nanosec": ns % 1_000_000_000}


def header_fields(seconds: float, frame_id: str = "") -> dict:
    """std_msgs/Header fields: stamp ``seconds`` [s], ``frame_id``."""
    return {"stamp": stamp_fields(seconds), "frame_id": frame_id}


def pose_fields(seconds: float, frame_id: str, x: float, y: float, z: float, yaw: float) -> dict:
    """geometry_msgs/PoseStamped fields of a planar pose: position [m], ``yaw`` [rad] about z."""
    from air_hockey_agent.core.frames import quaternion_from_yaw
    qx, qy, qz, qw = quaternion_from_yaw(yaw)
    return {"header": header_fields(seconds, frame_id), "pose": {
        "position": {"x": float(x), "y": float(y), "z": float(z)}, "orientation": {"x": qx, "y": qy, "z": qz, "w": qw}}}


def puck_state_fields(seconds: float, state, covariance=None, flags: int = 0, frame_id: str = "table") -> dict:
    """air_hockey_msgs/PuckState fields of (x, y, vx, vy, theta, omega) at ``seconds`` [s] with its 6x6
    ``covariance`` (None: zeros)."""
    x, y, vx, vy, theta, omega = (float(v) for v in state)
    cov = np.zeros(36) if covariance is None else np.asarray(covariance, float).reshape(36)
    return {"header": header_fields(seconds, frame_id), "x": x, "y": y, "vx": vx, "vy": vy, "theta": theta,
            "omega": omega, "covariance": cov, "flags": flags}


def physics_fields(seconds: float, params, impacts: int = 0, windows: int = 0) -> dict:
    """air_hockey_msgs/PuckPhysics fields of ``params`` (a :class:`~air_hockey_agent.core.puck.model.
    PuckParams`, table frame) in effect from ``seconds`` [s], learned from ``impacts`` and ``windows``."""
    return {"stamp": stamp_fields(seconds), **params.values(), "impacts_learned": int(impacts),
            "windows_learned": int(windows)}


def build(type_name: str, data: Mapping[str, Any] | None = None) -> Any:
    """The rosbags message ``type_name`` (``pkg/msg/Type``) with the fields in ``data``."""
    store = typestore()
    _, fields = store.fielddefs[type_name]
    data = dict(data or {})
    unknown = sorted(set(data) - {name for name, _ in fields})
    if unknown:
        raise KeyError(f"{type_name} has no field {', '.join(unknown)}")
    return store.types[type_name](**{name: _value(desc, data.get(name)) for name, desc in fields})


def _value(desc: tuple, value: Any) -> Any:
    kind, arg = desc
    if kind == Nodetype.NAME:
        return value if value is not None and not isinstance(value, Mapping) else build(arg, value)
    if kind == Nodetype.BASE:
        base = arg[0]
        if base == "string":
            return "" if value is None else str(value)
        if base == "bool":
            return bool(value)
        return (float if base.startswith("float") else int)(value or 0)
    (inner_kind, inner), length = arg  # ARRAY (length fixed) or SEQUENCE (length 0: any)
    items = list(value) if value is not None else []
    if inner_kind == Nodetype.BASE and inner[0] in NUMPY_TYPES:
        array = np.asarray(items, dtype=NUMPY_TYPES[inner[0]]).reshape(-1)
        return np.zeros(length, array.dtype) if kind == Nodetype.ARRAY and not items else array
    return [_value((inner_kind, inner), v) for v in items]

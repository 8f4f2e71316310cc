"""Conversions between ROS messages and the core's plain values, shared by the nodes and tools."""
from __future__ import annotations

import importlib
import math

import numpy as np
from air_hockey_msgs.msg import PuckPhysics, PuckState
from builtin_interfaces.msg import Duration, Time
from geometry_msgs.msg import PoseStamped

from air_hockey_agent.core.frames import pose_to_measurement
from air_hockey_agent.core.puck.model import PuckParams



def to_seconds(stamp: Time) -> float:
    """ROS time -> seconds."""
    return stamp.sec + stamp.nanosec * 1e-9


def to_stamp(seconds: float) -> Time:
    """Seconds -> ROS time (nanoseconds rounded, never 1e9)."""
    sec = math.floor(seconds)
    return Time(sec=int(sec), nanosec=min(int(round((seconds - sec) * 1e9)), 999_999_999))


def to_duration(seconds: float) -> Duration:
    """Seconds (>= 0) -> ROS duration, e.g. a trajectory point's time_from_start."""
    stamp = to_stamp(seconds)
    return Duration(sec=stamp.sec, nanosec=stamp.nanosec)


def pose_measurement(msg: PoseStamped, table_pose) -> tuple[float, float, float] | None:
    """Table-frame measurement (x, y, theta) of a mocap PoseStamped; None for an unusable pose
    (see :func:`air_hockey_agent.core.frames.pose_to_measurement`)."""
    p, q = msg.pose.position, msg.pose.orientation
    return pose_to_measurement((p.x, p.y, p.z), (q.x, q.y, q.z, q.w), table_pose, msg.header.frame_id)


def joint_vector(kinematics, robot: str, msg, logger) -> np.ndarray | None:
    """The arm's joint positions in model order from ``/<robot>/joint_states`` (a JointState); None, with
    a throttled warning naming the topic, when the message lacks a joint of ``kinematics`` (ArmKinematics)."""
    q = kinematics.positions_from_names(msg.name, msg.position)
    if q is None:
        logger.warn(f"/{robot}/joint_states: missing joints of {kinematics.joint_names}", throttle_duration_sec=5.0)
    return q


def state_msg(state: np.ndarray, cov: np.ndarray, seconds: float, flags: int = 0) -> PuckState:
    """PuckState (table frame) of a state (x, y, vx, vy, theta, omega) and its 6x6 covariance at ``seconds``."""
    msg = PuckState(x=float(state[0]), y=float(state[1]), vx=float(state[2]), vy=float(state[3]),
                    theta=float(state[4]), omega=float(state[5]), flags=flags)
    msg.header.stamp = to_stamp(seconds)
    msg.header.frame_id = "table"
    msg.covariance = np.asarray(cov, float).reshape(36)
    return msg


def physics_msg(params: PuckParams, seconds: float, impacts: int = 0, windows: int = 0) -> PuckPhysics:
    """PuckPhysics of a puck model's parameters (table frame), in effect from ``seconds``."""
    return PuckPhysics(stamp=to_stamp(seconds), **params.values(), impacts_learned=int(impacts),
                       windows_learned=int(windows))


def physics_from_msg(msg: PuckPhysics) -> PuckParams:
    """The physical parameters of a PuckPhysics message (table frame); ValueError naming the first invalid
    one."""
    params = PuckParams.from_attributes(msg)
    params.validate()
    return params


def message_class(type_name: str):
    """rclpy message class of ``pkg/msg/Type`` (rosidl_runtime_py is not among the ROS wheels)."""
    package, _, name = type_name.split("/")
    return getattr(importlib.import_module(f"{package}.msg"), name)

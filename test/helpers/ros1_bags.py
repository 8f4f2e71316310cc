"""ROS 1 bags as the thesis's lab recorded them (Noetic types: a header with seq; ROS 1 serialisation), written
with rosbags' own ROS 1 writer, independently of the package's reader."""
from __future__ import annotations

import math

from pathlib import Path

from rosbags.highlevel import AnyReader
from rosbags.rosbag1 import Writer
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

TF = "tf2_msgs/msg/TFMessage"


def _transform(t, seq: int, ns: int, parent: str, child: str, position, orientation):
    stamp = t["builtin_interfaces/msg/Time"](sec=ns // 10**9, nanosec=ns % 10**9)
    return t["geometry_msgs/msg/TransformStamped"](
        header=t["std_msgs/msg/Header"](seq=seq, stamp=stamp, frame_id=parent), child_frame_id=child,
        transform=t["geometry_msgs/msg/Transform"](
            translation=t["geometry_msgs/msg/Vector3"](x=position[0], y=position[1], z=position[2]),
            rotation=t["geometry_msgs/msg/Quaternion"](x=orientation[0], y=orientation[1], z=orientation[2],
                                                        w=orientation[3])))


def poses_to_tf_bag(source: Path, destination: Path, pose_topic: str = "/optitrack/puck", child: str = "Puck",
                    other: str = "Table", moved: tuple | None = None,
                    table_in_source: tuple = (0.0, 0.0, 0.0, 0.0)) -> int:
    """Write the PoseStamped poses of ``pose_topic`` in a rosbag2 ``source`` as ``/tf`` of a ROS 1 bag: each
    message holds a transform of another body (``other``, at a fixed place) and the puck's (``/<child>``,
    leading slash as ROS 1's tf allowed), parent ``/world``. With ``moved`` = ((x, y, z, yaw) of the poses'
    frame in a new world, a table frame's name) the puck's poses are carried into the new world (planar,
    written here apart from the package's frames module) and, instead of the fixed body, the table frame's
    transform (``table_in_source``, (x, y, z, yaw) in the poses' frame, carried the same way) is sent once
    on /tf_static. Returns the number of puck transforms."""
    store = get_typestore(Stores.ROS1_NOETIC)
    store.register(get_types_from_msg("geometry_msgs/TransformStamped[] transforms", TF))  # not in rosbags' store
    t, n = store.types, 0
    with AnyReader([source]) as reader, Writer(destination) as writer:
        connection = writer.add_connection("/tf", TF, typestore=store)
        static = writer.add_connection("/tf_static", TF, typestore=store) if moved else None
        for c, log_ns, raw in reader.messages(connections=[c for c in reader.connections if c.topic == pose_topic]):
            msg = reader.deserialize(raw, c.msgtype)
            s = msg.header.stamp
            ns = s.sec * 10**9 + s.nanosec
            p, q = msg.pose.position, msg.pose.orientation
            position, orientation = (p.x, p.y, p.z), (q.x, q.y, q.z, q.w)
            transforms = [_transform(t, n, ns, "/world", other, (1.0, 2.0, 0.0), (0.0, 0.0, 0.0, 1.0))]
            if moved:
                (x, y, z, yaw), frame = moved
                position, orientation = _carried(position, orientation, x, y, z, yaw)
                if n == 0:
                    tx, ty, tz, tyaw = table_in_source
                    where = _carried((tx, ty, tz), (0.0, 0.0, math.sin(tyaw / 2), math.cos(tyaw / 2)), x, y, z, yaw)
                    table = _transform(t, 0, ns, "/world", frame, *where)
                    writer.write(static, log_ns, store.serialize_ros1(t[TF](transforms=[table]), TF))
                transforms = []
            transforms.append(_transform(t, n, ns, "/world", "/" + child, position, orientation))
            writer.write(connection, log_ns, store.serialize_ros1(t[TF](transforms=transforms), TF))
            n += 1
    return n


def _carried(position, orientation, x, y, z, yaw):
    """A pose given in a frame at (x, y, z, yaw) of the world, in the world: rotate by yaw, then shift."""
    c, s = math.cos(yaw), math.sin(yaw)
    px, py, pz = position
    qx, qy, qz, qw = orientation
    hz, hw = math.sin(yaw / 2), math.cos(yaw / 2)  # q_yaw * q (Hamilton product)
    turned = (hw * qx - hz * qy, hw * qy + hz * qx, hw * qz + hz * qw, hw * qw - hz * qz)
    return (x + c * px - s * py, y + s * px + c * py, z + pz), turned

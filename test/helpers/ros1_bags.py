"""ROS 1 bags as the thesis's lab recorded them (Noetic types: a header with seq; ROS 1 serialisation), written
with rosbags' own ROS 1 writer, independently of the package's reader."""
from __future__ import annotations

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
                    other: str = "Table") -> int:
    """Write the PoseStamped poses of ``pose_topic`` in a rosbag2 ``source`` as ``/tf`` of a ROS 1 bag: each
    message holds a transform of another body (``other``, at a fixed place) and the puck's (``/<child>``,
    leading slash as ROS 1's tf allowed), parent ``/world``. Returns the number of puck transforms."""
    store = get_typestore(Stores.ROS1_NOETIC)
    store.register(get_types_from_msg("geometry_msgs/TransformStamped[] transforms", TF))  # not in rosbags' store
    t, n = store.types, 0
    with AnyReader([source]) as reader, Writer(destination) as writer:
        connection = writer.add_connection("/tf", TF, typestore=store)
        for c, log_ns, raw in reader.messages(connections=[c for c in reader.connections if c.topic == pose_topic]):
            msg = reader.deserialize(raw, c.msgtype)
            s = msg.header.stamp
            ns = s.sec * 10**9 + s.nanosec
            p, q = msg.pose.position, msg.pose.orientation
            transforms = [_transform(t, n, ns, "/world", other, (1.0, 2.0, 0.0), (0.0, 0.0, 0.0, 1.0)),
                          _transform(t, n, ns, "/world", "/" + child, (p.x, p.y, p.z), (q.x, q.y, q.z, q.w))]
            writer.write(connection, log_ns, store.serialize_ros1(t[TF](transforms=transforms), TF))
            n += 1
    return n

"""Bag reading and writing with rosbags: round trips in both rosbag2 storages, ROS 1 bags read, and one-line
errors for bad bags."""
import sqlite3

import pytest
from rosbags.rosbag1 import Writer as Ros1Writer
from rosbags.typesys import Stores, get_typestore

from air_hockey_agent.bags.reader import BagError, iter_raw, read_frame_transform, read_poses
from air_hockey_agent.bags.trajectories import find_bags, table_pose_from_tf
from helpers.ros1_bags import poses_to_tf_bag
from air_hockey_agent.bags.types import typestore
from air_hockey_agent.bags.writer import BagExistsError, write_bag

POSE = "geometry_msgs/msg/PoseStamped"


def pose(t_ns, x, y=0.0, qw=1.0, header=True):
    types = typestore().types
    stamp = types["builtin_interfaces/msg/Time"](sec=t_ns // 10**9, nanosec=t_ns % 10**9) if header else \
        types["builtin_interfaces/msg/Time"](sec=0, nanosec=0)
    return types[POSE](header=types["std_msgs/msg/Header"](stamp=stamp, frame_id="optitrack"),
                       pose=types["geometry_msgs/msg/Pose"](
                           position=types["geometry_msgs/msg/Point"](x=x, y=y, z=0.0),
                           orientation=types["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=qw)))


def write_poses(path, n=5, storage="mcap", topic="/optitrack/puck", header=True):
    msgs = [(topic, 10**9 + k * 8_333_333, pose(10**9 + k * 8_333_333, 0.1 * k, header=header)) for k in range(n)]
    write_bag(path, {topic: POSE}, msgs, storage)
    return path


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_pose_round_trip(tmp_path, storage):
    bag = write_poses(tmp_path / "bag", storage=storage)
    records = read_poses(bag, "/optitrack/puck")
    assert [round(r.position[0], 9) for r in records] == [0.0, 0.1, 0.2, 0.3, 0.4]
    assert records[1].stamp == pytest.approx(1.008333333)
    assert records[0].orientation == (0.0, 0.0, 0.0, 1.0)
    assert sorted(p.name for p in bag.iterdir())[0] in ("bag.db3", "bag.mcap")  # no staging names inside


def test_a_data_file_path_is_accepted_for_its_bag(tmp_path):
    bag = write_poses(tmp_path / "bag")
    assert len(read_poses(bag / "bag.mcap", "/optitrack/puck")) == 5


def test_log_times_stand_in_when_no_message_has_a_header_stamp(tmp_path):
    records = read_poses(write_poses(tmp_path / "bag", header=False), "/optitrack/puck")
    assert records[2].stamp == pytest.approx(1.016666666)


def test_our_message_types_are_registered():
    assert "air_hockey_msgs/msg/PuckState" in typestore().types


def test_writer_never_overwrites_and_leaves_nothing_behind(tmp_path):
    bag = write_poses(tmp_path / "bag")
    before = sorted(p.name for p in bag.iterdir())
    with pytest.raises(BagExistsError):
        write_poses(bag)
    assert sorted(p.name for p in bag.iterdir()) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bag"]


def test_interrupted_write_leaves_no_bag(tmp_path):
    def failing():
        yield "/optitrack/puck", 10**9, pose(10**9, 0.0)
        raise RuntimeError("recorder stopped")
    with pytest.raises(RuntimeError):
        write_bag(tmp_path / "bag", {"/optitrack/puck": POSE}, failing())
    assert list(tmp_path.iterdir()) == []


def error_of(path, topic="/optitrack/puck"):
    with pytest.raises(BagError) as info:
        read_poses(path, topic)
    message = str(info.value)
    assert "\n" not in message and str(path) in message
    return message


def test_missing_bag(tmp_path):
    assert "does not exist" in error_of(tmp_path / "nope")


def test_directory_that_is_not_a_bag(tmp_path):
    assert "not a bag (neither a rosbag2 bag" in error_of(tmp_path)


def test_missing_topic_names_the_topics_present(tmp_path):
    bag = write_poses(tmp_path / "bag", topic="/other")
    assert "no topic /optitrack/puck (topics: /other)" in error_of(bag)


def test_wrong_message_type(tmp_path):
    types = typestore().types
    msg = types["std_msgs/msg/String"](data="hi")
    write_bag(tmp_path / "bag", {"/optitrack/puck": "std_msgs/msg/String"}, [("/optitrack/puck", 1, msg)])
    assert "has type std_msgs/msg/String, expected geometry_msgs/msg/PoseStamped" in error_of(tmp_path / "bag")


def test_empty_topic(tmp_path):
    write_bag(tmp_path / "bag", {"/optitrack/puck": POSE}, [])
    assert "no messages on /optitrack/puck" in error_of(tmp_path / "bag")


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_truncated_data_file(tmp_path, storage):
    bag = write_poses(tmp_path / "bag", n=200, storage=storage)
    data = next(p for p in bag.iterdir() if p.suffix in (".mcap", ".db3"))
    data.write_bytes(data.read_bytes()[: data.stat().st_size // 3])
    assert "cannot read" in error_of(bag)


def test_garbage_database(tmp_path):
    bag = write_poses(tmp_path / "bag", storage="sqlite3")
    (bag / "bag.db3").write_bytes(b"this is not sqlite" * 100)
    assert "cannot read" in error_of(bag)
    with pytest.raises(sqlite3.DatabaseError):  # the reader did not repair or replace the input
        sqlite3.connect(bag / "bag.db3").execute("select * from messages").fetchall()


def write_ros1_poses(path, n=5, topic="/optitrack/puck"):
    """A ROS 1 bag as the lab's recorder wrote it: Noetic types (a header with seq), ROS 1 serialisation."""
    store = get_typestore(Stores.ROS1_NOETIC)
    t = store.types
    with Ros1Writer(path) as writer:
        connection = writer.add_connection(topic, POSE, typestore=store)
        for k in range(n):
            ns = 10**9 + k * 8_333_333
            stamp = t["builtin_interfaces/msg/Time"](sec=ns // 10**9, nanosec=ns % 10**9)
            msg = t[POSE](header=t["std_msgs/msg/Header"](seq=k, stamp=stamp, frame_id="optitrack"),
                          pose=t["geometry_msgs/msg/Pose"](position=t["geometry_msgs/msg/Point"](x=0.1 * k, y=0.0, z=0.0),
                                                            orientation=t["geometry_msgs/msg/Quaternion"](
                                                                x=0.0, y=0.0, z=0.0, w=1.0)))
            writer.write(connection, ns, store.serialize_ros1(msg, POSE))
    return path


def test_a_ros1_bag_reads_like_a_rosbag2_bag_and_replays_as_ros2_cdr(tmp_path):
    bag = write_ros1_poses(tmp_path / "lab.bag")
    records = read_poses(bag, "/optitrack/puck")
    assert [round(r.position[0], 9) for r in records] == [0.0, 0.1, 0.2, 0.3, 0.4]
    assert records[1].stamp == pytest.approx(1.008333333) and records[1].frame_id == "optitrack"
    topic, log_ns, raw = list(iter_raw(bag))[3]
    msg = typestore().deserialize_cdr(raw, POSE)  # the Jazzy type: no seq in the header
    assert (topic, log_ns) == ("/optitrack/puck", 10**9 + 3 * 8_333_333)
    assert msg.pose.position.x == pytest.approx(0.3) and msg.header.stamp.nanosec == 24_999_999
    assert msg.header.frame_id == "optitrack"


def test_bad_ros1_bags_are_one_line_errors(tmp_path):
    bag = write_ros1_poses(tmp_path / "lab.bag", n=300)
    assert "no topic /other (topics: /optitrack/puck)" in error_of(bag, "/other")
    bag.write_bytes(bag.read_bytes()[: bag.stat().st_size // 2])
    assert "cannot read" in error_of(bag)
    (tmp_path / "junk.bag").write_bytes(b"not a bag" * 50)
    assert "cannot read" in error_of(tmp_path / "junk.bag")


def test_directories_are_searched_for_both_kinds_of_bag(tmp_path):
    write_poses(tmp_path / "sessions" / "a")
    (tmp_path / "sessions" / "lab").mkdir()
    write_ros1_poses(tmp_path / "sessions" / "lab" / "b.bag")
    (tmp_path / "sessions" / "notes.txt").write_text("not a bag")
    bags, errors = find_bags([tmp_path / "sessions", tmp_path / "c.bag"])
    assert bags == [tmp_path / "sessions" / "a", tmp_path / "sessions" / "lab" / "b.bag", tmp_path / "c.bag"]
    assert errors == []
    assert find_bags([tmp_path / "none"])[1] == [f"{tmp_path / 'none'}: does not exist"]
    named = tmp_path / "sessions" / "notes.txt"  # named, it is read (and the reader says it is not a bag)
    assert find_bags([named]) == ([named], [])


def test_the_puck_is_read_from_tf_as_the_ros1_lab_published_it(tmp_path):
    """The ROS 1 lab's tracker looked the puck up on /tf (child frame "Puck"): its transforms are the poses,
    in their parent frame, and the other bodies' transforms are left out."""
    source = write_poses(tmp_path / "bag", n=7)
    assert poses_to_tf_bag(source, tmp_path / "tf.bag") == 7
    records = read_poses(tmp_path / "tf.bag", "/tf")
    assert [round(r.position[0], 9) for r in records] == [round(0.1 * k, 9) for k in range(7)]
    assert records[2].stamp == pytest.approx(1.016666666) and records[2].frame_id == "world"
    assert [r.stamp for r in records] == [r.stamp for r in read_poses(source, "/optitrack/puck")]
    assert len(read_poses(tmp_path / "tf.bag", "/tf", frame="Table")) == 7
    with pytest.raises(BagError) as info:
        read_poses(tmp_path / "tf.bag", "/tf", frame="Mallet")
    assert "no transform to frame Mallet on /tf (child frames: Puck, Table; choose one with --frame)" in str(info.value)


def test_a_fixed_frame_is_read_from_tf_and_must_share_the_pucks_parent(tmp_path):
    """The table's pose from the bag's transform to its frame (on /tf when no /tf_static holds it); poses
    in another frame than that transform's parent cannot use it."""
    source = write_poses(tmp_path / "bag", n=3)
    poses_to_tf_bag(source, tmp_path / "tf.bag")
    table = read_frame_transform(tmp_path / "tf.bag", "/Table")
    assert table.position == (1.0, 2.0, 0.0) and table.frame_id == "world"
    assert table_pose_from_tf(tmp_path / "tf.bag", "Table", read_poses(tmp_path / "tf.bag", "/tf")) == (
        1.0, 2.0, 0.0, 0.0)
    with pytest.raises(BagError) as info:
        table_pose_from_tf(tmp_path / "tf.bag", "Table", read_poses(source, "/optitrack/puck"))
    assert "the puck's poses are in frame optitrack, Table's transform in world" in str(info.value)
    with pytest.raises(BagError) as info:
        read_frame_transform(source, "Table")
    assert "no transform to frame Table on /tf_static or /tf (child frames: none)" in str(info.value)

"""The scene the visualizer draws (core/scene.py) and the visualizer node (separate process)."""
import math
import sys
from pathlib import Path

import pytest

from air_hockey_agent.core import scene
from air_hockey_agent.core.table import TableGeometry
from air_hockey_agent.params import load_defaults
from air_hockey_agent.paths import config_file
from air_hockey_agent.tools.launch import ProcessSpec
from air_hockey_agent.visualizer_params import PARAM_FILES, VISUALIZER_PARAMS, scene_style

BIN = Path(sys.executable).parent


@pytest.fixture(scope="module")
def defaults():
    return load_defaults([config_file(f) for f in PARAM_FILES], "/visualizer", VISUALIZER_PARAMS)


@pytest.fixture(scope="module")
def style(defaults):
    return scene_style(defaults)


def test_the_rims_leave_the_goal_openings_free(defaults, style):
    table = TableGeometry.from_params(defaults)
    rims = next(s for s in scene.table_shapes(table, style) if s.kind == "line_list" and s.id == 1)
    segments = list(zip(rims.points[::2], rims.points[1::2]))
    assert len(segments) == 6  # two long rims, each short rim on both sides of its goal
    for (x0, y0, _), (x1, y1, _) in segments:
        if x0 == x1:  # a short rim: it must not cross the opening |y| < goal_width / 2
            assert abs(x0) == pytest.approx(table.length / 2)
            assert min(abs(y0), abs(y1)) == pytest.approx(table.goal_width / 2)
        else:
            assert abs(y0) == pytest.approx(table.width / 2) and abs(x1 - x0) == pytest.approx(table.length)


def test_the_puck_velocity_arrow_covers_arrow_time_of_motion(defaults, style):
    shapes = scene.puck_shapes(0.1, -0.2, math.pi / 2, 2.0, -1.0, defaults["puck.radius"], style)
    disc = next(s for s in shapes if s.kind == "cylinder")
    assert disc.position[:2] == (0.1, -0.2) and disc.scale[0] == pytest.approx(2 * defaults["puck.radius"])
    (x0, y0, _), (x1, y1, _) = next(s for s in shapes if s.kind == "arrow").points
    assert (x1 - x0, y1 - y0) == pytest.approx((2.0 * style.arrow_time, -1.0 * style.arrow_time))
    at_rest = scene.puck_shapes(0.1, -0.2, 0.0, 0.0, 0.0, defaults["puck.radius"], style)
    assert not any(s.kind == "arrow" for s in at_rest)


def test_a_hit_is_drawn_until_its_time_and_a_position_while_it_is_the_latest():
    assert scene.command_visible(True, now=4.9, hit_time=5.0)  # a smash
    assert not scene.command_visible(True, now=5.1, hit_time=5.0)
    assert scene.command_visible(False, now=9.0, hit_time=5.0)  # a ready position


def test_a_hit_has_its_velocity_and_target_a_position_only_its_point(style):
    hit = scene.hit_shapes("iiwa_back", (0.5, 0.1), (-2.0, 0.0), (-0.98, 0.0), True, style)
    assert [s.kind for s in hit] == ["sphere", "arrow", "line_list"] and {s.ns for s in hit} == {"iiwa_back/hit"}
    assert hit[1].points[1][0] == pytest.approx(0.5 - 2.0 * style.arrow_time)
    assert hit[2].points[1][:2] == (-0.98, 0.0)
    ready = scene.hit_shapes("iiwa_back", (0.7, 0.0), (0.0, 0.0), (0.0, 0.0), False, style)
    assert [s.kind for s in ready] == ["sphere"]


def test_prediction_needs_two_points_and_shows_impacts(style):
    assert scene.prediction_shapes([(0.0, 0.0)], [], style) == []
    shapes = scene.prediction_shapes([(0.0, 0.0), (0.1, 0.0), (0.2, 0.1)], [(0.2, 0.1)], style)
    assert [s.kind for s in shapes] == ["line_strip", "sphere_list"] and len(shapes[0].points) == 3


def test_unknown_shape_kinds_and_colours_are_refused(style):
    with pytest.raises(ValueError, match="unknown kind 'blob'"):
        scene.Shape("puck", "blob", (0.0, 0.0, 0.0, 1.0), (1.0, 1.0, 1.0))
    with pytest.raises(KeyError):
        style.color("nobody")


@pytest.mark.integration
def test_the_game_scene_draws_what_it_was_given_in_the_table_frame(defaults, style):
    """The plain-value scene the node and the in-process recorder fill: iiwa_back's command (its own
    frame) drawn at the table frame's (-x, -y) until its hit time; mallets with their tactics; the score."""
    game = scene.GameScene(TableGeometry.from_params(defaults), style)
    assert {s.ns for s in game.shapes(0.0)} == {"table"}
    game.measurement, game.estimate = (0.3, 0.0), (0.3, 0.0, 0.0, 1.0, 0.0)
    game.prediction = ([(0.3, 0.0), (0.5, 0.0)], [(0.5, 0.0)])
    game.mallets["iiwa_front"], game.tactics["iiwa_front"] = (-0.8, 0.1), "ready"
    game.commands["iiwa_back"] = scene.SceneCommand((-0.6, 0.2), (2.0, 0.0), (0.98, 0.0), hit_time=5.0)
    game.status = scene.status_text("running", 1, 0, "")
    shapes = game.shapes(4.0)
    sphere = next(s for s in shapes if s.ns == "iiwa_back/hit" and s.kind == "sphere")
    assert sphere.position[:2] == pytest.approx((0.6, -0.2))
    label = next(s for s in shapes if s.ns == "iiwa_front/mallet" and s.kind == "text")
    assert label.text == "ready" and label.position[:2] == (-0.8, 0.1)
    assert {"measurement", "puck", "prediction", "score"} <= {s.ns for s in shapes}
    assert not [s for s in game.shapes(5.1) if s.ns == "iiwa_back/hit"]  # the hit was made or missed


def test_the_node_draws_commands_in_the_table_frame_and_survives_bad_messages(launcher, rclpy_node):
    """iiwa_back's hit command comes in its own frame (x toward iiwa_front): drawn at the table frame's
    (-x, -y). A command with an unknown tactic and joint states without the arm's joints are logged
    and ignored; the node goes on drawing."""
    from air_hockey_msgs.msg import HitCommand
    from geometry_msgs.msg import PoseStamped
    from sensor_msgs.msg import JointState
    from visualization_msgs.msg import MarkerArray

    launcher.start(ProcessSpec("visualizer", [str(BIN / "visualizer"), "--ros-args", "-p", "rate:=20.0"]))
    arrays = []
    rclpy_node.create_subscription(MarkerArray, "/visualization/markers", arrays.append, 10)
    commands = rclpy_node.create_publisher(HitCommand, "/iiwa_back/hit_command", 10)
    poses = rclpy_node.create_publisher(PoseStamped, "/optitrack/puck", 10)
    joints = rclpy_node.create_publisher(JointState, "/iiwa_front/joint_states", 10)
    from helpers.ros_wait import spin_until
    assert spin_until(rclpy_node, lambda: arrays, 60.0)

    def drawn(ns):
        return [m for m in arrays[-1].markers if m.ns == ns]

    future = rclpy_node.get_clock().now().nanoseconds * 1e-9 + 60.0
    cmd = HitCommand(tactic=HitCommand.TACTIC_SMASH)
    cmd.hit_point.x, cmd.hit_point.y = -0.6, 0.2
    cmd.hit_velocity.x = 2.0
    cmd.hit_time.sec = int(future)
    pose = PoseStamped()
    pose.header.frame_id = "table"
    pose.pose.position.x, pose.pose.orientation.w = 0.3, 1.0

    def command_drawn():
        commands.publish(cmd)
        poses.publish(pose)
        return drawn("iiwa_back/hit") and drawn("measurement")
    assert spin_until(rclpy_node, command_drawn, 30.0)
    sphere = next(m for m in drawn("iiwa_back/hit") if m.type == m.SPHERE)
    assert (sphere.pose.position.x, sphere.pose.position.y) == pytest.approx((0.6, -0.2))
    arrow = next(m for m in drawn("iiwa_back/hit") if m.type == m.ARROW)
    assert arrow.points[1].x < arrow.points[0].x  # toward iiwa_front's goal
    assert drawn("measurement")[0].pose.position.x == pytest.approx(0.3)
    assert arrays[-1].markers[0].action == arrays[-1].markers[0].DELETEALL

    commands.publish(HitCommand(tactic=99))
    joints.publish(JointState(name=["iiwa_joint_1"], position=[0.0]))
    seen = len(arrays)
    assert spin_until(rclpy_node, lambda: len(arrays) > seen + 5, 30.0)
    log = "\n".join(launcher.processes["visualizer"].lines)
    assert "/iiwa_back/hit_command: message ignored (ValueError: unknown tactic 99)" in log
    assert "/iiwa_front/joint_states: missing joints" in log
    assert launcher.processes["visualizer"].returncode is None and "Traceback" not in log


def test_the_game_scene_draws_what_it_knows_in_the_table_frame(defaults, style):
    """GameScene, filled by the node or the in-process recorder: the table always; the measurement, the
    estimate with its arrow, the prediction, each mallet, a hit until its time (iiwa_back's own frame turned
    by pi into the table frame) and the score line once known."""
    table = TableGeometry.from_params(defaults)
    empty = scene.GameScene(table, style)
    assert {s.ns for s in empty.shapes(0.0)} == {s.ns for s in scene.table_shapes(table, style)}
    full = scene.GameScene(table, style, measurement=(0.31, 0.1), estimate=(0.3, 0.1, 0.0, -1.0, 0.5),
                           prediction=([(0.3, 0.1), (0.1, 0.2)], [(0.1, 0.2)]),
                           mallets={"iiwa_front": (-0.8, 0.0), "iiwa_back": (0.8, 0.1)},
                           tactics={"iiwa_back": "cut"},
                           commands={"iiwa_back": scene.SceneCommand((-0.6, 0.2), (2.0, 0.0), (1.0, 0.0), 5.0)},
                           status=scene.status_text("running", 1, 2, "goal for iiwa_back"))
    drawn = full.shapes(4.0)
    measurement = next(s for s in drawn if s.ns == "measurement")
    assert measurement.kind == "sphere" and measurement.position[:2] == (0.31, 0.1)
    assert any(s.kind == "arrow" and not s.ns.endswith("/hit") for s in drawn)  # the estimate's velocity
    assert any(s.ns.startswith("iiwa_back") and s.ns.endswith("/hit") for s in drawn)
    hit = next(s for s in drawn if s.ns == "iiwa_back/hit" and s.kind == "arrow")
    assert hit.points[0][:2] == pytest.approx((0.6, -0.2)) and hit.points[1][0] < hit.points[0][0]
    score = next(s for s in drawn if s.ns == "score")
    assert score.text == "running   iiwa_front 1 : 2 iiwa_back\ngoal for iiwa_back"
    assert not any(s.ns == "iiwa_back/hit" for s in full.shapes(5.1))  # past its hit time
    assert len(full.shapes(5.1)) < len(drawn)

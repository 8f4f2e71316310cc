"""What the ``visualizer`` node draws for RViz and Foxglove, ROS-free: shapes in the table frame.

A :class:`Shape` is one marker (``visualization_msgs/Marker``) without ROS types: its namespace says what
it shows (``table``, ``puck``, ``prediction``, ``<robot>/mallet``, ``<robot>/hit``, ...), its kind how it
is drawn. Positions are table-frame metres (README "Frames and units"), z up from the playing surface;
sizes in metres; colours RGBA in [0, 1]. The node turns each scene into one MarkerArray that first
deletes the previous one, so a shape that is no longer listed (a hit that was made) disappears.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Mapping, Sequence

from air_hockey_agent.core.frames import ROBOT_YAW, quaternion_from_yaw, robot_to_table
from air_hockey_agent.core.table import TableGeometry

Point2 = tuple[float, float]
Point3 = tuple[float, float, float]
Color = tuple[float, float, float, float]
# each kind of shape and its visualization_msgs/Marker type constant
MARKER_TYPES = {"cube": 1, "cylinder": 3, "sphere": 2, "arrow": 0, "line_strip": 4, "line_list": 5, "sphere_list": 7,
                "text": 9}
KINDS = tuple(MARKER_TYPES)


@dataclass(frozen=True)
class Shape:
    """One marker: ``position`` and ``yaw`` place it (ignored by lines, which use ``points``)."""

    ns: str
    kind: str
    color: Color
    scale: Point3
    position: Point3 = (0.0, 0.0, 0.0)
    yaw: float = 0.0
    points: tuple[Point3, ...] = ()
    text: str = ""
    id: int = 0

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise ValueError(f"shape {self.ns}: unknown kind {self.kind!r} (one of {', '.join(KINDS)})")


@dataclass(frozen=True)
class SceneStyle:
    """Sizes and colours of the scene (``config/visualizer.yaml``)."""

    line_width: float                # [m] rims, paths, arrows' shafts
    text_size: float                 # [m] height of labels
    rim_height: float                # [m] drawn height of the rims above the surface
    puck_height: float               # [m]
    mallet_radius: float             # [m]
    mallet_height: float             # [m] drawn height of a mallet
    arrow_time: float                # [s] a velocity arrow is as long as the distance covered in this time
    colors: Mapping[str, Color] = field(default_factory=dict)  # "table", "rim", "puck", "measurement",
    # "prediction", "impact", "text" and one per robot name

    def color(self, name: str) -> Color:
        return self.colors[name]


def marker_fields(shape: Shape) -> dict:
    """The visualization_msgs/Marker fields of ``shape`` (action ADD), the header left to the caller."""
    qx, qy, qz, qw = quaternion_from_yaw(shape.yaw)
    return {"ns": shape.ns, "id": shape.id, "type": MARKER_TYPES[shape.kind], "text": shape.text,
            "pose": {"position": dict(zip("xyz", shape.position)), "orientation": {"x": qx, "y": qy, "z": qz, "w": qw}},
            "scale": dict(zip("xyz", shape.scale)), "color": dict(zip("rgba", shape.color)),
            "points": [dict(zip("xyz", p)) for p in shape.points]}


def table_shapes(table: TableGeometry, style: SceneStyle) -> list[Shape]:
    """The playing surface, the rims with their goal openings, and the centre line."""
    half_l, half_w, half_g = table.length / 2, table.width / 2, table.goal_width / 2
    z = style.rim_height
    rims = [((-half_l, -half_w), (half_l, -half_w)), ((-half_l, half_w), (half_l, half_w))]
    for x in (-half_l, half_l):  # each short rim on both sides of its goal opening
        rims += [((x, -half_w), (x, -half_g)), ((x, half_g), (x, half_w))]
    rim_points = tuple((px, py, z) for segment in rims for (px, py) in segment)
    return [
        Shape("table", "cube", style.color("table"), (table.length, table.width, style.line_width),
              (0.0, 0.0, -style.line_width / 2)),
        Shape("table", "line_list", style.color("rim"), (style.line_width, 0.0, 0.0), points=rim_points, id=1),
        Shape("table", "line_list", style.color("rim"), (style.line_width / 2, 0.0, 0.0),
              points=((0.0, -half_w, 0.0), (0.0, half_w, 0.0)), id=2),
    ]


def puck_shapes(x: float, y: float, theta: float, vx: float, vy: float, radius: float,
                style: SceneStyle) -> list[Shape]:
    """The estimated puck (a disc turned by ``theta``, a line to its rim showing the angle) and its
    velocity [m/s] as an arrow covering ``style.arrow_time`` of it."""
    h = style.puck_height
    notch = (x + radius * math.cos(theta), y + radius * math.sin(theta), h)
    shapes = [Shape("puck", "cylinder", style.color("puck"), (2 * radius, 2 * radius, h), (x, y, h / 2), theta),
              Shape("puck", "line_list", style.color("text"), (style.line_width / 2, 0.0, 0.0),
                    points=((x, y, h), notch), id=1)]
    if math.hypot(vx, vy) > 0.0:
        t = style.arrow_time
        shapes.append(_arrow("puck", 2, (x, y, h), (x + t * vx, y + t * vy, h), style.color("puck"), style))
    return shapes


def measurement_shape(x: float, y: float, style: SceneStyle) -> Shape:
    """The latest mocap measurement of the puck: a small sphere."""
    d = 2 * style.line_width
    return Shape("measurement", "sphere", style.color("measurement"), (d, d, d), (x, y, style.puck_height))


def prediction_shapes(path: Sequence[tuple[float, float]], impacts: Sequence[tuple[float, float]],
                      style: SceneStyle) -> list[Shape]:
    """The predicted path of the puck centre and its predicted rim impacts."""
    z = style.puck_height / 2
    shapes = []
    if len(path) >= 2:
        shapes.append(Shape("prediction", "line_strip", style.color("prediction"), (style.line_width, 0.0, 0.0),
                            points=tuple((px, py, z) for px, py in path)))
    if impacts:
        d = 3 * style.line_width
        shapes.append(Shape("prediction", "sphere_list", style.color("impact"), (d, d, d),
                            points=tuple((px, py, z) for px, py in impacts), id=1))
    return shapes


def mallet_shapes(robot: str, x: float, y: float, tactic: str, style: SceneStyle) -> list[Shape]:
    """A robot's mallet at its forward-kinematics position and its tactic as a label above it."""
    r, h = style.mallet_radius, style.mallet_height
    return [Shape(f"{robot}/mallet", "cylinder", style.color(robot), (2 * r, 2 * r, h), (x, y, h / 2)),
            Shape(f"{robot}/mallet", "text", style.color("text"), (0.0, 0.0, style.text_size),
                  (x, y, h + style.text_size), text=tactic, id=1)]


def hit_shapes(robot: str, point: Point2, velocity: Point2, target: Point2, hit: bool,
               style: SceneStyle) -> list[Shape]:
    """A command in the table frame ([m], [m/s]): where the mallet must be (a sphere); for a hit also its velocity
    at the hit (an arrow covering ``style.arrow_time`` of it) and the line to the puck's target."""
    r = style.mallet_radius
    shapes = [Shape(f"{robot}/hit", "sphere", style.color(robot), (r, r, r), (point[0], point[1], style.mallet_height))]
    if hit:
        z = style.mallet_height
        tip = (point[0] + style.arrow_time * velocity[0], point[1] + style.arrow_time * velocity[1], z)
        shapes.append(_arrow(f"{robot}/hit", 1, (point[0], point[1], z), tip, style.color(robot), style))
        shapes.append(Shape(f"{robot}/hit", "line_list", style.color(robot), (style.line_width / 2, 0.0, 0.0),
                            points=((point[0], point[1], 0.0), (target[0], target[1], 0.0)), id=2))
    return shapes


def score_shape(table: TableGeometry, text: str, style: SceneStyle) -> Shape:
    """The referee's status and score, above the table's far long rim."""
    return Shape("score", "text", style.color("text"), (0.0, 0.0, style.text_size),
                 (0.0, table.width / 2 + 2 * style.text_size, style.rim_height), text=text)


def _arrow(ns: str, shape_id: int, start: Point3, end: Point3, color: Color, style: SceneStyle) -> Shape:
    w = style.line_width
    return Shape(ns, "arrow", color, (w, 2 * w, 2 * w), points=(start, end), id=shape_id)


def command_visible(hit: bool, now: float, hit_time: float) -> bool:
    """A hit command is drawn until its hit time [s] (then the hit is made or missed); a position
    command (home, ready) as long as it is the robot's latest."""
    return not hit or now <= hit_time


def status_text(status: str, score_front: int, score_back: int, reason: str) -> str:
    """The score line: status, score seen from iiwa_front's side, and the referee's last reason."""
    line = f"{status}   iiwa_front {score_front} : {score_back} iiwa_back"
    return f"{line}\n{reason}" if reason else line


@dataclass(frozen=True)
class SceneCommand:
    """A robot's latest command in its own frame (README "Frames and units"): mallet point [m] and
    velocity [m/s] at ``hit_time`` [s], the puck's target [m]; a zero velocity is a position command."""

    point: Point2
    velocity: Point2
    target: Point2
    hit_time: float

    @property
    def is_hit(self) -> bool:
        return self.velocity[0] != 0.0 or self.velocity[1] != 0.0  # the tactics' Proposal.is_hit


@dataclass
class GameScene:
    """What the visualizer knows of a game, as plain values in the table frame, and the scene it draws:
    the latest measurement (x, y) [m], the estimate (x, y, theta, vx, vy), the prediction's path and
    rim impacts, each robot's mallet (x, y) and tactic, each robot's latest command, the score line.
    The ``visualizer`` node fills it from messages; the in-process game's recorder from the game."""

    table: TableGeometry
    style: SceneStyle
    measurement: Point2 | None = None
    estimate: tuple[float, float, float, float, float] | None = None
    prediction: tuple[Sequence[Point2], Sequence[Point2]] | None = None
    mallets: dict[str, Point2] = field(default_factory=dict)
    tactics: dict[str, str] = field(default_factory=dict)
    commands: dict[str, SceneCommand] = field(default_factory=dict)
    status: str | None = None

    def __post_init__(self) -> None:
        self._table_shapes = table_shapes(self.table, self.style)

    def shapes(self, now: float) -> list[Shape]:
        """Every shape of the scene at ``now`` [s]: table, puck, mallets, visible commands, score."""
        shapes = list(self._table_shapes) + self.puck_shapes()
        for robot in ROBOT_YAW:  # iiwa_front, then iiwa_back
            shapes += self.robot_shapes(robot, now)
        if self.status is not None:
            shapes.append(score_shape(self.table, self.status, self.style))
        return shapes

    def puck_shapes(self) -> list[Shape]:
        shapes, style = [], self.style
        if self.measurement is not None:
            shapes.append(measurement_shape(*self.measurement, style))
        if self.estimate is not None:
            x, y, theta, vx, vy = self.estimate
            shapes += puck_shapes(x, y, theta, vx, vy, self.table.puck_radius, style)
        if self.prediction is not None:
            shapes += prediction_shapes(*self.prediction, style)
        return shapes

    def robot_shapes(self, robot: str, now: float) -> list[Shape]:
        shapes = []
        if robot in self.mallets:
            shapes += mallet_shapes(robot, *self.mallets[robot], self.tactics.get(robot, ""), self.style)
        cmd = self.commands.get(robot)
        if cmd is not None and command_visible(cmd.is_hit, now, cmd.hit_time):
            # the robot frame shares the table frame's origin: velocities turn like points
            point = robot_to_table(*cmd.point, 0.0, robot)[:2]
            velocity = robot_to_table(*cmd.velocity, 0.0, robot)[:2]
            target = robot_to_table(*cmd.target, 0.0, robot)[:2]
            shapes += hit_shapes(robot, point, velocity, target, cmd.is_hit, self.style)
        return shapes

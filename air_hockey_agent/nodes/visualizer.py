"""``visualizer`` node: markers for RViz and Foxglove (presentation only; the agent never reads them).

Inputs: ``/optitrack/puck`` (PoseStamped, the latest measurement), ``/<tracker>/puck/state`` and
``/<tracker>/puck/prediction`` of the robot named by ``tracker``, and for both robots ``joint_states``
(mallet positions by forward kinematics of ``models/iiwa14_striker.urdf``, placed with ``robot_base``),
``tactic`` and ``hit_command`` (the robot's frame, drawn in the table frame), and ``/game_status``.
Output: ``/visualization/markers`` (visualization_msgs/MarkerArray in frame ``table``), ``rate`` times per
simulated second: the table, the puck with its velocity and predicted path and rim impacts, each mallet
with its tactic, each command (a hit until its hit time, with its velocity and target), the score. Each
array starts by deleting the previous one. The shapes are made in ``core/scene.py``.
"""
from __future__ import annotations

from geometry_msgs.msg import Point, PoseStamped
from rclpy.qos import DurabilityPolicy, QoSProfile
from sensor_msgs.msg import JointState
from visualization_msgs.msg import Marker, MarkerArray

from air_hockey_msgs.msg import GameStatus, HitCommand, PuckPrediction, PuckState, TacticState
from air_hockey_agent.core import scene
from air_hockey_agent.core.frames import TABLE_FRAME, quaternion_from_yaw
from air_hockey_agent.core.game.referee import STATUS_NAMES
from air_hockey_agent.core.game.tactics.base import NAMES
from air_hockey_agent.core.motion.kinematics import ArmKinematics
from air_hockey_agent.core.table import TableGeometry
from air_hockey_agent.nodes.messages import joint_vector, pose_measurement, to_seconds, to_stamp
from air_hockey_agent.nodes.runtime import AirHockeyNode, run
from air_hockey_agent.paths import model_path
from air_hockey_agent.sim.params import ROBOTS
from air_hockey_agent.visualizer_params import PARAM_FILES, VISUALIZER_PARAMS, scene_style

def marker(shape: scene.Shape, stamp) -> Marker:
    """visualization_msgs/Marker of a scene shape (table frame)."""
    m = Marker(ns=shape.ns, id=shape.id, type=scene.MARKER_TYPES[shape.kind], action=Marker.ADD, text=shape.text)
    m.header.frame_id, m.header.stamp = TABLE_FRAME, stamp
    m.pose.position.x, m.pose.position.y, m.pose.position.z = shape.position
    qx, qy, qz, qw = quaternion_from_yaw(shape.yaw)
    m.pose.orientation.x, m.pose.orientation.y, m.pose.orientation.z, m.pose.orientation.w = qx, qy, qz, qw
    m.scale.x, m.scale.y, m.scale.z = shape.scale
    m.color.r, m.color.g, m.color.b, m.color.a = shape.color
    m.points = [Point(x=float(x), y=float(y), z=float(z)) for x, y, z in shape.points]
    return m


class VisualizerNode(AirHockeyNode):
    NAME = "visualizer"
    DESCRIPTION = __doc__
    PARAM_FILES = PARAM_FILES
    PARAMS = VISUALIZER_PARAMS

    def __init__(self) -> None:
        super().__init__()
        p = self.params
        self.scene = scene.GameScene(TableGeometry.from_params(p), scene_style(p))
        self.kinematics = ArmKinematics(model_path("iiwa14_striker.urdf"))
        self.pub = self.create_publisher(MarkerArray, "/visualization/markers", 10)
        latched = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
        tracker = p["tracker"]
        self.create_subscription(PoseStamped, "/optitrack/puck", self.guarded("/optitrack/puck", self.on_pose), 10)
        self.create_subscription(PuckState, f"/{tracker}/puck/state",
                                 self.guarded(f"/{tracker}/puck/state", self.on_estimate), 10)
        self.create_subscription(PuckPrediction, f"/{tracker}/puck/prediction",
                                 self.guarded(f"/{tracker}/puck/prediction", self.on_prediction), 10)
        self.create_subscription(GameStatus, "/game_status", self.guarded("/game_status", self.on_status), latched)
        for robot in ROBOTS:
            self.create_subscription(JointState, f"/{robot}/joint_states",
                                     self.guarded(f"/{robot}/joint_states", lambda m, r=robot: self.on_joints(r, m)), 10)
            self.create_subscription(TacticState, f"/{robot}/tactic",
                                     self.guarded(f"/{robot}/tactic", lambda m, r=robot: self.on_tactic(r, m)), latched)
            self.create_subscription(HitCommand, f"/{robot}/hit_command",
                                     self.guarded(f"/{robot}/hit_command", lambda m, r=robot: self.on_command(r, m)), 10)
        self.create_timer(1.0 / p["rate"], self.guarded("/visualization/markers", self.publish_scene))

    def guarded(self, topic: str, callback):
        """A callback that logs a failure (a malformed message) instead of stopping the node; during
        shutdown (the context is gone) it stays silent."""
        def call(*args) -> None:
            try:
                callback(*args)
            except Exception as exc:
                if not self.context.ok():
                    return
                self.get_logger().error(f"{topic}: message ignored ({type(exc).__name__}: {exc})",
                                        throttle_duration_sec=1.0)
        return call

    # --- inputs: messages -> the scene's plain values ---------------------------------------------
    def on_pose(self, msg: PoseStamped) -> None:
        z = pose_measurement(msg, self.params["mocap_table_pose"])
        self.scene.measurement = None if z is None else (z[0], z[1])

    def on_estimate(self, msg: PuckState) -> None:
        self.scene.estimate = (msg.x, msg.y, msg.theta, msg.vx, msg.vy)

    def on_prediction(self, msg: PuckPrediction) -> None:
        path = [(msg.initial.x, msg.initial.y)] + [(s.x, s.y) for s in msg.states]
        self.scene.prediction = (path, [(i.x, i.y) for i in msg.impacts])

    def on_status(self, msg: GameStatus) -> None:
        self.scene.status = scene.status_text(STATUS_NAMES.get(msg.status, "?"), msg.score_front, msg.score_back,
                                              msg.reason)

    def on_joints(self, robot: str, msg: JointState) -> None:
        q = joint_vector(self.kinematics, robot, msg, self.get_logger())
        if q is not None:
            self.scene.mallets[robot] = self.kinematics.tip_in_table(q, self.params[f"robot_base.{robot}"])

    def on_tactic(self, robot: str, msg: TacticState) -> None:
        self.scene.tactics[robot] = msg.name

    def on_command(self, robot: str, msg: HitCommand) -> None:
        if msg.tactic not in NAMES:
            raise ValueError(f"unknown tactic {msg.tactic}")
        self.scene.commands[robot] = scene.SceneCommand((msg.hit_point.x, msg.hit_point.y),
                                                        (msg.hit_velocity.x, msg.hit_velocity.y),
                                                        (msg.target.x, msg.target.y), to_seconds(msg.hit_time))

    # --- output -------------------------------------------------------------------------------
    def publish_scene(self) -> None:
        now = self.get_clock().now().nanoseconds * 1e-9
        stamp = to_stamp(now)
        self.pub.publish(MarkerArray(markers=[Marker(action=Marker.DELETEALL)]
                                     + [marker(s, stamp) for s in self.scene.shapes(now)]))


def main(argv: list[str] | None = None) -> int:
    return run(VisualizerNode, argv)

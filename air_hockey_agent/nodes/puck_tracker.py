"""``puck_tracker`` node: EKF puck state and prediction from the mocap stream (thesis sec. 4.1.1, 4.2).

Subscribes ``/optitrack/puck`` (geometry_msgs/PoseStamped, mocap frame) and, with
``mallet_contact.enabled``, ``/<robot>/joint_states`` of both robots (their mallets, by forward kinematics:
a mallet the estimate meets hits it; in a mocap dropout the estimate coasts on these messages' stamps and
is published once it holds such a contact); publishes ``puck/state``
(PuckState, table frame) at every frame, ``puck/prediction`` (PuckPrediction) and ``puck/physics``
(PuckPhysics, latched: the physics it predicts with, at start and on every change: what it learns online
of the table, or new parameters; the tactics aim their shots with it). Services (thesis
4.1.1): ``set_physical_params``, ``set_noise_covariance``, ``kalman_step``, ``reset``. All filtering and
prediction is :class:`air_hockey_agent.core.estimation.ekf.PuckEKF`; this module only translates.
"""
from __future__ import annotations

import math
import sys

import numpy as np
from air_hockey_msgs.msg import LineCrossing, PuckPhysics, PuckPrediction, PuckState, WallImpact
from air_hockey_msgs.srv import KalmanStep, ResetFilter, SetNoiseCovariance, SetPhysicalParams
from geometry_msgs.msg import PoseStamped
from sensor_msgs.msg import JointState
from rclpy.qos import DurabilityPolicy, QoSProfile

from air_hockey_agent.core.estimation.agent_prediction import predict_for_agents
from air_hockey_agent.core.estimation.ekf import ACQUISITION_FRAMES, FLAG_PREDICTED, PuckEKF, check_covariance
from air_hockey_agent.core.estimation.table_learning import describe_learning
from air_hockey_agent.core.motion.kinematics import TableMallets
from air_hockey_agent.core.puck.prediction import prepare_prediction
from air_hockey_agent.nodes.messages import physics_msg, pose_measurement, state_msg, to_seconds, to_stamp
from air_hockey_agent.nodes.runtime import AirHockeyNode, run
from air_hockey_agent.paths import model_path
from air_hockey_agent.tracker_params import PARAM_FILES, ROBOTS, TRACKER_NODE_PARAMS


class PuckTrackerNode(AirHockeyNode):
    NAME = "puck_tracker"
    DESCRIPTION = __doc__
    PARAM_FILES = PARAM_FILES
    PARAMS = TRACKER_NODE_PARAMS

    def __init__(self) -> None:
        super().__init__()
        self.ekf = PuckEKF.from_params(self.params)
        prepare_prediction()  # the compiled prediction, before the first frame
        self.next_log = 1  # impacts and windows learned from at which the next log line comes
        self.state_pub = self.create_publisher(PuckState, "puck/state", 10)
        self.prediction_pub = self.create_publisher(PuckPrediction, "puck/prediction", 10)
        latched = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
        self.physics_pub = self.create_publisher(PuckPhysics, "puck/physics", latched)
        self.physics_learned = None  # the tracker's learning counts at the last puck/physics (None: none yet)
        self.publish_physics(0.0)
        self.create_subscription(PoseStamped, "/optitrack/puck", self.on_pose, 10)
        if self.ekf.mallets is not None:
            self.mallets = TableMallets(model_path("iiwa14_striker.urdf"),
                                        {r: self.params[f"robot_base.{r}"] for r in ROBOTS})
            for robot in ROBOTS:
                self.create_subscription(JointState, f"/{robot}/joint_states",
                                         lambda msg, r=robot: self.on_joint_state(r, msg), 10)
        self.create_service(SetPhysicalParams, "set_physical_params", self.on_set_physical_params)
        self.create_service(SetNoiseCovariance, "set_noise_covariance", self.on_set_noise)
        self.create_service(KalmanStep, "kalman_step", self.on_kalman_step)
        self.create_service(ResetFilter, "reset", self.on_reset)

    # --- stream -----------------------------------------------------------------------------------
    def on_pose(self, msg: PoseStamped) -> None:
        try:
            z = pose_measurement(msg, self.params["mocap_table_pose"])
            if z is None:
                self.get_logger().warn("/optitrack/puck: pose has a non-finite position or invalid quaternion; "
                                       "treated as a lost frame", throttle_duration_sec=1.0)
            t = to_seconds(msg.header.stamp)
            in_hand = self.ekf.in_hand
            flags = self.ekf.process(t, z)
            if self.ekf.in_hand and not in_hand:
                self.get_logger().info("a hand or mallet moves the puck: followed with a hand's noise (hand.*)",
                                       throttle_duration_sec=5.0)
            elif in_hand and not self.ekf.in_hand:
                self.get_logger().info("the puck moves freely again", throttle_duration_sec=5.0)
            self.log_learning()
            if self.ekf.learned != self.physics_learned:
                self.publish_physics(t)
            if self.ekf.initialised:
                self.state_pub.publish(state_msg(self.ekf.x, self.ekf.P, self.ekf.stamp, flags))
                self.publish_prediction(flags)
        except Exception as exc:  # a malformed message must never stop the tracker
            if not self.context.ok():
                return  # shut down while publishing: not the frame's fault
            self.get_logger().error(f"/optitrack/puck: frame dropped ({type(exc).__name__}: {exc})",
                                    throttle_duration_sec=1.0)

    def on_joint_state(self, robot: str, msg: JointState) -> None:
        """A robot's joints: its mallet for the filter (table frame, at the message's stamp; its velocity from
        the joint velocities when the message has them); in a dropout the estimate coasts to that stamp,
        published once it met a mallet (:meth:`PuckEKF.coast`)."""
        try:
            motion = self.mallets.motion(robot, msg.name, msg.position, msg.velocity)
            if motion is None:
                self.get_logger().warn(f"/{robot}/joint_states: missing joints of "
                                       f"{self.mallets.kinematics[robot].joint_names}", throttle_duration_sec=5.0)
                return
            t = to_seconds(msg.header.stamp)
            self.ekf.observe_mallet(robot, t, *motion)
            if self.ekf.coast(t):
                self.state_pub.publish(state_msg(self.ekf.x, self.ekf.P, self.ekf.stamp, FLAG_PREDICTED))
                self.publish_prediction(FLAG_PREDICTED)
        except Exception as exc:  # a malformed message must never stop the tracker
            if not self.context.ok():
                return
            self.get_logger().error(f"/{robot}/joint_states: message ignored ({type(exc).__name__}: {exc})",
                                    throttle_duration_sec=1.0)

    def log_learning(self) -> None:
        """Log what was learned online of the table when its count of impacts and windows reaches 1, 10,
        100, ... (a few lines a session)."""
        learning = self.ekf.learning
        if learning is None or learning.events < self.next_log:
            return
        self.next_log *= 10
        self.get_logger().info(f"learned online: {describe_learning(self.ekf.learning_report())}")

    def publish_physics(self, seconds: float) -> None:
        """``puck/physics``: the model's parameters now (learned or configured), from ``seconds``."""
        self.physics_learned = self.ekf.learned
        self.physics_pub.publish(physics_msg(self.ekf.model.params, seconds, *self.physics_learned))

    def publish_prediction(self, flags: int = 0) -> None:
        """``puck/prediction`` from the estimate now; ``flags`` (PuckState.FLAG_*) are its frame's, carried by
        ``initial`` (the tactics learn the mallet's law from the fused frames)."""
        p = self.params
        out = predict_for_agents(self.ekf, p["prediction_horizon"], p["prediction_sample_period"],
                                 p["defend_line_offset"])
        pred, t0 = out.prediction, out.stamp
        msg = PuckPrediction(sample_period=out.sample_period)
        msg.header.stamp, msg.header.frame_id = to_stamp(t0), "table"
        msg.initial = state_msg(self.ekf.x, self.ekf.P, t0, flags)
        msg.states = [state_msg(s, c, t0 + t, PuckState.FLAG_PREDICTED) for t, s, c in pred.samples]
        msg.impacts = [WallImpact(time_from_start=t, wall=w, x=x, y=y, sliding=sl) for t, w, x, y, sl in pred.impacts]
        for robot, line in out.defend_lines.items():
            c = pred.crossings.get(line)
            msg.defend_lines.append(LineCrossing(robot=robot, line_x=line, crosses=c is not None,
                                                 **({} if c is None else dict(time_from_start=c.time, y=c.y,
                                                                              vx=c.vx, vy=c.vy))))
        goals = [pred.crossings[g] for g in out.goal_lines if g in pred.crossings]
        if goals:
            msg.enters_goal, msg.goal_time_from_start = True, min(g.time for g in goals)
        self.prediction_pub.publish(msg)

    # --- services (thesis 4.1.1) -------------------------------------------------------------------
    def on_set_physical_params(self, request, response):
        # the service carries the thesis's four; the restitution slope and table acceleration stay as set
        # (the configured ones: what was learned online restarts from the new values)
        configured = self.ekf.model.params if self.ekf.learning is None else self.ekf.learning.base
        params = configured.with_values(
            friction_surface=request.friction_surface, damping=request.damping, restitution=request.restitution,
            friction_rim=request.friction_rim)
        try:
            self.ekf.set_model_params(params)
        except ValueError as exc:
            response.success, response.message = False, f"refused, filter unchanged: {exc}"
            return response
        self.publish_physics(self.ekf.stamp if self.ekf.initialised else 0.0)
        response.success, response.message = True, f"physical parameters set: {params}"
        return response

    def on_set_noise(self, request, response):
        try:
            q = check_covariance(np.reshape(request.process_covariance, (6, 6)), 6, "process_covariance") \
                if len(request.process_covariance) else self.ekf.settings.q
            r = check_covariance(np.reshape(request.measurement_covariance, (3, 3)), 3, "measurement_covariance") \
                if len(request.measurement_covariance) else self.ekf.settings.r
        except ValueError as exc:
            response.success, response.message = False, f"refused, filter unchanged: {exc}"
            return response
        # the service's Q is the process noise of every regime (the thesis has one)
        self.ekf.settings.q, self.ekf.settings.q_rest, self.ekf.settings.r = q, q, r
        response.success, response.message = True, "noise covariances set"
        stopped = []
        if len(request.measurement_covariance) and self.ekf.noise_learning is not None:
            self.ekf.noise_learning = None  # an R set by hand is kept: the online learning would replace it
            stopped.append("the marker noise")
        if len(request.process_covariance) and self.ekf.process_noise_learning is not None:
            self.ekf.process_noise_learning = None  # as a Q set by hand
            stopped.append("the process noise")
        if stopped:
            verb = "is" if len(stopped) == 1 else "are"
            response.message += f" ({' and '.join(stopped)} {verb} no longer learned online)"
        return response

    def on_kalman_step(self, request, response):
        z = (request.x, request.y, request.theta) if request.has_measurement else None
        flags = self.ekf.process(to_seconds(request.stamp), z)
        if not self.ekf.initialised:
            response.success, response.message = False, (f"filter not initialised yet (a track starts from "
                                                         f"{ACQUISITION_FRAMES} measurements that fit one velocity)")
            return response
        horizon = request.prediction_horizon if request.prediction_horizon > 0.0 else self.ekf.settings.dt
        pred = self.ekf.predict(horizon)
        response.success, response.message = True, ""
        response.estimate = state_msg(self.ekf.x, self.ekf.P, self.ekf.stamp, flags)
        response.prediction = state_msg(pred.state, pred.covariance, self.ekf.stamp + horizon, PuckState.FLAG_PREDICTED)
        response.measurement_rejected = bool(flags & PuckState.FLAG_OUTLIER_REJECTED)
        return response

    def on_reset(self, request, response):
        if request.has_initial_state:
            s = request.initial_state
            state = [s.x, s.y, s.vx, s.vy, s.theta, s.omega]
            if not all(math.isfinite(v) for v in state):
                response.success, response.message = False, "refused: initial_state has non-finite values"
                return response
            stamp = to_seconds(s.header.stamp)
            self.ekf.reset(state, stamp if stamp > 0.0 else None)  # zero stamp: holds at the next frame
            response.message = "filter reset to the given state"
        else:
            self.ekf.reset()
            response.message = "filter reset; waiting for measurements"
        response.success = True
        return response


def main(argv: list[str] | None = None) -> int:
    return run(PuckTrackerNode, argv)


if __name__ == "__main__":
    sys.exit(main())

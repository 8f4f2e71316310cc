"""``trajectory_generator`` node (one per robot namespace): HitCommand -> JointTrajectory.

Subscribes ``hit_command`` (air_hockey_msgs/HitCommand, the robot's own table frame: x toward the
opponent) and ``joint_states``; publishes ``joint_trajectory`` (trajectory_msgs/JointTrajectory with a
start stamp, the seven arm joints with positions and velocities) and ``trajectory_status``
(air_hockey_msgs/TrajectoryStatus: accepted, or refused and why, with the planned hit time and speed).
A hit velocity of zero asks to reach the point and stop there by the hit time. Every motion starts
``planning_delay`` after now: from the running motion's planned state then, or from rest, so its first
point is still ahead when the controller gets it and the arm never jumps. A refused command moves
nothing. When the measured joints leave the running plan by more than ``max_tracking_error`` (the arm
was reset), the next motion starts from the measured state. Publishes its
clock on ``~/sim_sync`` with every joint state (``table_sim`` waits for it when it runs as fast as
possible). The planning lives in :mod:`air_hockey_agent.core.motion.planner`; run with
``use_sim_time`` under the simulation.
"""
from __future__ import annotations

import math
import time

import numpy as np
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from trajectory_msgs.msg import JointTrajectory as JointTrajectoryMsg
from trajectory_msgs.msg import JointTrajectoryPoint

from air_hockey_msgs.msg import HitCommand, TrajectoryStatus
from air_hockey_agent.core.motion.arm_commander import ArmCommander
from air_hockey_agent.core.motion.kinematics import in_order
from air_hockey_agent.core.motion.planner import INVALID, Command, Plan, refused
from air_hockey_agent.motion_params import MOTION_PARAMS, PARAM_FILES, build_planner
from air_hockey_agent.nodes.messages import to_duration, to_seconds, to_stamp
from air_hockey_agent.nodes.runtime import AirHockeyNode, NodeStartupError, run

class TrajectoryGeneratorNode(AirHockeyNode):
    NAME = "trajectory_generator"
    DESCRIPTION = __doc__
    PARAM_FILES = PARAM_FILES
    PARAMS = MOTION_PARAMS

    def __init__(self) -> None:
        super().__init__()
        try:
            planner = build_planner(self.params, self.params["robot"])
        except ValueError as exc:
            raise NodeStartupError(f"parameter 'robot': {exc}") from exc
        self.arm = ArmCommander(planner, self.params["planning_delay"], self.params["max_tracking_error"])
        self.trajectory_pub = self.create_publisher(JointTrajectoryMsg, "joint_trajectory", 10)
        self.status_pub = self.create_publisher(TrajectoryStatus, "trajectory_status", 10)
        self.sync_pub = self.create_publisher(Clock, "~/sim_sync", 10)
        self.create_subscription(JointState, "joint_states", self.on_joint_state, 10)
        self.create_subscription(HitCommand, "hit_command", self.on_command, 10)

    def now_seconds(self) -> float:
        return self.get_clock().now().nanoseconds * 1e-9

    def on_joint_state(self, msg: JointState) -> None:
        try:
            joints = self.arm.planner.kin.joint_names
            q = in_order(msg.name, msg.position, joints)
            dq = in_order(msg.name, msg.velocity or [0.0] * len(msg.name), joints)
            if q is None or dq is None:
                self.get_logger().error(f"joint_states: message ignored (needs positions and velocities of "
                                        f"{list(joints)})", throttle_duration_sec=5.0)
            elif np.all(np.isfinite(q)) and np.all(np.isfinite(dq)):
                error = self.arm.measure(to_seconds(msg.header.stamp), q, dq)
                if error is not None:
                    self.get_logger().warn(f"joint_states: the arm is {error:.2f} rad from the running plan "
                                           "(reset?); the next motion starts from the measured state")
        except (TypeError, ValueError) as exc:
            self.get_logger().error(f"joint_states: message ignored ({type(exc).__name__}: {exc})",
                                    throttle_duration_sec=5.0)
        self.sync_pub.publish(Clock(clock=to_stamp(self.now_seconds())))

    def on_command(self, msg: HitCommand) -> None:
        wall = time.perf_counter()
        now = self.now_seconds()
        try:
            command = Command(np.array([msg.hit_point.x, msg.hit_point.y], float),
                              np.array([msg.hit_velocity.x, msg.hit_velocity.y], float), to_seconds(msg.hit_time))
            plan = self.arm.plan(command, now)
        except Exception as exc:  # a malformed command must never stop the node
            plan = refused(INVALID, f"{type(exc).__name__}: {exc}")
        elapsed = time.perf_counter() - wall
        if plan.ok:
            self.publish_trajectory(plan, now)
            self.get_logger().info(f"hit_command (tactic {msg.tactic}): {plan.message}, {elapsed * 1000:.1f} ms")
        else:
            self.get_logger().warn(f"hit_command (tactic {msg.tactic}) refused: {plan.message}")
        self.publish_status(msg, plan, now, elapsed)

    def publish_trajectory(self, plan: Plan, now: float) -> None:
        times, q, dq = self.arm.accept(plan, now)
        msg = JointTrajectoryMsg(joint_names=list(self.arm.planner.kin.joint_names))
        msg.header.stamp = to_stamp(now)
        msg.points = [JointTrajectoryPoint(positions=qi.tolist(), velocities=dqi.tolist(),
                                           time_from_start=to_duration(ti)) for ti, qi, dqi in zip(times, q, dq)]
        self.trajectory_pub.publish(msg)

    def publish_status(self, command: HitCommand, plan: Plan, now: float, elapsed: float) -> None:
        status = TrajectoryStatus(command_stamp=command.header.stamp, tactic=command.tactic, outcome=plan.outcome,
                                  reason=plan.message, hit_speed=float(plan.hit_speed),
                                  max_hit_speed=float(plan.max_speed), planning_time=elapsed)
        status.header.stamp = to_stamp(now)
        if math.isfinite(plan.hit_time):
            status.hit_time = to_stamp(plan.hit_time)
        self.status_pub.publish(status)


def main(argv: list[str] | None = None) -> int:
    return run(TrajectoryGeneratorNode, argv)

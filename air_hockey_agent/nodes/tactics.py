"""``tactics`` node (one per robot namespace): the upper layer of the agent (thesis sec. 4.1, 4.6).

Subscribes ``puck/prediction`` (the robot's puck tracker, table frame: the estimate it starts from and
its prediction, published together with ``puck/state`` for every frame, so the state topic is not read),
``puck/physics`` (the tracker's puck physics, latched: the shots are aimed with them when
``physics_from_tracker`` is true), ``joint_states`` (mallet position and velocity: forward kinematics
and its Jacobian), ``/game_status`` (the referee: stopped -> Init, paused -> Home, running -> play) and
``trajectory_status`` (the trajectory generator's answers).
Publishes ``hit_command`` (air_hockey_msgs/HitCommand, the robot's own frame) and ``tactic``
(air_hockey_msgs/TacticState: the current tactic and why, on every change and every ``status_period``)
and ``~/sim_sync`` (rosgraph_msgs/Clock: its clock after every decision, which ``table_sim`` waits for
when it runs as fast as possible).
Service ``force_tactic`` (ForceTactic) forces one tactic until released (the strategy test). The
decisions are :class:`air_hockey_agent.core.game.tactics.selector.TacticsSelector`; this node only
translates. Run with ``use_sim_time`` under the simulation.
"""
from __future__ import annotations

import math
import sys

import numpy as np
from rclpy.qos import DurabilityPolicy, QoSProfile
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState

from air_hockey_msgs.msg import (GameStatus, HitCommand, PuckPhysics, PuckPrediction, PuckState, TacticState,
                                 TrajectoryStatus)
from air_hockey_msgs.srv import ForceTactic
from air_hockey_agent.agent_params import AGENT_PARAMS, PARAM_FILES, build_selector
from air_hockey_agent.core.game.situation import build_situation, own_frame_physics, to_own_frame
from air_hockey_agent.core.game.tactics.base import NAMES
from air_hockey_agent.core.game.tactics.selector import STOPPED
from air_hockey_agent.core.motion.kinematics import in_order
from air_hockey_agent.nodes.messages import physics_from_msg, to_seconds, to_stamp
from air_hockey_agent.nodes.runtime import AirHockeyNode, NodeStartupError, run
from air_hockey_agent.sim.params import ROBOTS


def _state(msg: PuckState) -> list[float]:
    return [msg.x, msg.y, msg.vx, msg.vy, msg.theta, msg.omega]


class TacticsNode(AirHockeyNode):
    NAME = "tactics"
    DESCRIPTION = __doc__
    PARAM_FILES = PARAM_FILES
    PARAMS = AGENT_PARAMS

    def __init__(self) -> None:
        super().__init__()
        robot = self.params["robot"]
        if robot not in ROBOTS:
            raise NodeStartupError(f"parameter 'robot': must be one of {', '.join(ROBOTS)}, got '{robot}'")
        self.robot = robot
        self.selector, self.kin = build_selector(self.params, robot, log=self.get_logger().info)
        self.situation = None
        self.last_estimate = -math.inf
        self.status = STOPPED
        self.mallet: np.ndarray | None = None
        self.mallet_velocity: np.ndarray | None = None
        self._published: tuple | None = None
        latched = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
        self.command_pub = self.create_publisher(HitCommand, "hit_command", 10)
        self.tactic_pub = self.create_publisher(TacticState, "tactic", latched)
        self.sync_pub = self.create_publisher(Clock, "~/sim_sync", 10)
        self.create_subscription(PuckPrediction, "puck/prediction", self.on_prediction, 10)
        self.physics_log_at = 0  # log the tracker's physics when what it learned reaches this (0: the first)
        if self.params["physics_from_tracker"]:
            self.create_subscription(PuckPhysics, "puck/physics", self.on_physics, latched)
        self.create_subscription(JointState, "joint_states", self.on_joint_state, 10)
        self.create_subscription(GameStatus, "/game_status", self.on_game_status, latched)
        self.create_subscription(TrajectoryStatus, "trajectory_status", self.on_trajectory_status, 10)
        self.create_service(ForceTactic, "force_tactic", self.on_force)
        self.create_timer(1.0 / self.params["rate"], self.on_tick)
        self.create_timer(self.params["status_period"], lambda: self.publish_tactic(None, force=True))

    def now_seconds(self) -> float:
        return self.get_clock().now().nanoseconds * 1e-9

    # --- inputs ------------------------------------------------------------------------------------
    def on_prediction(self, msg: PuckPrediction) -> None:
        try:
            t0 = to_seconds(msg.header.stamp)
            samples = np.array([_state(s) for s in msg.states]).reshape(-1, 6)
            times = t0 + msg.sample_period * np.arange(1, len(samples) + 1)
            impacts = [(t0 + i.time_from_start, i.x, i.y) for i in msg.impacts]
            self.situation = build_situation(self.robot, t0, _state(msg.initial), times, samples, impacts,
                                             msg.initial.covariance)
            if msg.initial.flags & PuckState.FLAG_MEASUREMENT_USED:  # a fused frame: for the mallet's law
                self.selector.observe_puck(t0, to_own_frame(np.array(_state(msg.initial)), self.robot))
            self.last_estimate = t0
        except (ValueError, TypeError) as exc:
            self.get_logger().error(f"puck/prediction: message ignored ({exc})", throttle_duration_sec=1.0)

    def on_physics(self, msg: PuckPhysics) -> None:
        """Aim the shots with the tracker's physics (table frame -> own frame); logged at its first message
        and when what it learned reaches 1, 10, 100, ... impacts and windows."""
        try:
            table_frame = physics_from_msg(msg)
        except (ValueError, TypeError) as exc:
            self.get_logger().error(f"puck/physics: message ignored ({exc})", throttle_duration_sec=5.0)
            return
        self.selector.shots.use_physics(own_frame_physics(table_frame, self.robot))
        learned = int(msg.impacts_learned) + int(msg.windows_learned)
        if learned >= self.physics_log_at:
            self.physics_log_at = 10 * learned if learned else 1
            self.get_logger().info(f"shots aimed with the tracker's puck physics ({msg.impacts_learned} rim impacts "
                                   f"and {msg.windows_learned} free-flight windows learned): {table_frame}")

    def on_joint_state(self, msg: JointState) -> None:
        try:
            q = in_order(msg.name, msg.position, self.kin.joint_names)
            if q is not None and np.all(np.isfinite(q)):
                dq = in_order(msg.name, msg.velocity, self.kin.joint_names)  # None when velocities are missing
                if dq is not None and np.all(np.isfinite(dq)):
                    self.mallet, self.mallet_velocity = self.kin.planar_motion(q, dq)
                    self.selector.observe_mallet(to_seconds(msg.header.stamp), self.mallet, self.mallet_velocity)
                else:
                    self.mallet, self.mallet_velocity = self.kin.position(q)[:2], None
        except (TypeError, ValueError) as exc:
            self.get_logger().error(f"joint_states: message ignored ({exc})", throttle_duration_sec=5.0)

    def on_game_status(self, msg: GameStatus) -> None:
        self.status = int(msg.status)

    def on_trajectory_status(self, msg: TrajectoryStatus) -> None:
        self.selector.on_status(to_seconds(msg.command_stamp), int(msg.outcome), float(msg.max_hit_speed),
                                self.now_seconds())

    def on_force(self, request, response):
        try:
            response.message = self.selector.force(int(request.tactic) if request.force else None,
                                                    request.variant if request.force else "")
            response.success = True
        except ValueError as exc:
            response.success, response.message = False, f"refused: {exc}"
        self.get_logger().info(f"force_tactic: {response.message}")
        return response

    # --- decisions ---------------------------------------------------------------------------------
    def on_tick(self) -> None:
        now = self.now_seconds()
        situation = self.situation if now - self.last_estimate <= self.params["stale_estimate"] else None
        decision = self.selector.step(now, self.status, situation, self.mallet, self.mallet_velocity)
        if decision.command is not None:
            self.publish_command(decision.command, now)
        self.publish_tactic(decision)
        self.sync_pub.publish(Clock(clock=to_stamp(now)))

    def publish_command(self, proposal, now: float) -> None:
        msg = HitCommand(tactic=proposal.tactic)
        msg.header.stamp, msg.header.frame_id = to_stamp(now), self.robot
        msg.hit_point.x, msg.hit_point.y = float(proposal.point[0]), float(proposal.point[1])
        msg.hit_velocity.x, msg.hit_velocity.y = float(proposal.velocity[0]), float(proposal.velocity[1])
        msg.hit_time = to_stamp(proposal.time)
        msg.target.x, msg.target.y = (float(v) for v in proposal.target)
        self.command_pub.publish(msg)
        self.get_logger().debug(f"{NAMES[proposal.tactic]}: {proposal.reason}")

    def publish_tactic(self, decision, force: bool = False) -> None:
        sel = self.selector
        key = (sel.current, sel.forced)
        if not force and key == self._published:
            return
        if decision is not None and decision.changed:
            self.get_logger().info(f"tactic {NAMES[sel.current]}: {sel.reason}")
        self._published = key
        msg = TacticState(robot=self.robot, tactic=sel.current, name=NAMES[sel.current], forced=sel.forced is not None,
                          reason=sel.reason)
        msg.header.stamp = to_stamp(self.now_seconds())
        self.tactic_pub.publish(msg)


def main(argv: list[str] | None = None) -> int:
    return run(TacticsNode, argv)


if __name__ == "__main__":
    sys.exit(main())

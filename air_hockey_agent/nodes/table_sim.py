"""``table_sim`` node: the pybullet table standing in for the OptiTrack system and both robots.

Publishes ``/clock`` (simulated time; run every other node with ``use_sim_time``), ``/optitrack/puck``
(geometry_msgs/PoseStamped, mocap frame, 120 Hz with the lab's imperfections), ``/sim/puck_true_state``
(PuckState, table frame, at every mocap tick), ``/sim/contacts`` (MalletContact: which mallet touched the
puck, when, and the puck's velocity after) and ``/<robot>/joint_states`` (sensor_msgs/JointState).
Executes ``/<robot>/joint_trajectory`` (trajectory_msgs/JointTrajectory). Services: ``set_puck_state``
(SetPuckState, table frame) and ``reset_robots`` (std_srvs/Trigger). ``real_time_factor`` 1.0 is
watchable, larger is faster, 0 is as fast as possible: then, while agents publish their clocks on
``/<robot>/{tactics,trajectory_generator}/sim_sync`` (rosgraph_msgs/Clock), it stays at most
``lockstep_lead`` ahead of the slowest.
``gui:=true`` opens the pybullet window.
The world and the output schedule are :mod:`air_hockey_agent.sim`; this module only translates.
"""
from __future__ import annotations

import math
import sys
import time

import numpy as np
import rclpy
from air_hockey_msgs.msg import MalletContact, PuckState
from air_hockey_msgs.srv import SetPuckState
from geometry_msgs.msg import PoseStamped
from rclpy._rclpy_pybind11 import RCLError
from rclpy.executors import ExternalShutdownException
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_srvs.srv import Trigger
from trajectory_msgs.msg import JointTrajectory as JointTrajectoryMsg

from air_hockey_agent.core.frames import quaternion_from_yaw
from air_hockey_agent.core.estimation.synthetic import MocapImperfections
from air_hockey_agent.nodes.messages import state_msg, to_seconds, to_stamp
from air_hockey_agent.nodes.runtime import AirHockeyNode, NodeStartupError, run
from air_hockey_agent.sim.params import PARAM_FILES, ROBOTS, SIM_PARAMS
from air_hockey_agent.sim.runner import Every, SimRunner
from air_hockey_agent.sim.world import ARM_JOINTS, STRIKER_JOINTS, SimSettings, TableWorld
from air_hockey_agent.tools.ros_env import display_available



SYNCED_NODES = ("tactics", "trajectory_generator")  # agents whose clocks the simulation waits for at rtf 0


class TableSimNode(AirHockeyNode):
    NAME = "table_sim"
    DESCRIPTION = __doc__
    PARAM_FILES = PARAM_FILES
    PARAMS = SIM_PARAMS

    def __init__(self) -> None:
        super().__init__()
        p = self.params
        if p["gui"] and not display_available():
            raise NodeStartupError("gui:=true needs a display (DISPLAY is not set); run with gui:=false")
        self.world = TableWorld(SimSettings.from_params(p), gui=p["gui"])
        self.runner = SimRunner(self.world, p["mocap_rate"], MocapImperfections.from_params(p),
                                np.random.default_rng(p["seed"]), p["clock_rate"], p["joint_state_rate"],
                                p["mocap_table_pose"])
        self.clock_pub = self.create_publisher(Clock, "/clock", 10)
        self.mocap_pub = self.create_publisher(PoseStamped, "/optitrack/puck", 10)
        self.truth_pub = self.create_publisher(PuckState, "/sim/puck_true_state", 10)
        self.contact_pub = self.create_publisher(MalletContact, "/sim/contacts", 10)
        self.joint_pubs = {r: self.create_publisher(JointState, f"/{r}/joint_states", 10) for r in ROBOTS}
        for robot in ROBOTS:
            self.create_subscription(JointTrajectoryMsg, f"/{robot}/joint_trajectory",
                                     lambda msg, r=robot: self.on_trajectory(r, msg), 10)
        self.agent_clocks: dict[str, tuple[float, float]] = {}  # topic -> (sim time, wall time received)
        for topic in (f"/{robot}/{node}/sim_sync" for robot in ROBOTS for node in SYNCED_NODES):
            self.create_subscription(Clock, topic, lambda msg, t=topic: self.on_agent_clock(t, msg), 10)
        self.create_service(SetPuckState, "set_puck_state", self.on_set_puck_state)
        self.create_service(Trigger, "reset_robots", self.on_reset_robots)
        self.steps_per_round = max(1, round(p["callback_period"] / self.world.dt))  # physics steps between callbacks
        self.started = time.monotonic()
        self.get_logger().info(f"table simulation: physics {p['physics_rate']:.0f} Hz, real-time factor "
                               f"{p['real_time_factor']:g} (0 = as fast as possible), gui {p['gui']}")

    # --- main loop ----------------------------------------------------------------------------
    def spin(self) -> None:
        executor = self.executor_
        wall0, sim0 = time.monotonic(), self.world.time
        report = Every(1.0 / self.params["status_period"])
        while rclpy.ok(context=self.context):
            try:
                executor.spin_once(timeout_sec=0.0)
                if self.waiting_for_agents():
                    executor.spin_once(timeout_sec=0.001)
                    continue
                for _ in range(self.steps_per_round):
                    self.publish(self.runner.step())
            except (RCLError, RuntimeError, ExternalShutdownException):
                if rclpy.ok(context=self.context):
                    raise
                break  # shut down (Ctrl-C / SIGTERM) while publishing
            wall0, sim0 = self._pace(wall0, sim0)
            if report.due(time.monotonic() - self.started) is not None:
                self.get_logger().info(f"sim time {self.world.time:.1f} s, real-time factor "
                                       f"{self.world.time / max(time.monotonic() - self.started, 1e-9):.2f}")

    def on_agent_clock(self, topic: str, msg: Clock) -> None:
        self.agent_clocks[topic] = (to_seconds(msg.clock), time.monotonic())

    def waiting_for_agents(self) -> bool:
        """As fast as possible with lockstep: True while the simulation is more than ``lockstep_lead``
        ahead of an agent that is still publishing its clock."""
        p = self.params
        if p["real_time_factor"] > 0.0 or p["lockstep_lead"] <= 0.0:
            return False
        wall = time.monotonic()
        live = [t for t, received in self.agent_clocks.values() if wall - received < p["lockstep_timeout"]]
        return bool(live) and self.world.time > min(live) + p["lockstep_lead"]

    def _pace(self, wall0: float, sim0: float) -> tuple[float, float]:
        """Sleep to keep ``real_time_factor``; returns the (possibly re-anchored) reference times."""
        rtf = self.params["real_time_factor"]
        if rtf <= 0.0:
            return wall0, sim0
        ahead = (self.world.time - sim0) / rtf - (time.monotonic() - wall0)
        if ahead > 0.0:
            time.sleep(ahead)
        elif ahead < -self.params["max_lag"]:  # far behind (slow machine): run on at full speed without catching up
            return time.monotonic(), self.world.time
        return wall0, sim0

    def on_parameters_changed(self, changed: dict) -> None:
        if "real_time_factor" in changed:
            self.get_logger().info(f"real-time factor now {changed['real_time_factor']:g}")

    def publish(self, out) -> None:
        stamp = to_stamp(out.time)
        if out.clock:
            self.clock_pub.publish(Clock(clock=stamp))
        if out.joint_states:
            for robot in ROBOTS:
                self.joint_pubs[robot].publish(self.joint_state_msg(robot, stamp))
        for c in out.contacts:
            msg = MalletContact(robot=c.robot, duration=c.duration, x=c.x, y=c.y, vx=c.vx, vy=c.vy, speed=c.speed)
            msg.header.stamp, msg.header.frame_id = to_stamp(c.time), "table"
            self.contact_pub.publish(msg)
        if out.true_state is not None:
            self.truth_pub.publish(state_msg(out.true_state, np.zeros((6, 6)), out.time, out.truth_flags))
        if out.mocap is not None:
            mocap_stamp, (x, y, z, yaw) = out.mocap
            msg = PoseStamped()
            msg.header.stamp, msg.header.frame_id = to_stamp(mocap_stamp), "optitrack"
            msg.pose.position.x, msg.pose.position.y, msg.pose.position.z = x, y, z
            q = msg.pose.orientation
            q.x, q.y, q.z, q.w = quaternion_from_yaw(yaw)
            self.mocap_pub.publish(msg)

    def joint_state_msg(self, robot: str, stamp) -> JointState:
        q, dq = self.world.joint_state(robot)
        sq, sdq = self.world.striker_state(robot)
        msg = JointState(name=list(ARM_JOINTS + STRIKER_JOINTS), position=[*q, *sq], velocity=[*dq, *sdq])
        msg.header.stamp = stamp
        return msg

    # --- inputs -------------------------------------------------------------------------------
    def on_trajectory(self, robot: str, msg: JointTrajectoryMsg) -> None:
        topic = f"/{robot}/joint_trajectory"
        try:
            start = to_seconds(msg.header.stamp)
            start = self.world.time if start <= 0.0 else start
            times = [pt.time_from_start.sec + pt.time_from_start.nanosec * 1e-9 for pt in msg.points]
            has_velocities = all(len(pt.velocities) for pt in msg.points) and msg.points
            self.world.receive(robot, list(msg.joint_names), start, times, [list(pt.positions) for pt in msg.points],
                               [list(pt.velocities) for pt in msg.points] if has_velocities else None)
            self.warn_if_late(topic, start + times[0])
        except ValueError as exc:  # TrajectoryError included
            self.get_logger().error(f"{topic}: trajectory ignored: {exc}")

    def warn_if_late(self, topic: str, first_point: float) -> None:
        """Warn when a trajectory's first point [s, sim time] passed more than one callback round before it
        was served: the arm skips that part of the motion (an agent fell behind; lockstep prevents it)."""
        late_steps = round((self.world.time - first_point) / self.world.dt)
        if late_steps > self.steps_per_round:
            self.get_logger().warn(f"{topic}: the trajectory's first point is {late_steps * self.world.dt * 1000:.0f} "
                                   "ms in the past (an agent fell behind the simulation); the arm skips ahead",
                                   throttle_duration_sec=1.0)

    def on_set_puck_state(self, request, response):
        state = [request.x, request.y, request.vx, request.vy, request.theta, request.omega]
        table = self.world.settings.table
        if not all(math.isfinite(v) for v in state):
            response.success, response.message = False, "refused: non-finite values"
        elif not table.contains(request.x, request.y, -table.puck_radius):
            response.success, response.message = False, (
                f"refused: ({request.x:.3f}, {request.y:.3f}) m is not on the playing surface "
                f"(|x| <= {table.x_limit:.3f}, |y| <= {table.y_limit:.3f})")
        else:
            self.world.move_puck(state)
            response.success, response.message = True, f"puck set at t = {self.world.time:.3f} s"
        return response

    def on_reset_robots(self, request, response):
        self.world.reset_robots()
        response.success, response.message = True, "robots at home"
        return response

    def destroy_node(self) -> None:
        self.world.close()
        super().destroy_node()


def main(argv: list[str] | None = None) -> int:
    return run(TableSimNode, argv)


if __name__ == "__main__":
    sys.exit(main())

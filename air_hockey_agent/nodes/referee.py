"""``referee`` node: game status and score; the rules of :mod:`air_hockey_agent.core.game.referee`.

Inputs: ``/optitrack/puck`` (PoseStamped, mocap frame; the referee sees the puck as the mocap does,
independent of the players' trackers) and ``/<robot>/joint_states`` of both robots (mallet positions by
forward kinematics of ``models/iiwa14_striker.urdf``, placed with ``robot_base.<robot>``).
Output: ``/game_status`` (air_hockey_msgs/GameStatus, latched; on every change and every
``status_period``). Services (std_srvs/Trigger): ``~/start_game``, ``~/pause_game``, ``~/stop_game``
(clears the score), ``~/reset_robots`` (robots home, puck on a random side, game stopped). With ``sim`` the
referee puts the puck back after an event through table_sim's ``/set_puck_state`` and homes the
robots through its ``/reset_robots``; on the real table a person does. ``start_game`` is refused ("cannot
start yet") until table_sim has answered those requests: it drops the trajectories of the robots it resets,
so a motion planned before its reset would never run while its planner went on from it.
"""
from __future__ import annotations

import numpy as np
from geometry_msgs.msg import PoseStamped
from rclpy.qos import DurabilityPolicy, QoSProfile
from sensor_msgs.msg import JointState
from std_srvs.srv import Trigger

from air_hockey_msgs.msg import GameStatus
from air_hockey_msgs.srv import SetPuckState
from air_hockey_agent.core.motion.kinematics import ArmKinematics
from air_hockey_agent.core.game.referee import EVENT_NONE, NOT_YET, STATUS_NAMES, Decision, Referee, RefereeSettings
from air_hockey_agent.nodes.messages import joint_vector, pose_measurement, to_seconds, to_stamp
from air_hockey_agent.nodes.runtime import AirHockeyNode, run
from air_hockey_agent.referee_params import PARAM_FILES, REFEREE_PARAMS
from air_hockey_agent.sim.params import ROBOTS
from air_hockey_agent.paths import model_path


class RefereeNode(AirHockeyNode):
    NAME = "referee"
    DESCRIPTION = __doc__
    PARAM_FILES = PARAM_FILES
    PARAMS = REFEREE_PARAMS

    def __init__(self) -> None:
        super().__init__()
        p = self.params
        self.referee = Referee(RefereeSettings.from_params(p), np.random.default_rng(p["seed"]))
        self.kinematics = ArmKinematics(model_path("iiwa14_striker.urdf"))
        self.mallets: dict[str, tuple[float, float]] = {}
        latched = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
        self.status_pub = self.create_publisher(GameStatus, "/game_status", latched)
        self.create_subscription(PoseStamped, "/optitrack/puck", self.on_pose, 10)
        for robot in ROBOTS:
            self.create_subscription(JointState, f"/{robot}/joint_states",
                                     lambda msg, r=robot: self.on_joint_state(r, msg), 10)
        services = (("start_game", self.on_start), ("pause_game", self.on_pause), ("stop_game", self.on_stop),
                    ("reset_robots", self.on_reset))
        for name, handler in services:
            self.create_service(Trigger, f"~/{name}", handler)
        if p["sim"]:
            self.puck_client = self.create_client(SetPuckState, "/set_puck_state")
            self.robots_client = self.create_client(Trigger, "/reset_robots")
        self._published: tuple | None = None
        self._sim_calls: list = []  # table_sim requests (puck, robots) not answered yet
        self.create_timer(1.0 / p["rate"], self.on_tick)
        self.create_timer(p["status_period"], lambda: self.publish_status(force=True))
        self.publish_status(force=True)

    def now_seconds(self) -> float:
        return self.get_clock().now().nanoseconds * 1e-9

    # --- inputs -------------------------------------------------------------------------------
    def on_pose(self, msg: PoseStamped) -> None:
        try:
            z = pose_measurement(msg, self.params["mocap_table_pose"])
            if z is not None:
                self.referee.observe_puck(to_seconds(msg.header.stamp), z[0], z[1])
        except Exception as exc:  # a malformed message must never stop the referee
            self.get_logger().error(f"/optitrack/puck: frame ignored ({type(exc).__name__}: {exc})",
                                    throttle_duration_sec=1.0)

    def on_joint_state(self, robot: str, msg: JointState) -> None:
        try:
            q = joint_vector(self.kinematics, robot, msg, self.get_logger())
            if q is not None:
                self.mallets[robot] = self.kinematics.tip_in_table(q, self.params[f"robot_base.{robot}"])
        except Exception as exc:
            self.get_logger().error(f"/{robot}/joint_states: message ignored ({type(exc).__name__}: {exc})",
                                    throttle_duration_sec=1.0)

    # --- rules --------------------------------------------------------------------------------
    def on_tick(self) -> None:
        decision = self.referee.update(self.now_seconds(), self.mallets)
        if decision is not None:
            self.act(decision)
        self.publish_status()

    def act(self, decision: Decision) -> None:
        state = self.referee.state
        self.get_logger().info(f"{decision.reason}; game {STATUS_NAMES[state.status]}, score "
                               f"iiwa_front {state.score['iiwa_front']} : {state.score['iiwa_back']} iiwa_back")
        if not self.params["sim"]:
            return
        calls = self._pending_sim_calls()
        if decision.reset_robots:
            calls.append(self.robots_client.call_async(Trigger.Request()))
        if decision.reset_puck is not None:
            x, y = decision.reset_puck
            calls.append(self.puck_client.call_async(SetPuckState.Request(x=x, y=y)))

    def _pending_sim_calls(self) -> list:
        """table_sim requests not answered yet (the answered ones are dropped here)."""
        self._sim_calls = [call for call in self._sim_calls if not call.done()]
        return self._sim_calls

    def publish_status(self, force: bool = False) -> None:
        state = self.referee.state
        key = (state.status, state.score["iiwa_front"], state.score["iiwa_back"], state.last_event,
               state.last_event_time)
        if not force and key == self._published:
            return
        self._published = key
        now = self.now_seconds()
        msg = GameStatus(status=state.status, score_front=state.score["iiwa_front"],
                         score_back=state.score["iiwa_back"], last_event=state.last_event,
                         reason=state.reason)
        msg.header.stamp = to_stamp(now)
        msg.header.frame_id = "table"
        if state.last_event != EVENT_NONE:
            msg.last_event_stamp = to_stamp(state.last_event_time)
        self.status_pub.publish(msg)

    # --- services -----------------------------------------------------------------------------
    def _answer(self, response: Trigger.Response, result: tuple[bool, str]) -> Trigger.Response:
        response.success, response.message = result
        self.get_logger().info(f"{result[1]}")
        self.publish_status(force=True)
        return response

    def on_start(self, _request, response):
        if self._pending_sim_calls():  # a trajectory sent now could reach table_sim before the reset, which drops it
            return self._answer(response, (False, f"{NOT_YET}: table_sim is still resetting the robots or the puck"))
        return self._answer(response, self.referee.start(self.now_seconds()))

    def on_pause(self, _request, response):
        return self._answer(response, self.referee.pause(self.now_seconds()))

    def on_stop(self, _request, response):
        return self._answer(response, self.referee.stop(self.now_seconds()))

    def on_reset(self, _request, response):
        decision = self.referee.reset(self.now_seconds())
        self.act(decision)
        return self._answer(response, (True, decision.reason))


def main(argv: list[str] | None = None) -> int:
    return run(RefereeNode, argv)

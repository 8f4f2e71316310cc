"""The launcher's view of a running game: an rclpy node in the ``air-hockey game`` process that starts
the game through the referee, follows the clock, the score, the hits and the tactics, and records.

Message handling only; the counting is :class:`air_hockey_agent.core.game.scoreboard.Scoreboard`.
"""
from __future__ import annotations

import os
import time
from pathlib import Path
from typing import Callable, Mapping, Sequence

from air_hockey_agent.core.game.referee import NOT_YET
from air_hockey_agent.core.game.scoreboard import Scoreboard
from air_hockey_agent.tools import interrupt

START_RETRY = 0.1  # [s] wall time between start requests while the referee waits for table_sim's reset
ENV_KEYS = ("ROS_DOMAIN_ID", "FASTRTPS_DEFAULT_PROFILES_FILE", "RMW_IMPLEMENTATION", "ROS_HOME", "ROS_LOG_DIR")


class GameMonitor:
    def __init__(self, env: Mapping[str, str], robots: Sequence[str], record: Path | None,
                 topics: Mapping[str, str]) -> None:
        for key in ENV_KEYS:  # the same ROS domain and middleware settings as the nodes
            if key in env:
                os.environ[key] = env[key]
        import rclpy
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.qos import DurabilityPolicy, QoSProfile
        from rosgraph_msgs.msg import Clock

        from air_hockey_msgs.msg import GameStatus, MalletContact, TacticState
        from air_hockey_agent.nodes.messages import message_class, to_seconds
        self._rclpy = rclpy
        self.board = Scoreboard(robots)
        self.context = rclpy.Context()
        rclpy.init(context=self.context)
        self.node = rclpy.create_node("game_monitor", context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        latched = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
        board = self.board
        self.node.create_subscription(Clock, "/clock", lambda m: board.on_clock(to_seconds(m.clock)), 10)
        self.node.create_subscription(
            GameStatus, "/game_status",
            lambda m: board.on_status(m.score_front, m.score_back, m.last_event, m.reason,
                                      to_seconds(m.last_event_stamp)), latched)
        self.node.create_subscription(MalletContact, "/sim/contacts",
                                      lambda m: board.on_contact(m.robot, to_seconds(m.header.stamp)), 100)
        for robot in robots:
            self.node.create_subscription(TacticState, f"/{robot}/tactic",
                                          lambda m, r=robot: board.on_tactic(r, m.name, to_seconds(m.header.stamp)),
                                          latched)
        self.writer, self.bag = None, None
        if record is not None:
            from air_hockey_agent.bags.writer import BagWriter
            from air_hockey_agent.tools.files import output_bag_directory
            self.bag = output_bag_directory(record)
            self.writer = BagWriter(self.bag, dict(topics), "mcap").__enter__()
            from air_hockey_agent.tools.record import recording_qos
            for topic, msgtype in topics.items():  # latched topics as latched: what came before is kept
                self.node.create_subscription(message_class(msgtype), topic,
                                              lambda data, t=topic: self.writer.write(t, time.time_ns(), data),
                                              recording_qos(self.node, topic), raw=True)

    def _spin_until(self, done: Callable[[], bool], timeout: float) -> bool:
        deadline = time.monotonic() + timeout
        while not done() and time.monotonic() < deadline:
            self.executor.spin_once(timeout_sec=0.05)
            interrupt.check()
        return done()

    def start_game(self, timeout: float) -> None:
        """Reset through the referee (robots home, the puck on a random side) and start the game."""
        from std_srvs.srv import Trigger

        from air_hockey_agent.tools.game import GameError
        for service in ("/referee/reset_robots", "/referee/start_game"):
            client = self.node.create_client(Trigger, service)
            if not client.wait_for_service(timeout_sec=timeout):
                raise GameError(f"the referee's {service} service did not appear within {timeout:g} s")
            deadline = time.monotonic() + timeout
            while True:
                future = client.call_async(Trigger.Request())
                if not self._spin_until(future.done, timeout):
                    raise GameError(f"{service} failed: no answer")
                result = future.result()
                if result.success:
                    if service.endswith("start_game"):
                        self.board.start()
                    break
                if not result.message.startswith(NOT_YET) or time.monotonic() > deadline:
                    raise GameError(f"{service} failed: {result.message}")
                self._spin_until(lambda: False, START_RETRY)  # the referee waits for table_sim's reset

    def follow(self, duration: float, goals: int, period: float, launcher, say, tty: bool) -> dict:
        """Spin until ``duration`` s of sim time or ``goals`` goals; returns the processes that ended
        meanwhile (empty when the game ran to its end). Ctrl-C ends the game early. ``tty``: rewrite one
        progress line in place instead of printing a line per ``period``."""
        board, last = self.board, time.monotonic()
        try:
            while board.played < duration and not (goals and board.goals >= goals):
                self.executor.spin_once(timeout_sec=0.05)
                interrupt.check()
                ended = launcher.exited()
                if ended:
                    return ended
                if time.monotonic() - last >= period:
                    last = time.monotonic()
                    if tty:
                        print(f"\r[game] {board.progress()}", end="", flush=True)
                    else:
                        say(board.progress())
        except KeyboardInterrupt:
            say("interrupted: ending the game")
        if tty:
            print(flush=True)
        return {}

    def close(self) -> Path | None:
        """Stop recording (the bag appears complete or not at all) and leave ROS."""
        recording = None
        try:
            if self.writer is not None:
                self.writer.__exit__(None, None, None)
                recording = self.bag
        finally:
            self.node.destroy_node()
            self._rclpy.try_shutdown(context=self.context)
        return recording

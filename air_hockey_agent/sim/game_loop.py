"""The two-robot game in one process, without ROS: the same agent, sim, tracker and referee code as the
nodes, called in a fixed order on the simulated clock, so a seed repeats a game exactly.

``air-hockey game --in-process`` runs it. Per physics step (1 kHz, ``config/sim.yaml``): the world
steps; the mallet contacts are counted; on a joint-state tick each robot's arm bookkeeping, tactics and
the referee get the joints and the tracker the mallets (as ``/<robot>/joint_states``; in a mocap dropout
the tracker coasts on them, :meth:`PuckEKF.coast`); on a mocap tick the OptiTrack stand-in's
pose goes to the referee and to the tracker, whose prediction becomes each robot's situation (as
``puck/prediction``); on its tick the referee applies the rules and puts puck and robots back (as
through ``table_sim``'s services); on their tick the tactics decide, and a command is planned and
handed to the arm at once (as ``hit_command`` -> ``joint_trajectory``, without the transport's
delay). Both robots read one tracker: in the node graph each robot has its own, fed the same frames
with the same parameters (``config/tracker.yaml`` and the simulated table's physics,
``config/tracker_sim_table.yaml``), so they hold the same estimate; each robot's tactics aim with that
tracker's physics (as ``puck/physics``, when ``physics_from_tracker``).

Differences from the node graph, all timing: messages arrive at once (the node graph's lockstep lets
an agent lag the simulation by up to 20 ms) and a refused command's answer reaches the tactics in the
same step. Frames: table frame for the tracker and the referee, each robot's own frame for its
tactics and planner (README "Frames and units").
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from air_hockey_agent.core.estimation.agent_prediction import predict_for_agents
from air_hockey_agent.core.estimation.ekf import FLAG_MEASUREMENT_USED, FLAG_PREDICTED, PuckEKF
from air_hockey_agent.core.estimation.synthetic import MocapImperfections
from air_hockey_agent.core.frames import pose_to_measurement, quaternion_from_yaw
from air_hockey_agent.core.game.referee import RUNNING, Decision, Referee, RefereeSettings
from air_hockey_agent.core.game.scoreboard import Scoreboard
from air_hockey_agent.core.game.situation import (Situation, own_frame_physics, situation_from_prediction,
                                                  to_own_frame)
from air_hockey_agent.core.game.tactics.base import NAMES
from air_hockey_agent.core.motion.arm_commander import ArmCommander
from air_hockey_agent.core.motion.kinematics import ArmKinematics, TableMallets, in_order
from air_hockey_agent.core.motion.planner import Command
from air_hockey_agent.sim.params import ROBOTS
from air_hockey_agent.sim.runner import Every, SimRunner
from air_hockey_agent.sim.world import ARM_JOINTS, STRIKER_JOINTS, SimSettings, TableWorld

JOINT_NAMES = ARM_JOINTS + STRIKER_JOINTS  # as table_sim's joint_states name them


@dataclass
class GameConfig:
    """The parameters of every part, as the node graph loads them (``air-hockey game`` passes the same
    overrides: seed, the referee's unattended restart, the simulated table's puck physics). ``variants``:
    robot -> its own (agent, motion) parameters (``--versus``); the other robots play with ``agent`` and
    ``motion``. ``trackers``: robot -> its own tracker parameters, when its variant file sets any (in the
    node graph each robot has its tracker); the other robots share one tracker with ``tracker``."""

    sim: dict
    tracker: dict
    agent: dict
    motion: dict
    referee: dict
    variants: dict = field(default_factory=dict)
    trackers: dict = field(default_factory=dict)

    @classmethod
    def load(cls, seed: int, versus: tuple[str, str] | dict[str, str] | None = None,
             table: str = "") -> "GameConfig":
        """The defaults; with ``versus`` (robot, parameter YAML), or a dict of such robot -> file, that robot's
        agent reads the file's tactics and trajectory_generator parameters too
        (:func:`~air_hockey_agent.agent_params.load_agent_variant`), and its tracker the file's puck_tracker
        parameters; with ``table`` (a table file,
        :mod:`air_hockey_agent.sim.table_file`) on that simulated table."""
        from air_hockey_agent.agent_params import load_agent_params, load_agent_variant
        from air_hockey_agent.motion_params import load_motion_params
        from air_hockey_agent.params import load_node_params
        from air_hockey_agent.paths import config_file
        from air_hockey_agent import referee_params
        from air_hockey_agent.sim.params import load_sim_params
        from air_hockey_agent.tracker_params import SIM_TABLE_FILE, load_tracker_params
        physics = Path(table) if table else config_file(SIM_TABLE_FILE)
        sim = {**load_sim_params([Path(table)] if table else []), "seed": seed, "gui": False}
        referee = {**load_node_params(referee_params.PARAM_FILES, referee_params.NODE_NAME,
                                      referee_params.REFEREE_PARAMS),
                   "seed": seed, "restart_after_fault": True, "sim": True}
        agent = {**load_agent_params(), "puck_params_file": str(physics)}
        variants, trackers, tracker = {}, {}, load_tracker_params([physics])
        for robot, path in (versus.items() if isinstance(versus, dict) else [versus] if versus else []):
            variant_agent, variant_motion = load_agent_variant(Path(path))
            variants[robot] = ({**variant_agent, "puck_params_file": str(physics)}, variant_motion)
            variant_tracker = load_tracker_params([physics, Path(path)])
            if variant_tracker != tracker:
                trackers[robot] = variant_tracker
        return cls(sim, tracker, agent, load_motion_params(), referee, variants, trackers)

    def agent_for(self, robot: str) -> tuple[dict, dict]:
        """``robot``'s (agent, motion) parameters."""
        return self.variants.get(robot, (self.agent, self.motion))


@dataclass
class Tracker:
    """One tracker of the game (as a ``puck_tracker`` node), its parameters and the robots that read it."""

    ekf: PuckEKF
    params: dict
    robots: tuple[str, ...]
    learned: tuple[int, int] | None = None  # the learning's counts at the last share of its physics


class Player:
    """One robot's agent: its tactics (selector) and its arm's command bookkeeping and planner."""

    def __init__(self, robot: str, config: GameConfig, log: Callable[[str], None] | None) -> None:
        from air_hockey_agent.agent_params import build_selector
        from air_hockey_agent.motion_params import build_planner
        self.robot = robot
        self.agent, m = config.agent_for(robot)
        said = None if log is None else (lambda line: log(f"{robot}: {line}"))
        self.selector, self.kin = build_selector({**self.agent, "robot": robot}, robot, log=said, motion=m)
        self.arm = ArmCommander(build_planner(m, robot), m["planning_delay"], m["max_tracking_error"])
        self.stale_estimate = self.agent["stale_estimate"]
        self.tick = Every(self.agent["rate"])
        self.situation: Situation | None = None
        self.mallet: np.ndarray | None = None
        self.mallet_velocity: np.ndarray | None = None

    def on_joints(self, t: float, values: np.ndarray, velocities: np.ndarray) -> None:
        """Joint positions [rad] and velocities [rad/s] in JOINT_NAMES order at ``t`` [s]."""
        q = in_order(JOINT_NAMES, values, self.kin.joint_names)
        dq = in_order(JOINT_NAMES, velocities, self.kin.joint_names)
        self.mallet, self.mallet_velocity = self.kin.planar_motion(q, dq)
        self.selector.observe_mallet(t, self.mallet, self.mallet_velocity)
        joints = self.arm.planner.kin.joint_names
        self.arm.measure(t, in_order(JOINT_NAMES, values, joints), in_order(JOINT_NAMES, velocities, joints))

    def decide(self, now: float, status: int, world: TableWorld, recorder=None) -> str:
        """The tactics' decision at ``now`` [s]; a command is planned and handed to the arm at once (and
        with ``recorder``, a :class:`~air_hockey_agent.sim.game_record.GameRecorder`, recorded).
        Returns the current tactic's name."""
        fresh = self.situation is not None and now - self.situation.t <= self.stale_estimate
        decision = self.selector.step(now, status, self.situation if fresh else None, self.mallet,
                                      self.mallet_velocity)
        proposal = decision.command
        if proposal is not None:
            wall = time.perf_counter()
            plan = self.arm.plan(Command(np.asarray(proposal.point, float), np.asarray(proposal.velocity, float),
                                         proposal.time), now)
            planning_time = time.perf_counter() - wall
            motion = self._send(plan, now, world) if plan.ok else None
            if recorder is not None:
                recorder.on_command(now, self.robot, proposal, plan, planning_time, motion)
            self.selector.on_status(now, plan.outcome, float(plan.max_speed), now)
        if recorder is not None:
            recorder.on_tactic(now, self.robot, self.selector)
        return NAMES[self.selector.current]

    def _send(self, plan, now: float, world: TableWorld) -> tuple:
        """The accepted plan to the simulated arm, as table_sim executes a received trajectory; returns
        the motion as sent: (times [s] from now, q, dq, joint names)."""
        times, q, dq = self.arm.accept(plan, now)
        joints = self.arm.planner.kin.joint_names
        world.receive(self.robot, joints, now, times, q, dq)
        return times, q, dq, joints


class InProcessGame:
    """One game on the pybullet table; :meth:`run` plays it and returns the scoreboard's result.
    ``robots``: the robots with an agent (the others hold their home pose); ``refereed`` False: no
    referee, the game always running (the strategy test's setting); ``versus`` (robot, parameter YAML), or a
    dict of them: those robots' agent variants; ``table``: another simulated table (:meth:`GameConfig.load`)."""

    def __init__(self, seed: int, gui: bool = False, log: Callable[[str], None] | None = None,
                 robots: tuple[str, ...] = ROBOTS, refereed: bool = True,
                 versus: tuple[str, str] | dict[str, str] | None = None, table: str = "") -> None:
        from air_hockey_agent.paths import model_path
        self.config = c = GameConfig.load(seed, versus, table)
        self.world = TableWorld(SimSettings.from_params(c.sim), gui=gui)
        self.runner = SimRunner(self.world, c.sim["mocap_rate"], MocapImperfections.from_params(c.sim),
                                np.random.default_rng(seed), c.sim["clock_rate"], c.sim["joint_state_rate"],
                                c.sim["mocap_table_pose"])
        self.ekf = PuckEKF.from_params(c.tracker)  # the robots' shared tracker (and the recorder's)
        self.trackers = [Tracker(self.ekf, c.tracker, tuple(r for r in robots if r not in c.trackers))]
        self.trackers += [Tracker(PuckEKF.from_params(c.trackers[r]), c.trackers[r], (r,)) for r in robots
                          if r in c.trackers]
        self.players = {robot: Player(robot, c, log) for robot in robots}
        self.referee = Referee(RefereeSettings.from_params(c.referee), np.random.default_rng(seed)) if refereed else None
        self.referee_tick = Every(c.referee["rate"])
        self.referee_kin = ArmKinematics(model_path("iiwa14_striker.urdf"))
        self.tracker_mallets = TableMallets(model_path("iiwa14_striker.urdf"),
                                            {r: c.tracker[f"robot_base.{r}"] for r in ROBOTS})
        self.mallets: dict[str, tuple[float, float]] = {}
        self.board = Scoreboard(ROBOTS)
        self.recorder = None  # a GameRecorder (sim/game_record.py) to record the game
        self._share_physics()

    def _share_physics(self) -> None:
        """As the node graph's ``puck/physics``: each robot's tactics aim with the tracker's physics
        (``physics_from_tracker``), at the start and whenever the tracker has learned more of the table."""
        for tracker in self.trackers:
            if tracker.ekf.learned == tracker.learned:
                continue
            tracker.learned = tracker.ekf.learned
            for robot in tracker.robots:
                if self.players[robot].agent["physics_from_tracker"]:
                    self.players[robot].selector.shots.use_physics(own_frame_physics(tracker.ekf.model.params,
                                                                                      robot))

    def close(self) -> None:
        self.world.close()

    def run(self, duration: float, goals: int = 0, progress: Callable[[str], None] | None = None,
            progress_period: float = 10.0, real_time_factor: float = 0.0,
            check: Callable[[], None] = lambda: None) -> dict:
        """Play ``duration`` [s] of simulated time (or until ``goals`` goals, 0: off); ``progress`` gets a
        line every ``progress_period`` [s] of wall time; ``real_time_factor`` > 0 paces the simulation.
        KeyboardInterrupt ends the game there, raised by a signal or by ``check``, called after every step (the
        tool's :func:`air_hockey_agent.tools.interrupt.check`: a signal whose exception Python discarded)."""
        self._start()
        wall0, sim0 = time.monotonic(), self.world.time
        next_report = wall0 + progress_period
        try:
            while self.board.played < duration and not (goals and self.board.goals >= goals):
                self.step()
                check()
                now = time.monotonic()
                if real_time_factor > 0.0:
                    ahead = (self.world.time - sim0) / real_time_factor - (now - wall0)
                    if ahead > 0.0:
                        time.sleep(ahead)
                if progress is not None and now >= next_report:
                    progress(self.board.progress())
                    next_report = now + progress_period
        except KeyboardInterrupt:
            if progress is not None:
                progress("interrupted: ending the game")
        return self.board.result(None)

    def _start(self) -> None:
        """As ``air-hockey game`` does through the referee: reset (robots home, the puck put on a random
        side), then start once the referee has seen the puck (within ``lost_timeout``)."""
        self._act(self.referee.reset(self.world.time))
        deadline = self.world.time + self.config.referee["lost_timeout"]
        while True:
            self.step()
            ok, message = self.referee.start(self.world.time)
            if ok:
                break
            if self.world.time > deadline:
                raise RuntimeError(f"the referee did not start the game: {message}")
        self.board.start()

    @property
    def status(self) -> int:
        """The referee's game status (always running without a referee)."""
        return RUNNING if self.referee is None else self.referee.state.status

    def step(self):
        """One physics step and everything that falls due at its time; returns the step's
        :class:`~air_hockey_agent.sim.runner.StepOutput`."""
        out = self.runner.step()
        t = out.time
        self.board.on_clock(t)
        for contact in out.contacts:
            self.board.on_contact(contact.robot, contact.time)
        if out.joint_states:
            self._joints(t)
        if out.mocap is not None:
            self._frame(*out.mocap)
        if self.referee is not None and self.referee_tick.due(t) is not None:
            decision = self.referee.update(t, self.mallets)
            if decision is not None:
                self._act(decision)
            s = self.referee.state
            self.board.on_status(s.score[ROBOTS[0]], s.score[ROBOTS[1]], s.last_event, s.reason, s.last_event_time)
            if self.recorder is not None:
                self.recorder.on_status(t, s)
        for robot, player in self.players.items():
            if player.tick.due(t) is not None:
                self.board.on_tactic(robot, player.decide(t, self.status, self.world, self.recorder), t)
        if self.recorder is not None:
            self.recorder.on_step(out)
        return out

    def _joints(self, t: float) -> None:
        for robot in ROBOTS:
            q, dq = self.world.joint_state(robot)
            sq, sdq = self.world.striker_state(robot)
            values, velocities = np.concatenate([q, sq]), np.concatenate([dq, sdq])
            if robot in self.players:
                self.players[robot].on_joints(t, values, velocities)
            if self.recorder is not None:
                self.recorder.on_joints(t, robot, values, velocities)
            if self.referee is not None:
                arm = in_order(JOINT_NAMES, values, self.referee_kin.joint_names)
                self.mallets[robot] = self.referee_kin.tip_in_table(arm, self.config.referee[f"robot_base.{robot}"])
            if any(tracker.ekf.mallets is not None for tracker in self.trackers):  # as the nodes' joint_states
                position, velocity = self.tracker_mallets.motion(robot, JOINT_NAMES, values, velocities)
                for tracker in self.trackers:
                    tracker.ekf.observe_mallet(robot, t, position, velocity)
        for tracker in self.trackers:
            if tracker.ekf.coast(t):  # a dropout, and the estimate met a mallet in it: as the node publishes
                self._estimate(tracker, t, FLAG_PREDICTED)

    def _frame(self, stamp: float, pose: tuple) -> None:
        """A mocap frame: (x, y, z) [m] and yaw [rad] in the mocap frame at ``stamp`` [s]."""
        x, y, z, yaw = pose
        measurement = pose_to_measurement((x, y, z), quaternion_from_yaw(yaw), self.config.tracker["mocap_table_pose"],
                                          "optitrack")
        if measurement is not None and self.referee is not None:
            self.referee.observe_puck(stamp, measurement[0], measurement[1])
        flags = [tracker.ekf.process(stamp, measurement) for tracker in self.trackers]
        self._share_physics()
        if self.recorder is not None:
            self.recorder.on_mocap(measurement)
        for tracker, tracker_flags in zip(self.trackers, flags):
            if tracker.ekf.initialised:
                self._estimate(tracker, stamp, tracker_flags)

    def _estimate(self, tracker: Tracker, stamp: float, flags: int) -> None:
        """A tracker's estimate and prediction after a frame at ``stamp`` [s] (or a coast, :meth:`PuckEKF.coast`)
        with ``flags`` (``FLAG_*``): its robots' situations (as ``puck/prediction``)."""
        ekf, p = tracker.ekf, tracker.params
        prediction = predict_for_agents(ekf, p["prediction_horizon"], p["prediction_sample_period"],
                                        p["defend_line_offset"])
        if self.recorder is not None and ekf is self.ekf:
            self.recorder.on_estimate(ekf, flags, prediction)
        for robot in tracker.robots:
            player = self.players[robot]
            player.situation = situation_from_prediction(robot, ekf.x, prediction, ekf.P)
            if flags & FLAG_MEASUREMENT_USED:
                player.selector.observe_puck(stamp, to_own_frame(ekf.x, robot))

    def _act(self, decision: Decision) -> None:
        """What table_sim does for the referee: robots home, the puck put down at rest."""
        if decision.reset_robots:
            self.world.reset_robots()
        if decision.reset_puck is not None:
            x, y = decision.reset_puck
            self.world.move_puck([x, y, 0.0, 0.0, 0.0, 0.0])


def play_game(seed: int, duration: float, goals: int = 0, gui: bool = False, real_time_factor: float = 0.0,
              progress_period: float = 10.0, progress: Callable[[str], None] | None = None,
              record: Path | None = None, versus: tuple[str, str] | None = None, table: str = "",
              check: Callable[[], None] = lambda: None) -> dict:
    """One game of ``duration`` [s] (or ``goals`` goals) with ``seed``; the scoreboard's result. With
    ``record``, the game is also written to that MCAP bag directory (:mod:`air_hockey_agent.sim.game_record`;
    the result's ``"recording"``); with ``versus`` (robot, parameter YAML), that robot plays the file's agent
    variant; with ``table`` (a table file), on that simulated table; ``check`` as in :meth:`InProcessGame.run`.
    A module-level function, so worker processes can run it."""
    game = InProcessGame(seed, gui=gui, versus=versus, table=table, log=progress)
    try:
        if record is None:
            return game.run(duration, goals, progress, progress_period, real_time_factor, check)
        from air_hockey_agent.sim.game_record import GameRecorder
        with GameRecorder(record, JOINT_NAMES) as game.recorder:
            result = game.run(duration, goals, progress, progress_period, real_time_factor, check)
        return {**result, "recording": str(record)}
    finally:
        game.close()

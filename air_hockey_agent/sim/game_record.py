"""An in-process game recorded as ``air-hockey game --record`` records the node graph's: the same topics
and message types (:mod:`air_hockey_agent.sim.game_topics`) in an MCAP bag, so ``game-check``, Foxglove
and the bag tools read both alike.

What each topic holds, as the node that publishes it in the graph would: ``/optitrack/puck`` (the
OptiTrack stand-in's pose, mocap frame), ``/sim/puck_true_state`` and ``/sim/contacts`` (table_sim),
``/<robot>/joint_states`` (arm and striker joints), ``/game_status`` (the referee's, on every change),
``/<robot>/tactic`` (on every change), ``/<robot>/hit_command``, ``/<robot>/trajectory_status`` and
``/<robot>/joint_trajectory`` (each command, its answer, the accepted motion), ``/<robot>/puck/state``
and ``/<robot>/puck/physics`` (the tracker's estimate, and the physics it predicts with at its first
estimate, stamped zero as the node's at start, and on every learning event: both robots read one
tracker in process, so both topics carry it) and
``/visualization/markers`` (the visualizer's scene, :class:`air_hockey_agent.core.scene.GameScene`, at its
``rate``, ``config/visualizer.yaml``). Log times are the simulated time [ns] the message was made at;
header stamps as the nodes set them (sim time). The bag appears whole when the game ends, or not at all.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from air_hockey_agent.bags.build import (build, header_fields, physics_fields, pose_fields, puck_state_fields,
                                        stamp_fields)
from air_hockey_agent.bags.writer import BagWriter
from air_hockey_agent.core import scene
from air_hockey_agent.core.frames import TABLE_FRAME
from air_hockey_agent.core.game.referee import EVENT_NONE, STATUS_NAMES
from air_hockey_agent.core.game.tactics.base import NAMES
from air_hockey_agent.core.motion.kinematics import ArmKinematics, in_order
from air_hockey_agent.core.table import TableGeometry
from air_hockey_agent.sim.game_topics import MARKER_TOPICS, RECORDED_TOPICS
from air_hockey_agent.sim.params import ROBOTS
from air_hockey_agent.sim.runner import Every

MARKER_DELETEALL = 3  # visualization_msgs/Marker action


def _xyz(values) -> dict:
    return dict(zip("xyz", (float(v) for v in values)))


class GameRecorder:
    """Writes one in-process game to ``path`` (an MCAP bag directory; see the module's docstring).
    Use as a context manager around the game; :class:`air_hockey_agent.sim.game_loop.InProcessGame`
    calls the ``on_*`` methods."""

    def __init__(self, path: Path, joint_names: tuple[str, ...]) -> None:
        from air_hockey_agent.params import load_defaults
        from air_hockey_agent.paths import config_file, model_path
        from air_hockey_agent.visualizer_params import PARAM_FILES, VISUALIZER_PARAMS, scene_style
        p = load_defaults([config_file(f) for f in PARAM_FILES], "/visualizer", VISUALIZER_PARAMS)
        self.path, self.joint_names = Path(path), tuple(joint_names)
        self.scene = scene.GameScene(TableGeometry.from_params(p), scene_style(p))
        self.kinematics = ArmKinematics(model_path("iiwa14_striker.urdf"))
        self.bases = {robot: p[f"robot_base.{robot}"] for robot in ROBOTS}
        self.marker_tick = Every(p["rate"])
        self._types = {**RECORDED_TOPICS, **MARKER_TOPICS}
        self._writer = BagWriter(self.path, self._types, "mcap")
        self._tactics: dict[str, tuple] = {}
        self._status: tuple | None = None
        self._learned: tuple[int, int] | None = None  # the tracker's learning counts last recorded

    def __enter__(self) -> "GameRecorder":
        self._writer.__enter__()
        return self

    def __exit__(self, exc_type, exc, tb) -> bool:
        return self._writer.__exit__(exc_type, exc, tb)

    def _write(self, topic: str, t: float, data: dict) -> None:
        self._writer.write(topic, int(round(t * 1e9)), build(self._types[topic], data))

    # --- table_sim's topics ----------------------------------------------------------------------
    def on_step(self, out) -> None:
        """A physics step's outputs (:class:`air_hockey_agent.sim.runner.StepOutput`; the joints come
        through :meth:`on_joints`) and the scene at the visualizer's rate."""
        t = out.time
        for c in out.contacts:
            self._write("/sim/contacts", t, {"header": header_fields(c.time, TABLE_FRAME), "robot": c.robot,
                                             "duration": c.duration, "x": c.x, "y": c.y, "vx": c.vx, "vy": c.vy,
                                             "speed": math.hypot(c.vx, c.vy)})
        if out.true_state is not None:
            self._write("/sim/puck_true_state", t, puck_state_fields(t, out.true_state, flags=out.truth_flags))
        if out.mocap is not None:
            stamp, (x, y, z, yaw) = out.mocap
            self._write("/optitrack/puck", t, pose_fields(stamp, "optitrack", x, y, z, yaw))
        if self.marker_tick.due(t) is not None:
            shapes = self.scene.shapes(t)
            self._write("/visualization/markers", t, {"markers": [{"action": MARKER_DELETEALL}]
                                                      + [{**scene.marker_fields(s), "header": header_fields(t, TABLE_FRAME)} for s in shapes]})

    def on_joints(self, t: float, robot: str, values: np.ndarray, velocities: np.ndarray) -> None:
        """A robot's joint positions [rad] and velocities [rad/s] at ``t`` [s], in ``joint_names`` order."""
        self._write(f"/{robot}/joint_states", t, {"header": header_fields(t), "name": list(self.joint_names),
                                                   "position": values, "velocity": velocities})
        arm = in_order(self.joint_names, values, self.kinematics.joint_names)
        self.scene.mallets[robot] = self.kinematics.tip_in_table(arm, self.bases[robot])

    # --- the tracker's, the referee's ------------------------------------------------------------
    def on_mocap(self, measurement) -> None:
        """The table-frame measurement (x, y, theta) of the latest pose, or None (unusable)."""
        self.scene.measurement = None if measurement is None else (float(measurement[0]), float(measurement[1]))

    def on_estimate(self, ekf, flags: int, prediction) -> None:
        """The tracker's estimate after a frame (``flags``: PuckState.FLAG_*) and its prediction for the
        agents (:class:`air_hockey_agent.core.estimation.agent_prediction.AgentPrediction`)."""
        t = ekf.stamp
        for robot in ROBOTS:
            self._write(f"/{robot}/puck/state", t, puck_state_fields(t, ekf.x, ekf.P, flags))
        if ekf.learned != self._learned:
            effective = 0.0 if self._learned is None else t
            self._learned = ekf.learned
            for robot in ROBOTS:
                self._write(f"/{robot}/puck/physics", t, physics_fields(effective, ekf.model.params, *self._learned))
        x, y, vx, vy, theta, _ = (float(v) for v in ekf.x)
        self.scene.estimate = (x, y, theta, vx, vy)
        pred = prediction.prediction
        path = [(x, y)] + [(float(s[0]), float(s[1])) for _, s, _ in pred.samples]
        self.scene.prediction = (path, [(float(ix), float(iy)) for _, _, ix, iy, _ in pred.impacts])

    def on_status(self, t: float, state) -> None:
        """The referee's :class:`~air_hockey_agent.core.game.referee.GameState` at ``t`` [s], written when it
        changed."""
        key = (state.status, state.score[ROBOTS[0]], state.score[ROBOTS[1]], state.last_event, state.reason,
               state.last_event_time)
        if key == self._status:
            return
        self._status = key
        data = {"header": header_fields(t, TABLE_FRAME), "status": state.status, "score_front": state.score[ROBOTS[0]],
                "score_back": state.score[ROBOTS[1]], "last_event": state.last_event, "reason": state.reason}
        if state.last_event != EVENT_NONE:
            data["last_event_stamp"] = stamp_fields(state.last_event_time)
        self._write("/game_status", t, data)
        self.scene.status = scene.status_text(STATUS_NAMES.get(state.status, "?"), data["score_front"],
                                              data["score_back"], state.reason)

    # --- each robot's tactics and trajectory generator -------------------------------------------
    def on_tactic(self, t: float, robot: str, selector) -> None:
        """The robot's tactic after a decision, written when it changed."""
        key = (selector.current, selector.forced)
        if self._tactics.get(robot) == key:
            return
        self._tactics[robot] = key
        self._write(f"/{robot}/tactic", t, {"header": header_fields(t), "robot": robot, "tactic": selector.current,
                                            "name": NAMES[selector.current], "forced": selector.forced is not None,
                                            "reason": selector.reason})
        self.scene.tactics[robot] = NAMES[selector.current]

    def on_command(self, t: float, robot: str, proposal, plan, planning_time: float, motion=None) -> None:
        """A command sent at ``t`` [s] (the tactics' Proposal, robot frame), the planner's answer and, if
        accepted, the motion handed to the arm: (times [s] from ``t``, q, dq) in ``plan``'s joint order."""
        point, velocity, target = (tuple(float(v) for v in a) for a in (proposal.point, proposal.velocity,
                                                                           proposal.target))
        self._write(f"/{robot}/hit_command", t, {
            "header": header_fields(t, robot), "tactic": proposal.tactic, "hit_point": _xyz(point),
            "hit_velocity": _xyz(velocity), "hit_time": stamp_fields(proposal.time), "target": _xyz(target)})
        status = {"header": header_fields(t), "command_stamp": stamp_fields(t), "tactic": proposal.tactic,
                  "outcome": plan.outcome, "reason": plan.message, "hit_speed": float(plan.hit_speed),
                  "max_hit_speed": float(plan.max_speed), "planning_time": planning_time}
        if math.isfinite(plan.hit_time):
            status["hit_time"] = stamp_fields(plan.hit_time)
        self._write(f"/{robot}/trajectory_status", t, status)
        self.scene.commands[robot] = scene.SceneCommand(point, velocity, target, float(proposal.time))
        if motion is not None:
            times, q, dq, joints = motion
            self._write(f"/{robot}/joint_trajectory", t, {"header": header_fields(t), "joint_names": list(joints), "points": [
                {"positions": qi, "velocities": dqi, "time_from_start": stamp_fields(ti)}
                for ti, qi, dqi in zip(times, q, dq)]})

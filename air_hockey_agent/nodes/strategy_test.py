"""``strategy_test`` node: runs strategy-test trials against the agent of ``iiwa_front`` (thesis sec. 4.6).

For each trial of the ``trials`` parameter ("strategy:index,..."; initial states from
:mod:`air_hockey_agent.core.game.strategy.trials`): homes the robots (table_sim's ``/reset_robots``), lets the
robot wait at its ready point for ``settle`` (Ready forced, as in a game), forces the tested tactic through
``/iiwa_front/force_tactic`` (the agent's only test hook; Guard releases it to the state machine), sets the
puck through ``/set_puck_state`` and follows ``/sim/puck_true_state`` and ``/sim/contacts`` until the trial
ends (:class:`~air_hockey_agent.core.game.strategy.scoring.TrialWatcher`). Each result is printed as one line
``TRIAL_RESULT {json}``, with the tested robot's tactic and its reason when the trial ended
(``<robot>/tactic``); at the end ``STRATEGY_DONE`` and the node exits. It publishes a running ``/game_status``
(latched) so the tactics play; the opponent runs no agent and holds its home pose, or with ``defended`` runs
its agent, held in Ready through ``/iiwa_back/force_tactic`` until the tested robot's first hit and released
then; its contacts after the hit mark the trial ``defended``.

The node runs on events, not on a clock: its simulated time is the stamp of the latest true puck state
(published at every mocap tick, whether the puck moves or not), and a trial moves on when a service
answers or a puck state or contact arrives. It needs no ``/clock`` (run it without ``use_sim_time``);
a 20 Hz wall-time timer only waits for the services at start and enforces ``wall_timeout``.
"""
from __future__ import annotations

import json
import sys
import time

import rclpy
from rclpy.qos import DurabilityPolicy, QoSProfile
from std_srvs.srv import Trigger

from air_hockey_msgs.msg import GameStatus, MalletContact, PuckState, TacticState
from air_hockey_msgs.srv import ForceTactic, SetPuckState
from air_hockey_agent.core.game.strategy.scoring import TrialResult, TrialWatcher
from air_hockey_agent.core.game.strategy.trials import OPPONENT, PARK, ROBOT, make_trial
from air_hockey_agent.core.game.tactics.base import TACTIC_IDS
from air_hockey_agent.nodes.messages import to_seconds
from air_hockey_agent.nodes.runtime import AirHockeyNode, NodeStartupError, run
from air_hockey_agent.sim.contacts import TOUCHED_FLAGS
from air_hockey_agent.strategy_params import PARAM_FILES, STRATEGY_PARAMS, trial_settings

WALL_CHECK_PERIOD = 0.05  # [s] wall time between checks for the services at start and for wall_timeout


def parse_trials(text: str) -> list[tuple[str, int]]:
    out = []
    for item in filter(None, (t.strip() for t in text.split(","))):
        name, _, index = item.partition(":")
        if not index.isdigit():
            raise ValueError(f"parameter 'trials': '{item}' is not 'strategy:index'")
        out.append((name, int(index)))
    return out


class StrategyTestNode(AirHockeyNode):
    NAME = "strategy_test"
    DESCRIPTION = __doc__
    PARAM_FILES = PARAM_FILES
    PARAMS = STRATEGY_PARAMS

    def __init__(self) -> None:
        super().__init__()
        p = self.params
        self.settings = trial_settings(p)
        try:
            self.queue = [make_trial(name, index, p["seed"], self.settings) for name, index in parse_trials(p["trials"])]
        except ValueError as exc:
            raise NodeStartupError(str(exc)) from exc
        latched = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
        status = self.create_publisher(GameStatus, "/game_status", latched)
        status.publish(GameStatus(status=GameStatus.STATUS_RUNNING))
        self.reset_client = self.create_client(Trigger, "/reset_robots")
        self.puck_client = self.create_client(SetPuckState, "/set_puck_state")
        self.force_client = self.create_client(ForceTactic, f"/{ROBOT}/force_tactic")
        self.opponent_client = self.create_client(ForceTactic, f"/{OPPONENT}/force_tactic") if p["defended"] else None
        self.opponent_waits = False  # the opponent is held in Ready until the tested robot's hit
        self.create_subscription(PuckState, "/sim/puck_true_state", self.on_truth, 100)
        self.create_subscription(MalletContact, "/sim/contacts", self.on_contact, 100)
        self.create_subscription(TacticState, f"/{ROBOT}/tactic", self.on_tactic, latched)
        self.tactic = ""  # the tested robot's latest tactic and why ("smash: smash forced: waiting until it applies")
        self.watcher: TrialWatcher | None = None
        self.phase, self.pending, self.phase_start, self.wall_start = "next", None, 0.0, time.monotonic()
        self.sim_time = 0.0  # [s] stamp of the latest true puck state: the simulation's clock
        self.create_timer(WALL_CHECK_PERIOD, self.advance)

    # --- inputs --------------------------------------------------------------------------------
    def on_truth(self, msg: PuckState) -> None:
        self.sim_time = to_seconds(msg.header.stamp)
        if self.watcher is not None and self.phase == "run":
            self.watcher.state(self.sim_time, msg.x, msg.y, msg.vx, msg.vy,
                               touching=bool(msg.flags & TOUCHED_FLAGS[ROBOT]))
        self.advance()

    def on_tactic(self, msg: TacticState) -> None:
        self.tactic = f"{msg.name}: {msg.reason}"

    def on_contact(self, msg: MalletContact) -> None:
        if self.watcher is None or self.phase != "run":
            return
        if msg.robot != ROBOT:
            self.watcher.opponent_contact(to_seconds(msg.header.stamp))
            return
        self.watcher.contact(to_seconds(msg.header.stamp), msg.duration)
        self.advance()

    # --- trial phases --------------------------------------------------------------------------
    def call(self, client, request) -> None:
        self.pending = client.call_async(request)
        self.pending.add_done_callback(lambda _: self.advance())

    def advance(self) -> None:
        """Move the trial on as far as the answers and the simulated time allow (called on every event)."""
        if self.pending is not None and not self.pending.done():
            if time.monotonic() - self.wall_start > self.params["wall_timeout"]:
                self.finish_trial(f"no answer from a service within {self.params['wall_timeout']:g} s")
            return
        self.pending = None
        now = self.sim_time
        if self.phase == "next":
            clients = [c for c in (self.reset_client, self.puck_client, self.force_client, self.opponent_client) if c]
            if not all(c.service_is_ready() for c in clients):  # a request sent before the server is up is lost
                if time.monotonic() - self.wall_start > self.params["wall_timeout"]:
                    missing = [c.srv_name for c in clients if not c.service_is_ready()]
                    self.get_logger().error(f"services not available: {', '.join(missing)}")
                    rclpy.try_shutdown()
                return
            if not self.queue:
                print("STRATEGY_DONE", flush=True)
                rclpy.try_shutdown()
                return
            self.trial = self.queue.pop(0)
            self.wall_start = time.monotonic()
            self.phase = "reset"
            self.call(self.puck_client, SetPuckState.Request(x=PARK[0], y=PARK[1]))
        elif self.phase == "reset":
            self.phase = "force"
            self.call(self.reset_client, Trigger.Request())
        elif self.phase == "force":  # wait at the ready point, as in a game, then the tested tactic
            self.phase, self.phase_start = "force opponent" if self.opponent_client else "ready", None
            self.call(self.force_client, ForceTactic.Request(force=True, tactic=TACTIC_IDS["ready"]))
        elif self.phase == "force opponent":
            self.phase, self.opponent_waits = "ready", True
            self.call(self.opponent_client, ForceTactic.Request(force=True, tactic=TACTIC_IDS["ready"]))
        elif self.phase == "ready" and self.phase_start is None:
            self.phase_start = now  # Ready is in force (answered): settle from here, not from the request
        elif self.phase == "ready" and now - self.phase_start >= self.params["settle"]:
            self.phase = "settle"
            tactic = self.trial.tactic  # "": released to the state machine
            self.call(self.force_client, ForceTactic.Request(force=bool(tactic), tactic=TACTIC_IDS.get(tactic, 0),
                                                             variant=self.trial.variant))
        elif self.phase == "settle":
            x, y, vx, vy, theta, omega = self.trial.state
            self.watcher = TrialWatcher(self.trial, self.settings)
            self.phase = "run"
            self.call(self.puck_client, SetPuckState.Request(x=x, y=y, vx=vx, vy=vy, theta=theta, omega=omega))
        elif self.phase == "run":
            if self.opponent_waits and self.watcher.hit:
                self.opponent_waits = False  # the shot is played: the opponent defends
                self.call(self.opponent_client, ForceTactic.Request(force=False))
            elif self.watcher.done:
                self.finish_trial(None)
            elif time.monotonic() - self.wall_start > self.params["wall_timeout"]:
                self.finish_trial(f"no outcome within {self.params['wall_timeout']:g} s of wall time")

    def finish_trial(self, failure: str | None) -> None:
        if failure is None:
            result = self.watcher.result()
        else:
            result = TrialResult(self.trial.strategy, self.trial.index, reason=failure)
        record = result.record(failure is not None, self.tactic, self.trial.state)  # the tactic says why no hit, say
        print("TRIAL_RESULT " + json.dumps(record), flush=True)
        self.watcher, self.phase = None, "release"
        self.call(self.force_client, ForceTactic.Request(force=True, tactic=TACTIC_IDS["ready"]))
        self.phase = "next"


def main(argv: list[str] | None = None) -> int:
    return run(StrategyTestNode, argv)


if __name__ == "__main__":
    sys.exit(main())

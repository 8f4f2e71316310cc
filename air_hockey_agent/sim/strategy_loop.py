"""The strategy test's trials in one process, without ROS (``air-hockey strategy-test --in-process``).

Each trial runs as the ``strategy_test`` node runs it (thesis sec. 4.6): the puck parked on the opponent's
half, the robots homed, ``iiwa_front`` waiting at its ready point for ``settle``, the tested tactic forced
(for Guard none: the state machine decides), the puck set to the trial's initial state, and the true puck
states and the robot's contacts fed to the core
:class:`~air_hockey_agent.core.game.strategy.scoring.TrialWatcher` until it scores the trial. The agent,
tracker and table are :class:`~air_hockey_agent.sim.game_loop.InProcessGame` with ``iiwa_front``'s agent only
(the opponent holds its home pose) and no referee (always running). With ``defended`` the opponent runs its
agent too (the defaults, or its variant file): it waits at its ready point (Ready forced) until the tested
robot's first hit, then plays free, and its contacts after the hit mark the trial ``defended``.

Trials run in chunks of ``CHUNK`` consecutive trials of the run's list, each chunk on a fresh table
whose simulation seed is drawn from the run's seed and the chunk's number, so a trial's outcome does
not depend on how many workers share the chunks, and a run repeats exactly.
"""
from __future__ import annotations

from typing import Sequence

import numpy as np

from air_hockey_agent.core.game.strategy.scoring import TrialResult, TrialWatcher
from air_hockey_agent.core.game.strategy.trials import OPPONENT, PARK, ROBOT, Trial, TrialSettings, make_trial
from air_hockey_agent.core.game.tactics.base import NAMES, TACTIC_IDS

CHUNK = 20       # trials per fresh table
SIM_GUARD = 5.0  # [s] of simulated time beyond the watcher's own time-outs before a trial is given up


def chunks(trials: Sequence[tuple[str, int]]) -> list[tuple[int, list[tuple[str, int]]]]:
    """(chunk number, its trials) in order."""
    return [(k // CHUNK, list(trials[k:k + CHUNK])) for k in range(0, len(trials), CHUNK)]


def chunk_seed(seed: int, chunk: int) -> int:
    """The simulation seed of a chunk's table (its mocap noise), from the run's seed and the chunk."""
    return int(np.random.SeedSequence([seed, chunk]).generate_state(1)[0] % 2 ** 31)


def run_chunk(seed: int, chunk: int, trials: Sequence[tuple[str, int]], params_file: str = "",
              defended: bool = False, opponent_file: str = "", table_file: str = "") -> list[dict]:
    """Play ``trials`` ((strategy, index) pairs) on a fresh table; their ``--results`` records in order.
    ``params_file``: the tested agent reads this variant too (``strategy-test --params-file``); the trials'
    initial states stay those of the defaults, so a variant meets the same pucks. ``defended``: the opponent
    plays (``strategy-test --defended``), reading ``opponent_file`` too (``--opponent-params``).
    ``table_file``: on that simulated table (``--table``)."""
    from air_hockey_agent.sim.game_loop import InProcessGame
    from air_hockey_agent.strategy_params import trial_settings
    settings = trial_settings(table_file=table_file)
    variants = {robot: path for robot, path in ((ROBOT, params_file), (OPPONENT, opponent_file)) if path}
    game = InProcessGame(chunk_seed(seed, chunk), robots=(ROBOT, OPPONENT) if defended else (ROBOT,),
                         refereed=False, versus=variants, table=table_file)
    try:
        return [play_trial(game, make_trial(name, index, seed, settings), settings) for name, index in trials]
    finally:
        game.close()


def play_trial(game, trial: Trial, settings: TrialSettings) -> dict:
    """One trial on ``game`` (an InProcessGame with ``iiwa_front``'s agent, and the opponent's when it
    defends); its record."""
    selector = game.players[ROBOT].selector
    opponent = game.players[OPPONENT].selector if OPPONENT in game.players else None
    game.world.move_puck([*PARK, 0.0, 0.0, 0.0, 0.0])
    game.world.reset_robots()
    for waiting in filter(None, (selector, opponent)):
        waiting.force(TACTIC_IDS["ready"])
    _advance(game, settings.settle)
    selector.force(TACTIC_IDS[trial.tactic] if trial.tactic else None, trial.variant)
    watcher = TrialWatcher(trial, settings)
    game.world.move_puck(list(trial.state))
    allowed = settings.timeout + settings.after_hit + SIM_GUARD
    limit = game.world.time + allowed
    failure = None
    while not watcher.done:
        if game.world.time > limit:
            failure = f"no outcome within {allowed:g} s of simulated time"
            break
        out = game.step()
        for contact in out.contacts:
            if contact.robot == ROBOT:
                watcher.contact(contact.time, contact.duration)
                if opponent is not None and opponent.forced is not None:
                    opponent.force(None)  # the shot is played: the opponent defends
            else:
                watcher.opponent_contact(contact.time)
        if out.true_state is not None:
            watcher.state(out.time, *(float(v) for v in out.true_state[:4]),  # as the message carries them
                          touching=ROBOT in out.in_contact)
    tactic = f"{NAMES[selector.current]}: {selector.reason}"
    for waiting in filter(None, (selector, opponent)):
        waiting.force(TACTIC_IDS["ready"])
    if failure is not None:
        return TrialResult(trial.strategy, trial.index, reason=failure).record(True, tactic, trial.state)
    return watcher.result().record(False, tactic, trial.state)


def _advance(game, seconds: float) -> None:
    end = game.world.time + seconds
    while game.world.time < end:
        game.step()

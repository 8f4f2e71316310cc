"""The mallet's contact law learned online (core/game/contact_learning.py): from samples as the tactics get them,
against contacts made with another law, and in a game on a table whose mallet is not the configured one."""
from __future__ import annotations

import math

import numpy as np
import pytest

from air_hockey_agent.core.game.contact_check import MalletPath, fit_law, measure_contacts
from air_hockey_agent.core.game.contact_learning import SEARCH_PERIOD, ContactLearner
from contact_fixtures import GEOMETRY, contact_yaw, made_contact

TRUE_E, TRUE_MU = 0.6, 0.25  # the mallet the contacts are made with (the tactics are told 0.8, 0.1)


def _contacts(count: int, rng: np.random.Generator) -> list[tuple]:
    """``count`` contacts 1 s apart made with TRUE_E, TRUE_MU: (puck times, positions, yaws, mallet times,
    positions, velocities) each, the puck spinning at up to 15 rad/s."""
    out = []
    for k in range(count):
        angle, v_mallet, v_in = 0.0, np.zeros(2), np.zeros(2)
        while (v_in - v_mallet) @ [math.cos(angle), math.sin(angle)] > -0.3:  # closing at 0.3 m/s or more
            angle, v_mallet = rng.uniform(-0.8, 0.8), rng.uniform(-0.8, 0.8, 2)
            v_in = np.array([-rng.uniform(1.0, 3.0), rng.uniform(-0.8, 0.8)])
        spin = rng.uniform(-15.0, 15.0)
        t, puck, tm, mallet, mv, _ = made_contact(1.0 + k, np.array([-0.4, rng.uniform(-0.2, 0.2)]), v_in, angle,
                                                  v_mallet, TRUE_E, TRUE_MU, rng, spin=spin, mallet_rate=100.0)
        out.append((t, puck, contact_yaw(t, 1.0 + k, spin), tm, mallet, mv))
    return out


def _play(learner: ContactLearner, contacts: list[tuple]) -> list:
    """Feed the samples in time order as the tactics get them, updating at every decision (100 Hz); the laws
    returned."""
    events = []
    for t, puck, yaw, tm, mallet, mv in contacts:
        events += [(s, 0, (p, w)) for s, p, w in zip(t, puck, yaw)]
        events += [(s, 1, (p, v)) for s, p, v in zip(tm, mallet, mv)]
    laws, decided = [], -math.inf
    for stamp, kind, (a, b) in sorted(events, key=lambda e: e[0]):
        if kind == 0:
            learner.puck(stamp, a[0], a[1], b)
        else:
            learner.mallet(stamp, a, b)
        if stamp - decided >= 0.01:
            decided = stamp
            laws.append(learner.update(stamp, None))
    return laws


def test_the_learner_finds_the_law_its_contacts_were_made_with():
    learner = ContactLearner(GEOMETRY, 8, 50, (0.3, 1.0), (0.0, 0.5))
    laws = [law for law in _play(learner, _contacts(12, np.random.default_rng(4))) if law is not None]
    assert learner.seen == 12 and len(learner.contacts) == 12  # each contact measured once
    assert len(laws) == 5 and [law.seen for law in laws] == [8, 9, 10, 11, 12]  # from the 8th on, at each new one
    assert laws[-1].restitution == pytest.approx(TRUE_E, abs=0.03) and laws[-1].friction == pytest.approx(TRUE_MU,
                                                                                                          abs=0.05)
    capped = ContactLearner(GEOMETRY, 4, 5, (0.7, 1.0), (0.0, 0.5))
    last = [law for law in _play(capped, _contacts(8, np.random.default_rng(4))) if law is not None][-1]
    assert last.contacts == 5 and last.seen == 8 and last.restitution == pytest.approx(0.7)  # the newest 5; bound


def test_no_update_between_search_periods_or_without_samples():
    learner = ContactLearner(GEOMETRY, 1, 50, (0.3, 1.0), (0.0, 0.5))
    assert learner.update(0.0, None) is None  # no samples
    for t, puck, yaw, tm, mallet, mv in _contacts(1, np.random.default_rng(2)):
        for s, p, w in zip(t, puck, yaw):
            learner.puck(s, p[0], p[1], w)
        for s, p, v in zip(tm, mallet, mv):
            learner.mallet(s, p, v)
    assert learner.update(1.05, None) is None  # the contact (at 1.0 s) not yet SETTLED
    assert learner.update(1.05 + SEARCH_PERIOD / 2, None) is None  # searched too recently
    assert learner.update(1.2, None).seen == 1 and learner.update(1.35, None) is None  # measured once


def test_an_arm_put_somewhere_makes_no_contact_and_an_odd_contact_does_not_swing_the_fit():
    """A reset between two joint states (the mallet 0.3 m away at rest in both) would make the Hermite curve
    swing at tens of m/s through the puck: no contact there; and the fit is robust to one exit measured wrong."""
    times = np.arange(0.0, 1.0, 0.01)
    positions = np.where((times < 0.5)[:, None], [-0.7, 0.0], [-0.4, 0.3])
    path = MalletPath(times, positions, np.zeros((len(times), 2)))
    assert np.all(np.isnan(path.velocity(0.495))) and path.velocity(0.3) == pytest.approx([0.0, 0.0])
    rng = np.random.default_rng(9)
    contacts = []
    for t, puck, yaw, tm, mallet, mv in _contacts(10, rng):
        contacts += measure_contacts(t, puck, tm, mallet, mv, GEOMETRY, yaw)
    assert len(contacts) == 10
    contacts[3] = type(contacts[3])(**{**contacts[3].__dict__, "exit_measured": contacts[3].exit_measured + 3.0})
    e, mu, _ = fit_law(contacts, GEOMETRY.puck_radius)
    assert e == pytest.approx(TRUE_E, abs=0.03) and mu == pytest.approx(TRUE_MU, abs=0.05)


@pytest.mark.slow  # in-process: no ROS node
def test_a_game_on_a_table_whose_mallet_is_not_the_configured_one(tmp_path):
    """Both robots, told 0.8, learn the 0.6 of a simulated table's mallet (pybullet's contacts, not the law) from
    the tracker's estimates and their joint states in a 60 s game, and aim with it."""
    from air_hockey_agent.sim.game_loop import InProcessGame
    table = tmp_path / "mallet.yaml"
    table.write_text("/**/table_sim:\n  ros__parameters:\n    mallet_restitution: 0.6\n")
    game = InProcessGame(31, table=str(table))
    try:
        game.run(60.0)
    finally:
        game.close()
    for player in game.players.values():
        learned, selector = player.selector.learned, player.selector
        assert learned is not None and learned.seen >= 10, learned
        assert learned.restitution == pytest.approx(0.6, abs=0.04) and learned.friction == pytest.approx(0.1, abs=0.05)
        assert selector.shots.s.mallet_restitution == learned.restitution == selector.s.mallet_restitution

"""The robots' mallets in the tracker (core/estimation/mallet_contacts.py): the first contact against a
brute-force search, the contact against the heavy-mallet law, the mallets' tracks, and the filter through
a hit it does not see (a mocap dropout), on a truth whose restitution is not the filter's."""
from dataclasses import replace

import numpy as np
import pytest

from air_hockey_agent.core.estimation.ekf import FilterSettings, PuckEKF
from air_hockey_agent.core.estimation.mallet_contacts import (MalletContactSettings, MalletTracks, apply_contact,
                                                              first_contact)
from air_hockey_agent.core.estimation.synthetic import simulate_truth, true_state_at
from model_fixtures import DT, Q, model

SETTINGS = FilterSettings(dt=DT, q=Q, r=np.diag([1e-8, 1e-8, 1e-4]), p0=np.diag([1e-6, 1e-6, 1.0, 1.0, 1e-4, 100.0]),
                          gate_threshold=13.82, max_consecutive_rejections=3, outside_table_margin=0.05,
                          max_prediction_gap=2.0, mallet=MalletContactSettings(enabled=True))
REACH = 0.03165 + 0.04815  # puck and mallet radius [m]


def brute_force_contact(pp, vp, pm, vm, distance, horizon, step=1e-6):
    """The first time on a fine grid at which the centres are ``distance`` apart or closer (None)."""
    s = np.arange(0.0, horizon + step, step)
    gaps = np.hypot(*(pp[:, None] + np.outer(vp, s) - pm[:, None] - np.outer(vm, s)))
    inside = np.nonzero(gaps <= distance)[0]
    return None if len(inside) == 0 else s[inside[0]]


@pytest.mark.parametrize("pp, vp, pm, vm", [
    ((0.0, 0.0), (1.0, 0.0), (0.2, 0.0), (0.0, 0.0)),      # the puck runs into a resting mallet
    ((0.0, 0.0), (0.0, 0.0), (-0.15, 0.03), (2.0, 0.0)),    # a mallet hits a resting puck off its centre
    ((0.1, -0.2), (-0.5, 1.5), (0.3, 0.1), (-1.5, -0.5)),   # both moving, a glancing meeting
    ((0.0, 0.0), (1.0, 0.0), (0.0, 0.3), (0.0, 0.0)),       # passing by: no contact
    ((0.0, 0.0), (1.0, 0.0), (-0.2, 0.0), (0.0, 0.0)),      # moving away: no contact
    ((0.0, 0.0), (1.0, 0.0), (0.5, 0.0), (0.0, 0.0)),       # beyond the horizon
])
def test_the_first_contact_is_the_brute_force_one(pp, vp, pm, vm):
    pp, vp, pm, vm = map(np.array, (pp, vp, pm, vm))
    horizon = 0.25
    expected = brute_force_contact(pp, vp, pm, vm, REACH, horizon)
    got = first_contact(pp, vp, pm, vm, REACH, horizon)
    if expected is None:
        assert got is None
    else:
        assert got == pytest.approx(expected, abs=2e-6)


def test_an_overlap_counts_only_while_closing():
    puck, mallet = np.zeros(2), np.array([-0.07, 0.0])  # closer than the radii
    assert first_contact(puck, np.zeros(2), mallet, np.array([1.0, 0.0]), REACH, 0.01) == 0.0
    assert first_contact(puck, np.zeros(2), mallet, np.array([-1.0, 0.0]), REACH, 0.01) is None
    assert first_contact(puck, np.zeros(2), mallet, np.zeros(2), REACH, 0.01) is None


def test_a_contact_reverses_the_relative_normal_speed_by_e_and_widens_the_covariance():
    s = MalletContactSettings(enabled=True, restitution=0.7, friction=0.0, velocity_noise=0.3)
    x = np.array([0.0, 0.0, 0.3, -0.2, 0.5, 0.0])
    p = np.diag([1e-6, 1e-6, 1e-4, 1e-4, 1e-4, 1.0])
    mallet, u = np.array([-0.06, -0.05]), np.array([1.5, 0.5])
    after, cov = apply_contact(x, p, mallet, u, s, 0.03165)
    n = (x[:2] - mallet) / np.hypot(*(x[:2] - mallet))
    t = np.array([-n[1], n[0]])
    before_rel, after_rel = x[2:4] - u, after[2:4] - u
    assert after_rel @ n == pytest.approx(-0.7 * (before_rel @ n))   # Newton's law of restitution
    assert after_rel @ t == pytest.approx(before_rel @ t)            # no friction: tangential kept
    assert np.all(after[[0, 1, 4, 5]] == x[[0, 1, 4, 5]])
    dv = np.hypot(*(after[2:4] - x[2:4]))
    assert np.trace(cov[2:4, 2:4]) >= 2 * (0.3 * dv) ** 2
    assert np.allclose(cov, cov.T) and np.linalg.eigvalsh(cov).min() > 0.0


def test_the_tracks_difference_the_mallets_and_forget_stale_ones():
    tracks = MalletTracks(max_age=0.05)
    tracks.observe("a", 1.00, (0.0, 0.0))
    tracks.observe("a", 1.01, (0.02, -0.01))
    ((name, p, v),) = tracks.at(1.02)
    assert name == "a" and np.allclose(v, [2.0, -1.0]) and np.allclose(p, [0.04, -0.02])
    tracks.observe("a", 1.005, (5.0, 5.0))   # older than the last: ignored
    assert np.allclose(tracks.at(1.01)[0][1], [0.02, -0.01])
    assert tracks.at(1.07) == []              # its last sample is 60 ms old
    tracks.observe("a", 1.20, (0.1, 0.1))     # after a pause: no velocity from the old sample
    assert np.allclose(tracks.at(1.2)[0][2], 0.0)
    tracks.observe("a", 0.5, (0.3, 0.3))      # time jumped back (a simulation restart): taken
    assert np.allclose(tracks.at(0.5)[0][1], [0.3, 0.3])
    tracks.observe("a", 0.51, (np.nan, 0.0))  # not finite: ignored
    assert np.allclose(tracks.at(0.51)[0][1], [0.3, 0.3])
    tracks.observe("a", 0.52, (0.3, 0.3), velocity=(-1.0, 0.5))  # from the joint velocities: taken as given
    ((_, p, v),) = tracks.at(0.53)
    assert np.allclose(v, [-1.0, 0.5]) and np.allclose(p, [0.29, 0.305])


def _unseen_hit(settings: FilterSettings, rng_seed: int = 0):
    """A puck at rest at the origin, seen for 0.5 s; then no frame until 0.9 s while a mallet sweeps it at
    1 m/s (joint states at 100 Hz) off its centre; frames again from 0.9 s. The truth's contact is
    frictionless with restitution 0.7 (the filter's law: 0.8 and friction 0.1, 0.1 m/s and 5 degrees
    apart), then it flies as the model says. Returns the filter, the truth's velocity after the hit and
    the coasts' answers (time, whether the estimate holds a contact)."""
    rng = np.random.default_rng(rng_seed)
    m = model()
    ekf = PuckEKF(m, settings)
    u, start = np.array([1.0, 0.0]), np.array([-0.2, 0.02])
    tc = brute_force_contact(np.zeros(2), np.zeros(2), start, u, REACH, 1.0) + 0.5
    n = -(start + u * (tc - 0.5))
    n /= np.hypot(*n)
    v_after = (1.0 + 0.7) * (u @ n) * n
    times, states = simulate_truth(m, np.array([0.0, 0.0, *v_after, 0.0, 0.0]), 0.6, DT / 10)
    coasted = []
    frames = np.arange(1, 132) / 120.0   # until 1.09 s, the puck 0.8 m out at most
    ticks = np.arange(50, 110) / 100.0
    for t in np.unique(np.round(np.concatenate([frames, ticks]), 9)):
        if np.any(np.isclose(t, ticks, rtol=0.0, atol=1e-9)):
            ekf.observe_mallet("iiwa_front", t, start + u * (t - 0.5))
            coasted.append((t, ekf.coast(t)))
        if np.any(np.isclose(t, frames, rtol=0.0, atol=1e-9)) and not 0.5 < t < 0.9:
            position = np.zeros(2) if t < tc else true_state_at(m, times, states, t - tc)[:2]
            ekf.process(t, [*(position + rng.normal(0.0, 1e-4, 2)), 0.0])
    return ekf, true_state_at(m, times, states, ekf.stamp - tc)[2:4], coasted


def test_a_hit_in_a_dropout_flies_on_in_the_estimate():
    ekf, v_after, coasted = _unseen_hit(SETTINGS)
    assert ekf.stats.mallet_contacts == 1
    before = [c for t, c in coasted if t < 0.62]
    assert before and not any(before)        # nothing to publish before the contact
    assert any(c for t, c in coasted if t < 0.9)
    assert ekf.stats.outliers_rejected == 0 and ekf.stats.reinitialisations == 1  # the first track only
    assert np.hypot(*(ekf.x[2:4] - v_after)) < 0.05


def test_without_the_mallets_the_unseen_hit_costs_a_restart():
    ekf, v_after, coasted = _unseen_hit(replace(SETTINGS, mallet=MalletContactSettings(enabled=False)))
    assert ekf.mallets is None and not any(c for _, c in coasted)
    assert ekf.stats.outliers_rejected >= SETTINGS.max_consecutive_rejections and ekf.stats.reinitialisations == 2


def test_mallets_that_meet_nothing_change_nothing():
    def track(settings):
        ekf = PuckEKF(model(), settings)
        rng = np.random.default_rng(3)
        states = []
        for k in range(1, 120):
            t = k / 120.0
            ekf.observe_mallet("iiwa_back", t, (0.8, -0.3 + 0.1 * t))  # far from the puck's path
            ekf.coast(t)
            ekf.process(t, [-0.4 + 1.2 * t + rng.normal(0, 1e-4), 0.1 + rng.normal(0, 1e-4), 0.0])
            states.append(ekf.x.copy())
        return np.array(states), ekf
    with_mallets, ekf = track(SETTINGS)
    without, _ = track(replace(SETTINGS, mallet=MalletContactSettings(enabled=False)))
    assert ekf.stats.mallet_contacts == 0 and np.array_equal(with_mallets, without)

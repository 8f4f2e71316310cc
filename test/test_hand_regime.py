"""The filter's hand regime (core/estimation/hand_regime.py, used by ekf.py): a hand carrying the puck, as the test
bed's HandCarry moves it (core/puck/real_table.py: a minimum-jerk path, written apart from the filter), is
followed rather than rejected, and the process noise learns nothing from it; a human hit alone does not
start it."""
import numpy as np
import pytest

from air_hockey_agent.core.estimation.ekf import FLAG_REINITIALISED, PuckEKF
from air_hockey_agent.core.estimation.hand_regime import HandSettings
from air_hockey_agent.core.estimation.evaluation import EvaluationTotals, evaluate_stream
from air_hockey_agent.core.puck.real_table import RealTablePuck, TableEffects, carry_from
from air_hockey_agent.tracker_params import load_tracker_params, without_learning
from model_fixtures import session_on_testbed

FRAME = 1.0 / 120.0


def _params(**hand) -> dict:
    """The defaults without learning, ``hand`` overriding ``hand.*`` (e.g. acceleration=0.0)."""
    return {**without_learning(load_tracker_params()), **{"hand." + k: v for k, v in hand.items()}}


def _shot(params: dict, carry):
    """One shot on a calm test bed (the defaults' damping, no rim in reach: a slow hit across the middle),
    a hit at 0.3 s, then ``carry`` (start, time, target) or none: true times and states every 1 ms."""
    table = PuckEKF.from_params(params).model.table
    puck = RealTablePuck(table, TableEffects(damping=params["damping"]), np.random.default_rng(0))
    start = np.array([-0.4, 0.0, 0.0, 0.0, 0.0, 0.0])
    return puck.simulate(start, 5.0, 1e-3, 0.3, np.array([0.4, 0.05]), carry)


def _track(params: dict, states: np.ndarray):
    """Frames of ``states`` (every 1 ms from 0) at 120 Hz with 0.1 mm noise through a filter with ``params``.
    Returns the filter and, per frame, (t, in hand, restarted)."""
    ekf = PuckEKF.from_params(params)
    rng, trace = np.random.default_rng(1), []
    for t in np.arange(0.0, 5.0, FRAME):
        state = states[int(round(t / 1e-3))]
        z = [state[0] + rng.normal(0, 1e-4), state[1] + rng.normal(0, 1e-4), state[4] + rng.normal(0, 0.01)]
        flags = ekf.process(1000.0 + t, z)
        trace.append((t, ekf.in_hand, bool(flags & FLAG_REINITIALISED)))
    return ekf, trace


def _run(hand_acceleration: float, carry):
    """:func:`_shot` tracked by the defaults without learning, the hand's acceleration as given."""
    params = _params(acceleration=hand_acceleration)
    return _track(params, _shot(params, carry)[1])


def _first(trace, since: float, what: int) -> float:
    """The first time at or after ``since`` [s] whose trace entry has ``what`` (1: in hand, 2: restarted)."""
    return next(entry[0] for entry in trace if entry[0] >= since and entry[what])


def test_a_carry_starts_the_hand_regime_a_hit_alone_does_not_and_it_ends_once_the_puck_is_held_still():
    """A hit (one restart) leaves the regime off; a hand carrying the puck 0.6 m in 1.2 s from 2.0 s starts it
    and the filter restarts far less often than without it; it ends within a second of the puck held still."""
    carry = (2.0, 1.2, np.array([0.3, 0.25, 1.0]))
    ekf, trace = _run(3.0, carry)
    assert not any(hand for t, hand, _ in trace if t < 2.0)
    assert any(hand for t, hand, _ in trace if 2.0 <= t <= 3.2)
    assert not any(hand for t, hand, _ in trace if t > 4.2)
    assert ekf.stats.hand_regimes >= 1 and ekf.stats.hand_frames > 0
    _, without = _run(0.0, carry)
    restarts = sum(r for t, _, r in trace if t >= 2.0)
    restarts_without = sum(r for t, _, r in without if t >= 2.0)
    assert restarts_without >= 2 * restarts + 2
    _, hit_only = _run(3.0, None)
    assert not any(hand for _, hand, _ in hit_only)


def test_a_hand_that_stops_the_moving_puck_starts_the_regime_at_the_first_restart():
    """The hand takes the puck at 2.0 s while it slides at about 0.37 m/s: the restart that follows keeps
    under stop_fraction of the speed the model predicted (no rim in reach), so the regime starts with it,
    not with the second restart as it does with stop_fraction 0."""
    carry = (2.0, 1.2, np.array([0.3, 0.25, 1.0]))
    params = _params()
    times, states = _shot(params, carry)
    assert 0.3 < np.hypot(*states[1999, 2:4]) < 0.45  # the puck slides when the hand takes it
    _, trace = _track(params, states)
    grab = _first(trace, 2.0, 2)
    assert grab < 2.1 and _first(trace, 2.0, 1) == grab
    _, slow = _track(_params(stop_fraction=0.0), states)
    assert _first(slow, 2.0, 2) == grab and _first(slow, 2.0, 1) > grab


def test_a_restart_soon_after_the_regime_ended_starts_it_again():
    """A hand carries the puck, holds it until the regime has ended (at e), then moves it again: if it does
    so within hand.window of e (a hand's acceleration passing zero mid-carry ends the regime too), the
    first restart starts the regime again; later than that, it takes the second restart as ever."""
    params = _params()
    times, states = _shot(params, (2.0, 0.8, np.array([0.3, 0.25, 1.0])))
    _, trace = _track(params, states)
    end = next(t for (t, hand, _), (_, before, _) in zip(trace[1:], trace) if before and not hand and t > 2.0)
    for delay, at_once in ((0.1, True), (params["hand.window"] + 0.3, False)):
        again = states.copy()
        carry_from(times, again, int(round((end + delay) / 1e-3)), 0.8, np.array([-0.3, -0.2, 0.0]))
        _, trace = _track(params, again)
        restart = _first(trace, end + delay, 2)
        assert bool(_first(trace, end + delay, 1) == restart) is at_once, (delay, restart)


def test_a_hit_soon_after_the_regime_starts_none_and_the_flight_is_the_models():
    """A hand carries the puck from 2.0 s for 0.8 s and holds it until the regime has ended (at e); 0.15 s
    later (a human placing the puck and hitting it, the strategy test's launch after a reset) the puck is
    hit at 1.5 m/s: the restart gains more than hand.hit_speed, so it starts no regime and the flight is
    filtered with the model's noise. With hit_speed 0 it counts as a hand moving the puck on (within
    hand.window of e) and the regime runs into the flight."""
    params = _params()
    times, states = _shot(params, (2.0, 0.8, np.array([0.3, 0.25, 1.0])))
    _, trace = _track(params, states)
    end = next(t for (t, hand, _), (_, before, _) in zip(trace[1:], trace) if before and not hand and t > 2.0)
    at = int(round((end + 0.15) / 1e-3))
    puck = RealTablePuck(PuckEKF.from_params(params).model.table, TableEffects(damping=params["damping"]),
                         np.random.default_rng(2))
    _, flight = puck.simulate(states[at], 5.0 - at * 1e-3, 1e-3, 1e-3, np.array([-1.4, -0.5]))
    states = np.concatenate([states[:at], flight])
    _, trace = _track(params, states)
    hit = _first(trace, end + 0.15, 2)
    assert hit < end + 0.2 and not any(hand for t, hand, _ in trace if t >= end)
    _, old = _track(_params(hit_speed=0.0), states)
    assert _first(old, end + 0.15, 1) == hit


def test_the_hands_noise_is_white_noise_acceleration_of_its_density():
    """Q of the hand over dt: density a^2 dt0 times (dt^3/3, dt^2/2, dt) on each (value, rate) pair, zero
    elsewhere; over two half steps the covariance a constant-velocity model accumulates equals one step's."""
    hand = HandSettings(acceleration=3.0, spin_acceleration=10.0)
    q = hand.noise(FRAME, FRAME)
    assert q[2, 2] == pytest.approx((3.0 * FRAME) ** 2) and q[5, 5] == pytest.approx((10.0 * FRAME) ** 2)
    assert q[0, 2] == pytest.approx(9.0 * FRAME * FRAME ** 2 / 2) and q[0, 1] == 0.0 and q[0, 3] == 0.0
    f = np.eye(6)
    f[0, 2] = f[1, 3] = f[4, 5] = FRAME / 2
    half = hand.noise(FRAME / 2, FRAME)
    assert np.allclose(f @ half @ f.T + half, q, rtol=1e-12, atol=0.0)
    assert not HandSettings().enabled


def test_on_a_test_bed_whose_shots_end_in_a_carry_the_filter_stays_calibrated():
    """Eight test-bed shots, each ending in a hand's carry of 1-2 s (testbed.carry_time): without the hand
    regime the carries reject over 5 % of the poses, restart the filter more than once a second and drive
    the learned flight noise over ten times the configured; with it under 2 %, 0.4 per second (issue #13's
    targets: 2 % and 0.5; measured 1.6 % and 0.31) and 2 times (as on the same shots without carries:
    1.3), and the flight NIS median under 2.6. Without carries it
    never starts and changes nothing."""
    def run(acceleration: float, carry_time):
        params = {**load_tracker_params(), "hand.acceleration": acceleration}
        ekf = PuckEKF.from_params(params)
        frames = [(f.stamp, f.measurement) for f in session_on_testbed(ekf, 8, 5, testbed={"carry_time": carry_time})]
        totals = EvaluationTotals((1.0,), rest_speed=params["regime_rest_speed"])
        evaluate_stream(ekf, frames, totals)
        return totals.summary(), ekf.process_noise_learning.scales["flight"].scale
    off, off_scale = run(0.0, [1.0, 2.0])
    on, on_scale = run(3.0, [1.0, 2.0])
    assert off["rejected_fraction"] > 0.05 and off["reinit_per_s"] > 1.0 and off_scale > 10.0
    assert on["rejected_fraction"] < 0.02 and on["reinit_per_s"] < 0.4 and on_scale < 2.0
    assert on["nis_by_regime"]["flight"]["median"] < 2.6 and on["hand"]["regimes"] >= 4
    calm, _ = run(3.0, [0.0, 0.0])
    calm_off, _ = run(0.0, [0.0, 0.0])
    assert calm["hand"] == {"regimes": 0, "frames": 0} and calm == calm_off


def _regime(**settings):
    from air_hockey_agent.core.estimation.hand_regime import HandRegime
    return HandRegime(HandSettings(**{"acceleration": 3.0, "window": 0.5, "calm_time": 0.2, "calm_acceleration": 1.0,
                                      "stop_fraction": 0.25, "hit_speed": 1.0, **settings}))


def test_the_regime_starts_at_a_steady_stop_or_a_second_restart_soon_and_a_hit_starts_none():
    regime = _regime()
    assert not regime.after_restart(1.0, 0.8, 0.1, steady=False)  # slow but no constant velocity: a reversal
    assert regime.after_restart(1.3, 0.8, 0.1, steady=True) and regime.active  # within 0.5 s of 1.0
    stop = _regime()
    assert stop.after_restart(5.0, 0.8, 0.1, steady=True) and stop.active  # kept 12 % of the predicted speed
    late = _regime()
    assert not late.after_restart(1.0, 0.8, 0.5, steady=True) and not late.after_restart(1.6, 0.8, 0.5, True)
    hit = _regime()
    assert not hit.after_restart(1.0, 0.0, 0.0, steady=True) and not hit.after_restart(1.2, 0.0, 3.0, steady=True)
    assert not hit.active  # the second restart, 0.2 s after the first, gained 3 m/s: a hit
    assert _regime(acceleration=0.0).after_restart(5.0, 0.8, 0.1, steady=True) is False  # switched off


def test_the_regime_ends_after_two_calm_windows_or_at_a_hit():
    regime = _regime()
    regime.after_restart(0.0, 0.8, 0.0, steady=True)
    t = 0.0
    for _ in range(60):  # 0.5 s of updates adding 3 m/s^2: never calm
        t += 1 / 120
        regime.watch(t, 3.0 / 120, 0.0)
    assert regime.active
    ended = None
    for _ in range(120):  # then none: calm once the last 0.2 s hold under 1 m/s^2 (7 of the 3 m/s^2 updates,
        t += 1 / 120      # from 0.5 + 0.2 - 7/120 s on), ended calm_time later
        regime.watch(t, 0.0, 0.0)
        if ended is None and not regime.active:
            ended = t
    calm = 0.5 + 0.2 - 7 / 120
    assert ended is not None and calm + 0.2 <= ended <= calm + 0.2 + 1.5 / 120
    hit = _regime()
    hit.after_restart(0.0, 0.8, 0.0, steady=True)
    assert not hit.after_restart(0.3, 0.0, 2.5, steady=True) and not hit.active


def test_a_restart_under_way_forgets_the_velocity_added_before_it():
    """The filter's restart begins a new track: what the updates added before it does not count toward
    the regime's calm test (as the filter's reset cleared it before the regime had a module of its own)."""
    regime = _regime(calm_time=0.2)
    regime.after_restart(0.0, 0.8, 0.0, steady=True)
    for k in range(1, 25):  # 0.2 s adding 6 m/s^2
        regime.watch(k / 120, 6.0 / 120, 0.0)
    regime.after_restart(0.21, 0.5, 0.4, steady=True)  # goes on, the corrections dropped
    assert regime.active and regime._corrections == []

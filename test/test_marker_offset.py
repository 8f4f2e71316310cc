"""The mocap pivot off the disc's centre (core/estimation/marker_offset.py): the correction, the online
estimate from free-flight windows, and the filter on a test bed whose markers sit off the centre (the
mocap stand-in's offset, core/estimation/synthetic.py, written apart from the estimate)."""
import math

import numpy as np
import pytest

from air_hockey_agent.core.estimation.ekf import FLAG_OUTLIER_REJECTED, PuckEKF
from air_hockey_agent.core.estimation.evaluation import EvaluationTotals, evaluate_stream, prediction_series
from air_hockey_agent.core.estimation.marker_offset import centre_of, centres_of, offset_sensitivity, pivot_shift
from air_hockey_agent.core.estimation.flight_adaptation import AccelerationAdaptation, AccelerationSettings, quadratic_fit
from air_hockey_agent.core.puck.model import PuckParams
from air_hockey_agent.tracker_params import load_tracker_params
from model_fixtures import session_on_testbed

TRUE_OFFSET = (0.0015, -0.001)  # [m]


def window(rng, offset, spin, noise=3e-4, seconds=0.5):
    """A free-flight window's measured poses: a decelerating straight path, the pivot ``offset`` turning
    at ``spin`` [rad/s], Gaussian position noise [m]."""
    t = np.arange(0.0, seconds, 1.0 / 120.0)
    v, a = rng.uniform(-1.5, 1.5, 2), rng.uniform(-0.2, 0.2, 2)
    theta = rng.uniform(-math.pi, math.pi) + spin * t
    shift = np.array([pivot_shift(th, offset) for th in theta])
    xy = v * t[:, None] + 0.5 * a * t[:, None] ** 2 + shift + rng.normal(0.0, noise, (len(t), 2))
    return t, np.column_stack([xy, np.angle(np.exp(1j * theta))])


def test_the_centre_is_the_pivot_taken_back_by_the_offset():
    z = np.array([0.3, -0.2, 2.5])
    dx, dy = pivot_shift(2.5, TRUE_OFFSET)
    assert math.hypot(dx, dy) == pytest.approx(math.hypot(*TRUE_OFFSET))
    assert np.allclose(centre_of(z + [dx, dy, 0.0], TRUE_OFFSET), z)
    assert np.allclose(centre_of(z, (0.0, 0.0)), z)


def test_the_offset_is_found_from_spinning_windows_and_a_puck_that_does_not_turn_tells_nothing():
    """Forty windows of pucks spinning at 3-15 rad/s (either way) with 0.3 mm noise: the offset within
    0.1 mm and its std below that; two hundred windows without spin leave the prior's std."""
    rng = np.random.default_rng(4)
    learned = offset_learning()
    for _ in range(40):
        assert learned.observe_offset(*window(rng, TRUE_OFFSET, rng.choice([-1, 1]) * rng.uniform(3.0, 15.0)))
    report = learned.offset_report()
    assert learned.offset == pytest.approx(TRUE_OFFSET, abs=1e-4) and max(report["std"]) < 1e-4
    still = offset_learning()
    for _ in range(200):
        still.observe_offset(*window(rng, TRUE_OFFSET, 0.0))
    assert min(still.offset_report()["std"]) > 0.9e-3 and max(map(abs, still.offset)) < 1e-4
    assert report["windows"] == 40 and report["value"] == list(learned.offset)


def offset_learning(prior_std: float = 0.001) -> AccelerationAdaptation:
    """The flight learning with the offset learned (prior 0, ``prior_std`` [m]) and the configured defaults'
    other settings."""
    params = {**load_tracker_params(), "acceleration_adaptation.marker_offset_prior_std": prior_std}
    return AccelerationAdaptation(PuckParams.from_params(params), AccelerationSettings.from_params(params), (0.0, 0.0))


def test_a_windows_acceleration_fitted_with_a_wrong_offset_is_off_by_the_sensitivity():
    """A puck turning at 7 rad/s on a parabola: its positions taken back by o' instead of the pivot's o
    give a fitted acceleration off by exactly M (o - o') (the fit is linear in the positions)."""
    t = np.arange(0.0, 0.5, 1.0 / 120.0)
    theta = 0.3 + 7.0 * t
    centre = np.column_stack([0.1 + 1.2 * t + 0.025 * t * t, -0.2 + 0.4 * t])
    pivots = np.column_stack([centre + np.array([pivot_shift(th, TRUE_OFFSET) for th in theta]), theta])
    assumed = (0.0005, 0.0003)
    fitted = {o: quadratic_fit(list(t), centres_of(pivots, o))[0] for o in (assumed, TRUE_OFFSET)}
    error = fitted[assumed] - fitted[TRUE_OFFSET]
    expected = offset_sensitivity(t, theta) @ (np.array(TRUE_OFFSET) - assumed)
    assert np.allclose(error, expected, atol=1e-9) and np.linalg.norm(expected) > 0.01


def test_windows_learned_before_the_offset_was_known_are_put_right_once_it_is():
    """Thirty windows of a puck spinning at 3-12 rad/s on a table with g = (0, 0.06) m/s^2, the configured
    damping and no surface friction, the pivot 2 mm off and 0.5 mm noise, each fitted with the offset
    known so far (0 at first): every window is learned from and the flight law ends within 5 mm/s^2,
    0.01 1/s and 0.01 m/s^2 of the truth. (Learned apart, the first windows' circling stayed in the
    flight law as an acceleration and it refused half of the later windows: g (0.003, 0.050), surface
    friction 0.032.)"""
    rng = np.random.default_rng(0)
    offset, g = (0.002, -0.001), np.array([0.0, 0.06])
    learning = offset_learning()
    damping = learning.flight_law()["damping"]
    t = np.arange(0.0, 0.5, 1.0 / 120.0)
    tau = (t - 0.25)[:, None]  # about the window's middle, whose velocity the flight law takes
    for _ in range(30):
        v, spin = rng.uniform(0.5, 1.5, 2) * rng.choice([-1, 1], 2), rng.choice([-1, 1]) * rng.uniform(3.0, 12.0)
        theta = rng.uniform(-math.pi, math.pi) + spin * t
        centre = v * tau + 0.5 * (g - damping * v) * tau ** 2
        pivots = np.column_stack([centre + np.array([pivot_shift(th, offset) for th in theta])
                                  + rng.normal(0.0, 5e-4, (len(t), 2)), np.angle(np.exp(1j * theta))])
        fit = quadratic_fit(list(t), centres_of(pivots, learning.offset))
        if learning.observe(*fit, sensitivity=offset_sensitivity(t, pivots[:, 2])):  # as TableLearning does
            learning.observe_offset(t, pivots)
    law = learning.flight_law()
    assert learning.windows == 30
    assert learning.offset == pytest.approx(offset, abs=1e-4)
    assert law["table_acceleration"] == pytest.approx(tuple(g), abs=0.005)
    assert law["damping"] == pytest.approx(damping, abs=0.01) and law["friction_surface"] < 0.01


def test_the_filter_learns_the_markers_offset_on_the_test_bed_and_predicts_better_for_it():
    """A test-bed session whose mocap pivot sits (1.5, -1.0) mm off the centre: the filter learns it within
    0.2 mm and predicts better at 1.0 s than with the offset held at the configured 0; on the same shots
    with the pivot at the centre it learns zero within 0.2 mm."""
    params = load_tracker_params()
    held = {**params, "acceleration_adaptation.marker_offset_prior_std": 0.0}
    medians = {}
    for name, p in (("learned", params), ("held", held)):
        ekf = PuckEKF.from_params(p)
        frames = [(f.stamp, f.measurement) for f in session_on_testbed(ekf, 8, 3, marker_offset_x=TRUE_OFFSET[0],
                                                                        marker_offset_y=TRUE_OFFSET[1])]
        totals = EvaluationTotals((1.0,))
        evaluate_stream(ekf, frames, totals)
        medians[name] = totals.summary()["horizons"]["1.0"]["median_m"]
        if name == "learned":
            assert ekf.learning.marker_offset == pytest.approx(TRUE_OFFSET, abs=2e-4)
            assert ekf.learning.report()["marker_offset"]["windows"] > 20
        else:
            assert ekf.learning.report()["marker_offset"] is None and ekf.learning.marker_offset == (0.0, 0.0)
    assert medians["learned"] < 0.9 * medians["held"]
    ekf = PuckEKF.from_params(params)
    evaluate_stream(ekf, [(f.stamp, f.measurement) for f in session_on_testbed(ekf, 8, 3)], EvaluationTotals((1.0,)))
    assert max(map(abs, ekf.learning.marker_offset)) < 2e-4


def test_predictions_are_compared_with_what_the_mocap_measures_the_pivot_at_the_predicted_angle():
    """A puck spinning in place at 5 rad/s, its pivot 2 mm off, measured without noise: with the offset
    configured the evaluation's errors at 0.5 s are those of the angle's prediction (well under 0.1 mm),
    as the prediction says the mocap measures the pivot; untold, the filter follows the pivot's circle
    (10 mm/s) and errs by millimetres."""
    from air_hockey_agent.tracker_params import without_learning
    offset = (0.002, 0.0)
    frames = []
    for k in range(600):
        t = 100.0 + k / 120.0
        theta = math.remainder(0.3 + 5.0 * (t - 100.0), 2.0 * math.pi)
        dx, dy = pivot_shift(theta, offset)
        frames.append((t, np.array([0.2 + dx, -0.1 + dy, theta])))
    medians = {}
    for name, configured in (("told", list(offset)), ("untold", [0.0, 0.0])):
        ekf = PuckEKF.from_params({**without_learning(load_tracker_params()), "marker_offset": configured})
        totals = EvaluationTotals((0.5,))
        evaluate_stream(ekf, frames, totals)
        medians[name] = totals.summary()["horizons"]["0.5"]["median_m"]
    assert medians["told"] < 1e-4 and medians["untold"] > 0.002
    told = PuckEKF.from_params({**without_learning(load_tracker_params()), "marker_offset": list(offset)})
    series = prediction_series(told, frames, 0.5)  # plot's: measured positions at the centre, as the estimates
    assert np.allclose(series.measured[:, :2], [0.2, -0.1], atol=1e-12)
    assert np.nanmax(np.abs(series.predicted[:, :2] - [0.2, -0.1])) < 1e-4


def test_frames_the_gate_rejects_do_not_cut_the_windows_the_offset_is_learned_from():
    """A puck flying 2.5 s at 0.6 m/s, spinning at 5 rad/s, its pivot 2 mm off, with a 5 cm marker glitch
    every 40 frames (a third of a second, shorter than a 0.5 s flight window): the gate rejects the
    glitches (and, until the offset is learned, some of the pivot's circling), and the windows run on
    past them (a rejected frame gives them nothing but ends nothing), so the offset is learned within
    0.3 mm from 4 windows. Had each rejection ended the window (as before), no window would have reached
    its end and the offset would have stayed at the configured 0."""
    params = load_tracker_params()
    ekf = PuckEKF.from_params(params)
    d, offset, spin = params["damping"], (0.002, 0.0), 6.0
    glitches = rejected = 0
    for k in range(300):
        t = 50.0 + k / 120.0
        s = t - 50.0
        x = -0.9 + 0.6 * (1.0 - math.exp(-d * s)) / d
        theta = math.remainder(0.4 + spin * s, 2.0 * math.pi)
        dx, dy = pivot_shift(theta, offset)
        z = np.array([x + dx, 0.1 + dy, theta]) + np.r_[np.random.default_rng(k).normal(0.0, 1e-4, 2), 0.0]
        if k % 40 == 39:
            z[1] += 0.05
            glitches += 1
        rejected += bool(ekf.process(t, z) & FLAG_OUTLIER_REJECTED)
    assert glitches == 7 and rejected >= glitches
    assert ekf.learning.report()["marker_offset"]["windows"] >= 3
    assert ekf.learning.marker_offset == pytest.approx(offset, abs=3e-4)

"""The mocap pivot off the disc's centre (core/estimation/marker_offset.py): the correction, the online
estimate from free-flight windows, and the filter on a test bed whose markers sit off the centre (the
mocap stand-in's offset, core/estimation/synthetic.py, written apart from the estimate)."""
import math

import numpy as np
import pytest

from air_hockey_agent.core.estimation.ekf import FLAG_OUTLIER_REJECTED, PuckEKF
from air_hockey_agent.core.estimation.evaluation import EvaluationTotals, evaluate_stream, prediction_series
from air_hockey_agent.core.estimation.marker_offset import MarkerOffsetAdaptation, centre_of, pivot_shift
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
    learned = MarkerOffsetAdaptation((0.0, 0.0), 0.001)
    for _ in range(40):
        assert learned.observe(*window(rng, TRUE_OFFSET, rng.choice([-1, 1]) * rng.uniform(3.0, 15.0)))
    assert learned.value == pytest.approx(TRUE_OFFSET, abs=1e-4) and max(learned.std) < 1e-4
    still = MarkerOffsetAdaptation((0.0, 0.0), 0.001)
    for _ in range(200):
        still.observe(*window(rng, TRUE_OFFSET, 0.0))
    assert min(still.std) > 0.9e-3 and max(map(abs, still.value)) < 1e-4
    assert learned.report() == {"windows": 40, "value": list(learned.value), "std": list(learned.std)}


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
            assert ekf.learning.offset is None and ekf.learning.marker_offset == (0.0, 0.0)
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

"""Puck EKF against simulated ground truth: tracking, lost frames, outliers, re-initialisation."""
import numpy as np
import pytest

from air_hockey_agent.core.estimation.ekf import (FLAG_MEASUREMENT_USED, FLAG_OUTLIER_REJECTED, FLAG_PREDICTED,
                                       FLAG_REINITIALISED, FilterSettings, PuckEKF, check_covariance)
from air_hockey_agent.core.estimation.synthetic import MocapImperfections, mocap_stream, simulate_truth, true_state_at
from model_fixtures import DT, Q, model

SETTINGS = FilterSettings(dt=DT, q=Q, r=np.diag([1e-8, 1e-8, 1e-4]), p0=np.diag([1e-6, 1e-6, 1.0, 1.0, 1e-4, 100.0]),
                          gate_threshold=16.27, max_consecutive_rejections=3, outside_table_margin=0.05,
                          max_prediction_gap=2.0)
START = np.array([-0.5, 0.1, 2.5, 1.7, 0.0, 8.0])  # several rim impacts in 4 s


def run(noise, seed=0, duration=4.0, start=START):
    m = model()
    times, states = simulate_truth(m, start, duration, DT / 10)
    frames = mocap_stream(m, times, states, 120.0, noise, np.random.default_rng(seed))
    ekf = PuckEKF(m, SETTINGS)
    errors, flags = [], []
    for stamp, z in frames:
        flags.append(ekf.process(stamp, z))
        if ekf.initialised:
            errors.append(ekf.x - true_state_at(m, times, states, stamp))
    return ekf, np.array(errors), flags


def test_tracks_ground_truth_through_rim_impacts():
    ekf, err, _ = run(MocapImperfections())
    assert ekf.stats.outliers_rejected == 0 and ekf.stats.reinitialisations == 1
    assert np.median(np.hypot(err[:, 0], err[:, 1])) < 2e-4            # [m], noise is 1e-4 per axis
    assert np.percentile(np.hypot(err[20:, 2], err[20:, 3]), 95) < 0.02  # [m/s] after convergence


def test_lost_frames_are_bridged_by_prediction():
    ekf, err, flags = run(MocapImperfections(lost_rate=0.2))
    assert ekf.stats.lost_frames > 50
    assert sum(f & FLAG_PREDICTED > 0 for f in flags) == ekf.stats.lost_frames
    assert np.max(np.hypot(err[:, 0], err[:, 1])) < 5e-3


def test_glitches_are_rejected_and_do_not_disturb_the_estimate():
    clean_ekf, clean_err, _ = run(MocapImperfections(), seed=4)
    ekf, err, flags = run(MocapImperfections(glitch_rate=0.02, glitch_size=0.1), seed=4)
    assert ekf.stats.outliers_rejected >= 5
    assert ekf.stats.reinitialisations == 1
    assert np.median(np.hypot(err[:, 0], err[:, 1])) < 2 * np.median(np.hypot(clean_err[:, 0], clean_err[:, 1]))


def test_unmodelled_hit_reinitialises_after_a_run_of_rejections():
    m = model()
    ekf = PuckEKF(m, SETTINGS)
    t = 0.0
    for k in range(30):  # moving +x at 1 m/s
        t = k * DT
        ekf.process(t, [1.0 * t, 0.0, 0.0])
    hit_flags = []
    for k in range(1, 8):  # suddenly moving -y at 2 m/s (a mallet hit)
        hit_flags.append(ekf.process(t + k * DT, [1.0 * t, -2.0 * k * DT, 0.0]))
    assert hit_flags[0] & FLAG_OUTLIER_REJECTED
    assert any(f & FLAG_REINITIALISED for f in hit_flags[:4])
    assert ekf.x[3] == pytest.approx(-2.0, abs=0.05) and abs(ekf.x[2]) < 0.05


def test_covariance_grows_in_prediction_and_shrinks_on_update():
    ekf = PuckEKF(model(), SETTINGS)
    ekf.process(0.0, [0.0, 0.0, 0.0])
    ekf.process(DT, [0.01, 0.0, 0.0])
    before = np.trace(ekf.P[:2, :2])
    ekf.predict_to(2 * DT)
    predicted = np.trace(ekf.P[:2, :2])
    ekf.update(np.array([0.02, 0.0, 0.0]))
    assert before < predicted and np.trace(ekf.P[:2, :2]) < predicted


def test_angle_innovation_is_wrapped():
    ekf = PuckEKF(model(), SETTINGS)
    ekf.reset([0.0, 0.0, 0.0, 0.0, np.pi - 0.01, 0.0], stamp=0.0)
    y, _, _ = ekf.innovation(np.array([0.0, 0.0, -np.pi + 0.01]))
    assert y[2] == pytest.approx(0.02)


def test_repeated_and_out_of_order_frames_are_ignored():
    ekf = PuckEKF(model(), SETTINGS)
    ekf.process(0.0, [0.0, 0.0, 0.0])
    ekf.process(DT, [0.01, 0.0, 0.0])
    state = ekf.x.copy()
    assert ekf.process(DT, [0.5, 0.0, 0.0]) == 0
    assert ekf.process(0.5 * DT, [0.5, 0.0, 0.0]) == 0
    assert np.array_equal(ekf.x, state) and ekf.stats.repeated_frames == 2


def test_measurement_far_outside_the_table_is_dropped():
    ekf = PuckEKF(model(), SETTINGS)
    ekf.process(0.0, [0.0, 0.0, 0.0])
    ekf.process(DT, [0.01, 0.0, 0.0])
    assert ekf.process(2 * DT, [5.0, 0.0, 0.0]) & FLAG_OUTLIER_REJECTED
    assert ekf.x[0] < 0.1


@pytest.mark.parametrize("matrix, message", [(np.diag([1.0, -1.0, 1.0]), "not positive definite"),
                                             (np.array([[1, 2, 0], [0, 1, 0], [0, 0, 1.0]]), "not symmetric"),
                                             (np.eye(2), "must be 3x3")])
def test_invalid_covariances_are_refused(matrix, message):
    with pytest.raises(ValueError, match=message):
        check_covariance(matrix, 3, "R")


def test_state_set_without_a_time_holds_at_the_next_frame():
    """Reset to a given state with no stamp (the node's reset service with a zero header stamp): the
    next live frame, however late its stamp, is fused into that state instead of restarting the filter."""
    ekf = PuckEKF(model(), SETTINGS)
    ekf.reset([0.1, 0.2, 0.0, 0.0, 0.0, 0.0])
    flags = ekf.process(1234.5, [0.1001, 0.2, 0.0])
    assert flags == FLAG_MEASUREMENT_USED and ekf.stamp == 1234.5
    assert ekf.stats.reinitialisations == 0 and ekf.x[0] == pytest.approx(0.1001, abs=5e-5)


def test_time_jumping_back_restarts_the_filter():
    """A looping replay or a restarted simulation sends old stamps again: the filter starts over
    instead of ignoring every frame as a repeat."""
    ekf = PuckEKF(model(), SETTINGS)
    for k in range(10):
        ekf.process(100.0 + k * DT, [0.01 * k, 0.0, 0.0])
    ekf.process(50.0, [0.3, 0.2, 0.0])
    flags = ekf.process(50.0 + DT, [0.301, 0.2, 0.0])
    assert flags & FLAG_REINITIALISED and ekf.stamp == pytest.approx(50.0 + DT)
    assert ekf.x[0] == pytest.approx(0.301)

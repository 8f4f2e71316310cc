"""The unscented, minimum-error-entropy and multiple-model filters (core/estimation/ukf.py, imm.py, issue
#13 item 2) against independent references: the exact linear case, the Kalman update and the EKF they
must reduce to, a heavy-tailed error and a hit they must handle, and ground truth through rim impacts."""
from dataclasses import replace

import numpy as np
import pytest

from air_hockey_agent.core.estimation.ekf import FilterSettings, PuckEKF
from air_hockey_agent.core.estimation.synthetic import MocapImperfections, mocap_stream, simulate_truth, true_state_at
from air_hockey_agent.core.estimation.imm import MODES, PuckIMM
from air_hockey_agent.core.estimation.ukf import PuckMEEUKF, PuckUKF
from air_hockey_agent.params import ParameterValueError
from air_hockey_agent.tracker_params import load_tracker_params
from model_fixtures import DT, Q, model

SETTINGS = FilterSettings(dt=DT, q=Q, r=np.diag([1e-8, 1e-8, 1e-4]), p0=np.diag([1e-6, 1e-6, 1.0, 1.0, 1e-4, 100.0]),
                          gate_threshold=13.82, max_consecutive_rejections=3, outside_table_margin=0.05,
                          max_prediction_gap=2.0)
P = np.diag([1e-7, 2e-7, 1e-3, 2e-3, 1e-4, 1e-2])
P[0, 2] = P[2, 0] = 1e-6


def filters(kind, **settings):
    f = kind(model(friction_surface=0.0), replace(SETTINGS, **settings))
    f.reset([0.0, 0.1, 1.0, 0.5, 0.3, 2.0], 0.0)
    f.P = P.copy()
    return f


def test_on_a_linear_step_the_unscented_prediction_is_the_kalman_one():
    # without surface friction and away from the rims one model step is linear: sigma points are exact
    ekf, ukf = filters(PuckEKF), filters(PuckUKF)
    for f in (ekf, ukf):
        f.predict_to(DT)
    assert ukf.x == pytest.approx(ekf.x, abs=1e-12)
    assert np.abs(ukf.P - ekf.P).max() < 1e-12 * np.abs(ekf.P).max()


def test_sigma_points_straddling_a_rim_widen_the_velocity_spread():
    # a puck 3 mm short of the right rim: the mean (2.5 mm this step) misses it, sigma points do not
    state = [0.0, model().table.y_limit - 0.003, 0.0, 0.3, 0.0, 0.0]
    ekf, ukf = filters(PuckEKF), filters(PuckUKF)
    for f in (ekf, ukf):
        f.reset(state, 0.0)
        f.P = P.copy()
        f.predict_to(DT)
    assert ukf.P[3, 3] > 1.5 * ekf.P[3, 3]


def test_mee_update_with_a_wide_kernel_and_only_the_fiducial_point_is_the_kalman_update():
    ekf, mee = filters(PuckEKF), filters(PuckMEEUKF, mee_kernel=1e6, mee_fiducial=1.0)
    z = np.array([0.0003, 0.1002, 0.31])
    for f in (ekf, mee):
        f.update(z)
    assert mee.x == pytest.approx(ekf.x, abs=1e-9)
    assert np.abs(mee.P - ekf.P).max() < 1e-9 * np.abs(ekf.P).max()


def test_mee_update_resists_an_impulsive_error_the_kalman_update_follows():
    # a converged track (position prior tighter than the marker noise) and a marker error of 3.5 std,
    # inside the 2-dof gate (13.82) but far in the Gaussian's tail
    ekf, mee = filters(PuckEKF), filters(PuckMEEUKF)
    tight = P.copy()
    tight[0, 0] = tight[1, 1] = 1e-9
    tight[0, 2] = tight[2, 0] = 0.0
    sigma = np.sqrt(tight[0, 0] + SETTINGS.r[0, 0])
    z = np.array([3.5 * sigma, 0.1, 0.3])
    for f in (ekf, mee):
        f.P = tight.copy()
        f.update(z)
    assert abs(mee.x[0]) < 0.8 * abs(ekf.x[0])


@pytest.mark.parametrize("kind", [PuckUKF, PuckMEEUKF, PuckIMM])
def test_tracks_ground_truth_through_rim_impacts(kind):
    m = model()
    start = np.array([-0.5, 0.1, 2.5, 1.7, 0.0, 8.0])
    times, states = simulate_truth(m, start, 4.0, DT / 10)
    # SETTINGS' R is the marker noise alone: no stamp jitter
    frames = mocap_stream(m, times, states, 120.0, MocapImperfections(jitter_std=0.0), np.random.default_rng(0))
    f = kind(m, SETTINGS)
    errors = []
    for stamp, z in frames:
        f.process(stamp, z)
        if f.initialised:
            errors.append(f.x - true_state_at(m, times, states, stamp))
    err = np.array(errors)
    assert f.stats.reinitialisations == 1 and f.stats.outliers_rejected <= 2
    assert np.median(np.hypot(err[:, 0], err[:, 1])) < 2e-4            # [m], noise is 1e-4 per axis
    assert np.percentile(np.hypot(err[20:, 2], err[20:, 3]), 95) < 0.02  # [m/s] after convergence



@pytest.mark.parametrize("kind", [PuckEKF, PuckUKF, PuckMEEUKF, PuckIMM])
def test_a_dropout_is_bridged_by_the_fast_prediction_and_the_track_goes_on(kind):
    """0.3 s without frames across a rim impact (longer than one step: the fast prediction, and for the IMM
    its mixture's, after which the modes restart from it at the mixed probabilities): the first frame after
    the gap is fused, not a restart, and the estimate stays on the truth."""
    m = model()
    start = np.array([-0.5, 0.1, 2.5, 1.7, 0.0, 8.0])
    times, states = simulate_truth(m, start, 2.0, DT / 10)
    frames = mocap_stream(m, times, states, 120.0, MocapImperfections(jitter_std=0.0), np.random.default_rng(1))
    frames = [(t, z) for t, z in frames if not 0.7 < t < 1.0]  # the puck meets a rim at 0.76 s
    f = kind(m, SETTINGS)
    errors = []
    for stamp, z in frames:
        f.process(stamp, z)
        if stamp > 1.0:
            errors.append(np.hypot(*(f.x[:2] - true_state_at(m, times, states, stamp)[:2])))
    assert f.stats.reinitialisations == 1 and f.stats.outliers_rejected <= 2
    assert errors[0] < 1e-3 and np.median(errors) < 2e-4  # [m]
    if kind is PuckIMM:
        assert f.mode_probabilities.sum() == pytest.approx(1.0)

def test_the_filter_parameter_selects_the_estimator_and_refuses_unknown_ones():
    tracker = load_tracker_params()
    assert type(PuckEKF.from_params(tracker)) is PuckEKF  # config/tracker.yaml: the EKF
    assert type(PuckEKF.from_params({**tracker, "filter": "ukf"})) is PuckUKF
    assert type(PuckEKF.from_params({**tracker, "filter": "mee_ukf"})) is PuckMEEUKF
    assert type(PuckEKF.from_params({**tracker, "filter": "imm"})) is PuckIMM
    from air_hockey_agent.tracker_params import TRACKER_PARAMS
    spec = next(s for s in TRACKER_PARAMS if s.name == "filter")
    with pytest.raises(ParameterValueError, match="'kalman' is not one of ekf, ukf, mee_ukf"):
        spec.check("kalman")


# --- the multiple-model filter (core/estimation/imm.py) ----------------------------------------------
def test_imm_with_identical_modes_is_the_ekf():
    m = model()
    settings = replace(SETTINGS, impact_noise=0.15, imm_rim_impact_noise=0.15, imm_contact_speed=0.0,
                       imm_contact_spin=0.0)
    times, states = simulate_truth(m, np.array([-0.5, 0.1, 2.5, 1.7, 0.0, 8.0]), 2.0, DT / 10)
    frames = mocap_stream(m, times, states, 120.0, MocapImperfections(), np.random.default_rng(1))
    ekf, imm = PuckEKF(m, settings), PuckIMM(m, settings)
    for stamp, z in frames:
        assert ekf.process(stamp, z) == imm.process(stamp, z)
        if ekf.initialised:
            assert imm.x == pytest.approx(ekf.x, abs=1e-9)
            assert np.abs(imm.P - ekf.P).max() <= 1e-9 * np.abs(ekf.P).max()


def test_imm_fuses_a_hit_its_contact_mode_expects_where_the_ekf_rejects_and_restarts():
    m = model(friction_surface=0.0, damping=0.0)
    settings = replace(SETTINGS, imm_switch_probability=0.002, imm_rim_impact_noise=0.5, imm_contact_speed=2.0,
                       imm_contact_spin=10.0)
    rng = np.random.default_rng(2)
    hit, v0, v1 = 0.5, np.array([0.5, 0.0]), np.array([-1.0, 0.6])  # a hand turns the puck at t = 0.5 s

    def position(t):
        return np.array([-0.5, -0.2]) + v0 * min(t, hit) + v1 * max(t - hit, 0.0)
    ekf, imm = PuckEKF(m, settings), PuckIMM(m, settings)
    contact = []
    for k in range(120):
        t = k / 120.0
        z = np.append(position(t) + rng.normal(0.0, 1e-4, 2), 0.0)
        ekf.process(t, z)
        imm.process(t, z)
        contact.append(imm.mode_probabilities[MODES.index("contact")])
    assert ekf.stats.reinitialisations >= 2 and imm.stats.reinitialisations == 1  # the first is the track's start
    assert imm.stats.outliers_rejected < ekf.stats.outliers_rejected
    assert max(contact[60:63]) > 0.5 > max(contact[20:59] + contact[66:])  # the hit's frames are the contact mode's
    assert imm.x[2:4] == pytest.approx(v1, abs=0.02)


def test_imm_reports_the_nis_of_its_likely_mode_which_is_consistent():
    """On frames from the model with the filter's own noise (a free puck, rims), the NIS should follow the
    chi-square of 3 dof (median 2.37), as the EKF's does; the mixture's covariance, widened by the rare
    contact mode, read far less."""
    m = model()
    settings = replace(SETTINGS, impact_noise=0.15, imm_switch_probability=0.002, imm_rim_impact_noise=0.5,
                       imm_contact_speed=2.0, imm_contact_spin=10.0)
    times, states = simulate_truth(m, np.array([-0.5, 0.1, 1.5, 1.0, 0.0, 3.0]), 6.0, DT / 10)
    noise = MocapImperfections(position_std=1e-4, angle_std=1e-2, jitter_std=0.0)  # R of SETTINGS, nothing else
    frames = mocap_stream(m, times, states, 120.0, noise, np.random.default_rng(3))
    nis = {}
    for kind in (PuckEKF, PuckIMM):
        f = kind(m, settings)
        values = []
        for stamp, z in frames:
            f.process(stamp, z)
            if f.last_nis is not None:
                values.append(f.last_nis)
        nis[kind] = float(np.median(values[20:]))
    assert 1.9 < nis[PuckEKF] < 2.9, nis
    assert nis[PuckIMM] == pytest.approx(nis[PuckEKF], rel=0.1), nis


@pytest.mark.parametrize("kind", [PuckUKF, PuckMEEUKF])
def test_a_covariance_that_lost_definiteness_falls_back_to_the_linearised_step(kind):
    f = filters(kind)
    f.P[5, 5] = -1e-12  # rounding made P indefinite: no Cholesky factor
    f.predict_to(DT)
    f.P[0, 0] = -1e-12
    f.update(np.array([0.008, 0.104, 0.32]))
    assert np.all(np.isfinite(f.x)) and np.all(np.isfinite(f.P))

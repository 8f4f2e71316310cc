"""The flight process noise learned online (core/estimation/process_noise_adaptation.py): the rule on given
innovation distances, and the filter on test-bed tables with more and with less unmodelled acceleration than
the configured Q stands for (the test bed's random accelerations, core/puck/real_table.py, written apart
from the filter)."""
import math

import numpy as np
import pytest

from air_hockey_agent.core.estimation.ekf import PuckEKF
from air_hockey_agent.core.estimation.evaluation import EvaluationTotals, evaluate_stream
from air_hockey_agent.core.estimation.process_noise_adaptation import (CONSISTENT_MEDIAN, ProcessNoiseAdaptation,
                                                                       ProcessNoiseAdaptationSettings)
from air_hockey_agent.tracker_params import load_tracker_params, without_learning
from model_fixtures import session_on_testbed

CONFIGURED = np.diag([1e-10, 1e-10, 6.25e-8, 6.25e-8, 1e-6, 1e-6])


def test_a_block_scales_its_regimes_noise_by_its_medians_correction_to_the_gains_power():
    """A flight block whose median is twice the chi-square's scales Q's velocity terms by 2^0.5 and leaves the
    others and the other regimes; 10 % of glitches in a block at the consistent median leave the scale
    where it was; the scale stays within its bounds; an impact block scales both impact terms' standard
    deviations by the square root of its scale."""
    settings = ProcessNoiseAdaptationSettings(block=100, impact_block=40, gain=0.5, min_scale=0.1)
    learner = ProcessNoiseAdaptation(settings, CONFIGURED, CONFIGURED, 0.15, 0.001, 1 / 120)
    assert not any(learner.observe("flight", 2.0 * CONSISTENT_MEDIAN) for _ in range(99))
    assert learner.observe("flight", 2.0 * CONSISTENT_MEDIAN)
    assert learner.scales["flight"].scale == pytest.approx(math.sqrt(2.0)) and learner.scales["flight"].blocks == 1
    assert np.allclose(np.diag(learner.q()), np.diag(CONFIGURED) * [1, 1, math.sqrt(2.0), math.sqrt(2.0), 1, 1])
    assert np.array_equal(learner.q("rest"), CONFIGURED) and learner.impact() == (0.15, 0.001)
    consistent = -2.0 * np.log(1.0 - (np.arange(90) + 0.5) / 90)  # chi-square (2 dof) quantiles: median 2 ln 2
    for d2 in list(consistent) + [1e6] * 10:
        learner.observe("flight", d2)
    assert learner.scales["flight"].scale == pytest.approx(math.sqrt(2.0), rel=0.15)
    for value, bound in ((1e9, 100.0), (1e-9, 0.1)):
        for _ in range(2000):
            learner.observe("flight", value)
        assert learner.scales["flight"].scale == bound
    for _ in range(40):
        learner.observe("impact", 0.25 * CONSISTENT_MEDIAN)
    assert learner.impact() == pytest.approx((0.15 * 0.5 ** 0.5, 0.001 * 0.5 ** 0.5))
    report = learner.report()
    assert report["flight"]["blocks"] == 42 and report["impact"]["blocks"] == 1 and report["rest"]["blocks"] == 0
    assert report["flight"]["acceleration_std_m_s2"] == pytest.approx(0.25e-3 * math.sqrt(0.1) * 120)


def _flight(enabled: bool, random_acceleration: float, film: float):
    params = {**load_tracker_params(), "process_noise_adaptation.enabled": enabled}
    ekf = PuckEKF.from_params(params)
    frames = [(f.stamp, f.measurement) for f in session_on_testbed(
        ekf, 10, 11, testbed={"random_acceleration": random_acceleration, "air_film_amplitude": film})]
    totals = EvaluationTotals((1.0,), rest_speed=params["regime_rest_speed"])
    evaluate_stream(ekf, frames, totals)
    summary = totals.summary()
    return ekf, summary["nis_by_regime"]["flight"]["median"], summary["rejected_fraction"], \
        summary["horizons"]["1.0"]["median_m"]


def test_on_a_table_with_more_random_acceleration_the_filter_stays_calibrated():
    """Random accelerations 5 times the test bed's (0.05 m/s^2 std): with Q as configured the filter is
    overconfident in free flight (NIS median over 3, more than 2 % of the poses rejected); learning the
    scale (to over 5) brings the NIS under 2.8 and the rejections under 1.5 %, and predicts no worse."""
    _, nis_off, rejected_off, error_off = _flight(False, 0.05, 0.01)
    ekf, nis_on, rejected_on, error_on = _flight(True, 0.05, 0.01)
    assert nis_off > 3.0 and rejected_off > 0.02
    assert nis_on < 2.8 and rejected_on < 0.015 and ekf.process_noise_learning.scales["flight"].scale > 5.0
    assert error_on <= error_off


def test_where_nothing_accelerates_the_puck_unmodelled_the_scale_falls():
    """No random acceleration and no air film (the tilt, learned as the table acceleration, stays): the
    configured Q is more than the flight needs and the scale falls below 1; errors and NIS as without."""
    _, nis_off, _, error_off = _flight(False, 0.0, 0.0)
    ekf, nis_on, _, error_on = _flight(True, 0.0, 0.0)
    flight = ekf.process_noise_learning.scales["flight"]
    assert flight.scale < 1.0 and flight.blocks >= 20
    assert error_on == pytest.approx(error_off, rel=0.02) and nis_on == pytest.approx(nis_off, abs=0.1)


def test_the_impact_noise_falls_where_the_learned_rims_leave_less_than_it_allows():
    """The plain test bed: its rims are learned online, and the configured impact noise (15 % of the
    velocity, 1 ms of travel: a guess for real rims) then allows more than the impacts need (impact NIS
    near 1.2 of the chi-square's 2.37); learned, it falls to less than half (variance) within two blocks
    and the impact NIS rises toward the chi-square's, the errors no worse than 3 %."""
    def impacts(enabled: bool):
        params = {**load_tracker_params(), "process_noise_adaptation.enabled": enabled}
        ekf = PuckEKF.from_params(params)
        frames = [(f.stamp, f.measurement) for f in session_on_testbed(ekf, 10, 11)]
        totals = EvaluationTotals((1.0,), rest_speed=params["regime_rest_speed"])
        evaluate_stream(ekf, frames, totals)
        summary = totals.summary()
        return ekf, summary["nis_by_regime"]["impact"]["median"], summary["horizons"]["1.0"]["median_m"]
    _, nis_off, error_off = impacts(False)
    ekf, nis_on, error_on = impacts(True)
    impact = ekf.process_noise_learning.report()["impact"]
    assert impact["blocks"] >= 2 and impact["scale"] < 0.5 and impact["impact_noise"] < 0.15 * 0.71
    assert nis_off < 1.3 and nis_on > nis_off + 0.2 and error_on <= 1.03 * error_off


def test_what_sets_the_noise_keeps_it():
    """sysid's and the thesis-style columns' filter (nothing learned) and noise-estimate's (the noise
    is its to estimate) learn no process noise."""
    from air_hockey_agent.core.identification.noise import fixed_noise
    params = load_tracker_params()
    assert PuckEKF.from_params(params).process_noise_learning is not None
    assert PuckEKF.from_params(without_learning(params)).process_noise_learning is None
    assert PuckEKF.from_params(fixed_noise(params)).process_noise_learning is None

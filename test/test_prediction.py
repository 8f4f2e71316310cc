"""The fast (compiled) prediction agrees with the step-by-step reference in Python."""
import numpy as np
import pytest

from air_hockey_agent.core.puck.prediction import predict_fast, predict_stepwise
from air_hockey_agent.core.table import WALL_FAR, WALL_RIGHT
from model_fixtures import DT, Q, model

P0 = np.diag([1e-7, 1e-7, 1e-3, 1e-3, 1e-4, 1e-2])
LINES = [-0.778, 0.778]
COV_RTOL = 1e-12  # the same steps in another order of arithmetic: rounding only


def random_states(n, seed):
    rng = np.random.default_rng(seed)
    for _ in range(n):
        yield np.array([rng.uniform(-0.9, 0.9), rng.uniform(-0.48, 0.48), *rng.uniform(-3, 3, 2),
                        rng.uniform(-3, 3), rng.uniform(-20, 20)]), float(rng.choice([0.5, 1.0, 1.5, 1.2345]))


def assert_agree(a, b):
    """Two predictions of the same state and horizon agree: state, covariance, impacts, samples (with their
    covariances), crossings."""
    diff = a.state - b.state
    diff[4] = (diff[4] + np.pi) % (2 * np.pi) - np.pi
    assert np.abs(diff).max() < 1e-10
    if a.covariance is not None:
        assert np.abs(a.covariance - b.covariance).max() <= COV_RTOL * np.abs(a.covariance).max()
    assert [i[1] for i in a.impacts] == [i[1] for i in b.impacts]
    assert np.allclose([i[0] for i in a.impacts], [i[0] for i in b.impacts], atol=1e-10)
    assert len(a.samples) == len(b.samples)
    for (ta, sa, ca), (tb, sb, cb) in zip(a.samples, b.samples):  # the samples themselves, not only their count
        d = sa - sb
        d[4] = (d[4] + np.pi) % (2 * np.pi) - np.pi
        assert ta == pytest.approx(tb, abs=1e-12) and np.abs(d).max() < 1e-10
        assert (ca is None) == (cb is None)
        if ca is not None:
            assert np.abs(ca - cb).max() <= COV_RTOL * np.abs(ca).max()
    assert a.crossings.keys() == b.crossings.keys()
    for line, crossing in a.crossings.items():
        assert crossing.time == pytest.approx(b.crossings[line].time, abs=1e-9)
        assert crossing.y == pytest.approx(b.crossings[line].y, abs=1e-9)
        assert (crossing.vx, crossing.vy) == pytest.approx((b.crossings[line].vx, b.crossings[line].vy), abs=1e-10)


@pytest.mark.parametrize("friction, impact_noise, contact_time", [(0.0, 0.0, 0.0), (2.28e-4, 0.0, 0.0), (0.05, 0.0, 0.0),
                                                                 (2.28e-4, 0.15, 0.0), (2.28e-4, 0.15, 0.002),
                                                                 (0.0, 0.0, 0.001)])
def test_fast_prediction_agrees_with_stepwise(friction, impact_noise, contact_time):
    m = model(friction_surface=friction)
    noise = {"impact_noise": impact_noise, "impact_contact_time": contact_time}
    for state, horizon in random_states(60, seed=int(friction * 1e6)):
        a = predict_stepwise(m, state, P0, horizon, DT, Q, lines=LINES, sample_every=6, **noise)
        b = predict_fast(m, state, P0, horizon, DT, Q, lines=LINES, sample_every=6, **noise)
        assert_agree(a, b)


@pytest.mark.parametrize("physics", [{}, {"friction_surface": 0.0},
                                     {"restitution_slope": 0.2, "restitution_min": 0.6, "restitution_knee": 0.5,
                                      "tangential_restitution": -0.6, "friction_rim": 0.3},
                                     {"friction_surface": 0.01, "damping": 0.12, "table_acceleration": (0.02, -0.03)},
                                     {"spin_damping": 0.4, "tangential_restitution": -0.5},
                                     {"impact_delay": 0.002, "friction_surface": 0.0},
                                     {"impact_delay": 0.001, "table_acceleration": (0.01, 0.0)}])
def test_the_compiled_mean_is_the_stepwise_mean(physics):
    """Without a covariance predict_fast takes the model's own steps in compiled code (prediction_kernel): the same
    states, rim impacts (rim, time, contact point, sliding or not), samples and line crossings as the Python
    steps, up to rounding, with the speed-dependent restitution, the tangential restitution and a tilt."""
    m = model(**physics)
    impacts = sliding = 0
    for state, horizon in random_states(80, seed=21):
        for every in (6, 0):
            a = predict_stepwise(m, state, None, horizon, DT, Q, lines=LINES + [0.0], sample_every=every)
            b = predict_fast(m, state, None, horizon, DT, Q, lines=LINES + [0.0], sample_every=every)
            assert b.covariance is None
            assert_agree(a, b)
            assert [(i[1], i[4]) for i in b.impacts] == [(i[1], i[4]) for i in a.impacts]
            assert np.allclose([i[2:4] for i in b.impacts], [i[2:4] for i in a.impacts], rtol=0.0, atol=1e-12)
        impacts, sliding = impacts + len(a.impacts), sliding + sum(i[4] for i in a.impacts)
    assert impacts > 50 and 0 < sliding < impacts  # both impact branches were compared


def test_the_compiled_mean_lets_a_puck_into_the_goal_and_bounces_it_off_the_rim_beside_it():
    m = model()
    into_goal, beside = (np.array([0.5, y, 2.0, 0.0, 0.0, 0.0]) for y in (0.0, 0.3))
    scored = predict_fast(m, into_goal, None, 0.5, DT, Q)
    assert not scored.impacts and m.table.scored_x < scored.state[0] < m.table.scored_x + 2.0 * DT
    assert scored.state[2:4].tolist() == [0.0, 0.0]  # in the goal it stays (the model's step, held in the goal)
    bounced = predict_fast(m, beside, None, 0.5, DT, Q)
    assert [i[1] for i in bounced.impacts] == [WALL_FAR] and bounced.state[2] < 0.0


@pytest.mark.parametrize("y, degrees", [(0.047, 70.0), (-0.047, -70.0), (0.09, 11.0), (0.08, 30.0), (0.0, 60.0),
                                        (0.05, 6.0), (0.11, 0.0), (0.1, 10.0), (0.07, 45.0)])
@pytest.mark.parametrize("delay", [0.0, 0.002])
def test_the_compiled_prediction_meets_the_posts_as_the_model_does(y, degrees, delay):
    """Pucks crossing the far goal line inside the opening, steep or grazing a post (a corner impact: some come
    back, some are turned into the goal) or clear of both posts (they score): the compiled prediction, mean
    and covariance, equals the Python steps."""
    m = model(impact_delay=delay)
    v = 2.0 * np.array([np.cos(np.radians(degrees)), np.sin(np.radians(degrees))])
    state = np.array([m.table.x_limit - 0.1 * v[0], y - 0.1 * v[1], *v, 0.0, 3.0])
    for cov in (P0, None):
        a = predict_stepwise(m, state, cov, 0.6, DT, Q, lines=LINES, sample_every=6, impact_noise=0.15)
        b = predict_fast(m, state, cov, 0.6, DT, Q, lines=LINES, sample_every=6, impact_noise=0.15)
        assert_agree(a, b)
    scored = y in (0.0, 0.05) and degrees in (6.0, 60.0)  # clear of both posts (test_puck_model's reference)
    assert (WALL_FAR not in [i[1] for i in a.impacts]) == scored


def test_predicted_covariance_grows_with_the_horizon():
    m = model()
    state = np.array([0.0, 0.0, 0.5, 0.1, 0.0, 1.0])
    traces = [np.trace(predict_fast(m, state, P0, h, DT, Q).covariance[:2, :2]) for h in (0.1, 0.5, 1.0)]
    assert traces[0] < traces[1] < traces[2]


def test_prediction_stops_the_puck_and_keeps_it_still():
    m = model(friction_surface=0.5)
    a = predict_fast(m, np.array([0.0, 0.0, 0.2, 0.0, 0.0, 0.0]), P0, 1.5, DT, Q)
    assert a.state[2] == 0.0 and a.state[0] < 0.2


def test_impact_noise_adds_its_covariance_after_a_rim_impact_only():
    m = model()
    toward_rim = np.array([0.0, 0.4, 0.0, 2.0, 0.0, 5.0])  # hits the right rim within 0.05 s
    along = np.array([0.0, 0.0, 1.0, 0.0, 0.0, 5.0])
    for state, impacts in ((toward_rim, True), (along, False)):
        plain = predict_fast(m, state, P0, 0.1, DT, Q)
        noisy = predict_fast(m, state, P0, 0.1, DT, Q, impact_noise=0.2)
        assert bool(plain.impacts) == impacts
        extra = noisy.covariance - plain.covariance
        if not impacts:
            assert np.array_equal(extra, np.zeros((6, 6)))
            continue
        speed2 = float(plain.state[2] ** 2 + plain.state[3] ** 2)
        # added at the impact step, then carried by the later steps: at least 0.2^2 |v|^2 shrunk by damping
        assert extra[2, 2] == pytest.approx(0.04 * speed2, rel=0.1)
        assert extra[3, 3] == pytest.approx(0.04 * speed2, rel=0.1)
        assert extra[5, 5] > 0.0



def test_the_impact_contact_time_adds_position_uncertainty_after_a_rim_impact_only():
    """The outgoing path of a rim impact is offset by up to the puck's travel during the contact: the
    position variance grows by (contact time x speed)^2 at the impact (then carried on); velocity and spin
    get nothing from it; a step without an impact gets nothing."""
    m = model()
    toward_rim = np.array([0.0, 0.4, 0.0, 2.0, 0.0, 5.0])
    along = np.array([0.0, 0.0, 1.0, 0.0, 0.0, 5.0])
    for state, impacts in ((toward_rim, True), (along, False)):
        plain = predict_fast(m, state, P0, 0.1, DT, Q)
        offset = predict_fast(m, state, P0, 0.1, DT, Q, impact_contact_time=0.002)
        extra = offset.covariance - plain.covariance
        if not impacts:
            assert np.array_equal(extra, np.zeros((6, 6)))
            continue
        speed2 = float(plain.state[2] ** 2 + plain.state[3] ** 2)
        assert extra[0, 0] == pytest.approx(0.002 ** 2 * speed2, rel=0.1)
        assert extra[1, 1] == pytest.approx(0.002 ** 2 * speed2, rel=0.1)
        assert np.allclose(extra[2:, 2:], 0.0, atol=1e-15)


@pytest.mark.parametrize("accel, damping", [((0.02, -0.01), 0.125), ((-0.3, 0.5), 0.5), ((0.4, 0.0), 0.0),
                                            ((0.0, -0.2), 2.0)])
def test_fast_prediction_on_a_tilted_table_agrees_with_stepwise(accel, damping):
    """A table acceleration without surface friction: same states, covariances, impacts and line crossings as
    step by step, with curved paths that turn back (strong g)."""
    m = model(friction_surface=0.0, damping=damping, table_acceleration=accel)
    flat = model(friction_surface=0.0, damping=damping)
    for state, horizon in random_states(60, seed=11):
        for cov, every in ((P0, 6), (None, 6), (P0, 0)):
            a = predict_stepwise(m, state, cov, horizon, DT, Q, lines=LINES, sample_every=every, impact_noise=0.15)
            b = predict_fast(m, state, cov, horizon, DT, Q, lines=LINES, sample_every=every, impact_noise=0.15)
            assert_agree(a, b)
        assert np.linalg.norm(b.state[:2] - predict_fast(flat, state, None, horizon, DT, Q).state[:2]) > 1e-4


@pytest.mark.parametrize("physics", [{"spin_damping": 0.4}, {"spin_damping": 2.0, "table_acceleration": (0.02, -0.01)},
                                     {"spin_damping": 0.4, "friction_surface": 0.0}])
def test_fast_prediction_with_spin_damping_agrees_with_stepwise(physics):
    """The spin's decay in both of the kernel's paths (the glide of a flat table, the full step), with the
    covariance (its spin row and column scaled by the decay), samples and impacts."""
    m = model(**physics)
    for state, horizon in random_states(60, seed=17):
        for cov, every in ((P0, 6), (None, 6), (P0, 0)):
            a = predict_stepwise(m, state, cov, horizon, DT, Q, lines=LINES, sample_every=every, impact_noise=0.15,
                                 impact_contact_time=0.001)
            b = predict_fast(m, state, cov, horizon, DT, Q, lines=LINES, sample_every=every, impact_noise=0.15,
                             impact_contact_time=0.001)
            assert_agree(a, b)
    slow = predict_fast(m, np.array([0.0, 0.0, 0.05, 0.02, 0.0, 5.0]), P0, 1.0, DT, Q)  # no rim within 1 s
    assert not slow.impacts and slow.state[5] == pytest.approx(5.0 * (1 - DT * physics["spin_damping"]) ** 120)


def test_a_puck_at_rest_on_a_tilted_table_slides_downhill_into_the_rim():
    m = model(friction_surface=0.0, table_acceleration=(0.0, 0.3))
    rest = np.array([0.0, 0.3, 0.0, 0.0, 0.0, 0.0])
    a = predict_stepwise(m, rest, P0, 1.5, DT, Q, lines=LINES)
    b = predict_fast(m, rest, P0, 1.5, DT, Q, lines=LINES)
    assert_agree(a, b)
    assert b.impacts and b.impacts[0][1] == WALL_RIGHT  # the long rim at +y


def test_a_puck_thrown_uphill_comes_back_across_the_line_and_into_the_rim_behind_it():
    """A line crossing and a rim impact after the motion along them turned back."""
    m = model(friction_surface=0.0, table_acceleration=(0.5, 0.2))
    uphill = np.array([0.5, 0.3, -0.4, -0.3, 0.0, 0.0])  # away from the line x = 0.778 and the far rim
    a = predict_stepwise(m, uphill, P0, 3.0, DT, Q, lines=LINES)
    b = predict_fast(m, uphill, P0, 3.0, DT, Q, lines=LINES)
    assert_agree(a, b)
    assert 0.778 in b.crossings and b.crossings[0.778].vx > 0.0
    assert [wall for _, wall, *_ in b.impacts][:1] == [WALL_FAR]


def test_a_puck_that_crosses_a_line_and_turns_back_crosses_it_at_the_first_time():
    m = model(friction_surface=0.0, table_acceleration=(-0.8, 0.0))
    over = np.array([0.6, 0.3, 0.6, 0.0, 0.0, 0.0])  # out to x = 0.82, back over the line x = 0.778
    a = predict_stepwise(m, over, P0, 1.5, DT, Q, lines=LINES)
    b = predict_fast(m, over, P0, 1.5, DT, Q, lines=LINES)
    assert_agree(a, b)
    assert not b.impacts and b.crossings[0.778].vx > 0.0  # on the way out


@pytest.mark.parametrize("friction, accel", [(2.28e-4, (0.02, -0.01)), (0.05, (0.03, 0.02)), (0.3, (0.0, -0.4))])
def test_fast_prediction_with_surface_friction_on_a_tilted_table_agrees_with_stepwise(friction, accel):
    """Friction and a table acceleration together (every step takes the contact search): same mean,
    covariance, impacts and crossings, with and without process noise."""
    m = model(friction_surface=friction, table_acceleration=accel)
    for state, horizon in random_states(40, seed=13):
        for cov, every in ((P0, 6), (None, 6), (P0, 0)):
            a = predict_stepwise(m, state, cov, horizon, DT, Q, lines=LINES, sample_every=every, impact_noise=0.15)
            b = predict_fast(m, state, cov, horizon, DT, Q, lines=LINES, sample_every=every, impact_noise=0.15)
            assert_agree(a, b)
        zero_q = np.zeros((6, 6))  # without process noise the covariance is the Jacobian's alone
        a, b = (predict(m, state, P0, horizon, DT, zero_q, impact_noise=0.15)
                for predict in (predict_stepwise, predict_fast))
        assert_agree(a, b)


@pytest.mark.parametrize("friction, moves", [(0.1, False), (0.01, True)])
def test_friction_holds_a_puck_at_rest_on_a_slight_tilt_only(friction, moves):
    m = model(friction_surface=friction, table_acceleration=(0.03, -0.04))  # |g| = 0.05 m/s^2
    rest = np.array([0.1, 0.2, 0.0, 0.0, 0.3, 0.0])
    a = predict_stepwise(m, rest, P0, 1.5, DT, Q, lines=LINES)
    b = predict_fast(m, rest, P0, 1.5, DT, Q, lines=LINES)
    assert_agree(a, b)
    assert (np.linalg.norm(b.state[:2] - rest[:2]) > 1e-3) == moves


def test_a_prediction_of_the_wrong_shapes_is_refused_in_one_line():
    m = model()
    state = np.array([0.0, 0.0, 1.0, 0.0, 0.0, 0.0])
    with pytest.raises(ValueError, match=r"covariance \(6, 6\).*got \(6,\), \(6,\) and \(6, 6\)"):
        predict_fast(m, state, np.ones(6), 0.5, DT, Q)
    with pytest.raises(ValueError, match=r"state \(6,\), got \(4,\)"):
        predict_fast(m, state[:4], None, 0.5, DT, Q)


def test_a_horizon_of_zero_or_less_predicts_the_state_itself():
    m = model()
    state = np.array([0.1, 0.2, 1.0, -0.5, 0.3, 2.0])
    for horizon in (0.0, -0.5):
        for cov in (P0, None):
            a = predict_stepwise(m, state, cov, horizon, DT, Q, lines=LINES, sample_every=6)
            b = predict_fast(m, state, cov, horizon, DT, Q, lines=LINES, sample_every=6)
            assert_agree(a, b)
            assert np.array_equal(b.state, state) and not b.samples and not b.impacts


@pytest.mark.parametrize("vy", [0.0, 0.4])
def test_a_line_just_before_a_rim_is_crossed_in_the_step_whose_impact_sends_the_puck_back(vy):
    """Closed form: a puck at 3.4 m/s crosses x = x_limit - 0.01 m (the shots' line before the far rim) 1.5 ms
    after its start and meets the rim 2.9 ms later, inside one 8.3 ms step; the crossing is at (line - x0) / vx
    after the start, at y0 + vy t, with the incoming velocity, where the step's end lies back before the line
    (it was missed when only the step's two ends were compared: a bank shot near a post had no goal-line
    crossing, and the strategy test's Smash found no shot, issue #13's lab table). Started 4 mm from the rim,
    beyond the line, the puck crosses it on the way back within the step: at the impact's time plus the way
    back over the outgoing speed, with the outgoing velocity (no damping: the step's end velocity)."""
    m = model(friction_surface=0.0, damping=0.0, table_acceleration=(0.0, 0.0))
    limit = m.table.x_limit
    line = limit - 0.01
    way_in = np.array([limit - 0.015, -0.2, 3.4, vy, 0.0, 0.0])  # beside the goal mouth
    way_back = np.array([limit - 0.004, -0.2, 3.4, vy, 0.0, 0.0])
    for predict in (lambda s: predict_stepwise(m, s, P0, 0.1, DT, Q, lines=[line], sample_every=1),
                    lambda s: predict_fast(m, s, P0, 0.1, DT, Q, lines=[line], sample_every=1),
                    lambda s: predict_fast(m, s, None, 0.1, DT, Q, lines=[line], sample_every=1)):
        pred = predict(way_in)
        t = (line - way_in[0]) / 3.4
        assert pred.impacts[0][0] < DT and pred.impacts[0][1] == WALL_FAR  # the impact is in the first step
        assert pred.samples[0][1][0] < line  # and the step ends back before the line
        crossing = pred.crossings[line]
        assert (crossing.time, crossing.y, crossing.vx, crossing.vy) == pytest.approx((t, -0.2 + vy * t, 3.4, vy),
                                                                                    abs=1e-12)
        pred = predict(way_back)
        t_impact, _, x_impact, y_impact, _ = pred.impacts[0]
        out = pred.samples[0][1]
        t = t_impact + (x_impact - line) / -out[2]
        crossing = pred.crossings[line]
        assert t < DT and out[2] < 0.0
        assert (crossing.time, crossing.y, crossing.vx, crossing.vy) == pytest.approx(
            (t, y_impact + out[3] * (t - t_impact), out[2], out[3]), abs=1e-9)
    assert_agree(predict_stepwise(m, way_in, P0, 0.5, DT, Q, lines=[line]),
                 predict_fast(m, way_in, P0, 0.5, DT, Q, lines=[line]))

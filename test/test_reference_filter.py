"""The reference filter of `eval-prediction --reference` (core.estimation.reference_filter): the challenge
baseline's tracker as REFERENCE_FACTS sec. 1 describes it, checked against that description's verified
figures, closed forms and the table's mirror symmetry."""
import math

import numpy as np
import pytest

from air_hockey_agent.core.estimation.evaluation import EvaluationTotals, evaluate_stream
from air_hockey_agent.core.estimation.reference_filter import ReferenceFilter
from air_hockey_agent.core.table import WALL_LEFT, WALL_NORMALS, WALL_RIGHT
from air_hockey_agent.reference_params import load_reference_params
from air_hockey_agent.tracker_params import load_tracker_params


def reference(frequency=120.0, **overrides):
    tracker = {**load_tracker_params(), "frequency": frequency}
    return ReferenceFilter.from_params({**load_reference_params(), **overrides}, tracker)


def fly(f, state, steps, dt):
    x = np.array(state, float)
    walls = []
    for _ in range(steps):
        matrix, _, wall = f.model.step(x, dt)
        x = matrix @ x
        walls.append(wall)
    return x, walls


def test_a_side_rim_impact_as_the_baseline_was_seen_to_do():
    """REFERENCE_FACTS 1.11 (a scratch run of the baseline's tracker at its 50 Hz): a side-rim impact at
    vy = 2 m/s without spin gives vy = -1.47 m/s 0.3 s later and a spin of about -12.4 rad/s (the slide
    sign of zero slip is +1)."""
    f = reference(frequency=50.0)
    y0 = f.model.table.y_limit - 0.17  # the rim is met in the fifth 20 ms step
    x, walls = fly(f, [0.0, y0, 0.0, 2.0, 0.0, 0.0], 15, 0.02)
    assert walls[4] == WALL_RIGHT and walls.count(None) == 14
    assert x[3] == pytest.approx(-1.47, abs=0.005)
    assert x[5] == pytest.approx(-12.4, abs=0.05)


@pytest.mark.parametrize("vx, vy, spin", [(1.0, 2.0, 0.0), (-0.7, 1.5, 8.0), (0.3, 3.0, -20.0)])
def test_the_rims_are_mirror_images_of_each_other(vx, vy, spin):
    """Mirrored in the x axis (y -> -y, vy -> -vy, spin -> -spin) an impact on the right rim is one on the
    left; turned by 180 degrees about the centre (x, y, v -> -x, -y, -v) one on the far rim is one on the
    near: the rims' frames are right-handed and the slide sign follows them."""
    f = reference()
    y0 = f.model.table.y_limit - 0.01
    right, walls_r = fly(f, [0.0, y0, vx, vy, 0.0, spin], 3, 1 / 120)
    left, walls_l = fly(f, [0.0, -y0, vx, -vy, 0.0, -spin], 3, 1 / 120)
    assert WALL_RIGHT in walls_r and WALL_LEFT in walls_l
    np.testing.assert_allclose(left, right * np.array([1, -1, 1, -1, -1, -1]), atol=1e-12)
    x0 = f.model.table.x_limit - 0.01
    y = 0.4  # beside the goal: the short rim's face
    far, walls_f = fly(f, [x0, y, vy, vx, 0.0, spin], 3, 1 / 120)
    near, walls_n = fly(f, [-x0, -y, -vy, -vx, 0.0, spin], 3, 1 / 120)
    assert walls_f != walls_n and None in walls_f and walls_f.count(None) == walls_n.count(None) == 2
    np.testing.assert_allclose(near, far * np.array([-1, -1, -1, -1, 1, 1]), atol=1e-12)


@pytest.mark.parametrize("wall", range(4))
@pytest.mark.parametrize("along, spin", [(1.0, 0.0), (-1.5, 0.0), (0.8, -10.0)])
def test_an_impact_slows_the_contact_points_slip_along_every_rim(wall, along, spin):
    """Rim friction works against the slip of the puck's contact point along the rim (its velocity along
    the rim plus the spin's at the contact point, radius r from the centre toward the rim), whichever the
    rim: taken in the table frame here, so a rim frame of the wrong hand (the spin's sign turned) fails."""
    f = reference()
    n = np.array(WALL_NORMALS[wall])
    tangent = np.array([-n[1], n[0]])
    r = f.model.table.puck_radius
    start = -n * (f.model.table.wall_offset(wall) - 0.004) + tangent * 0.2  # 4 mm from the rim, beside the goal
    velocity = along * tangent - 1.0 * n

    def slip(state):
        contact_velocity = state[2:4] + state[5] * np.array([-(-r * n[1]), -r * n[0]])  # omega x (-r n)
        return float(contact_velocity @ tangent)

    state = np.array([*start, *velocity, 0.0, spin])
    after, walls = fly(f, state, 2, 1 / 120)
    assert walls[0] == wall
    assert abs(slip(after)) < abs(slip(state))


def test_free_flight_is_linear_damping_per_axis_and_noise_per_second():
    """Away from the rims: v_n = v_0 (1 - dt d)^n per axis, x_n = x_0 + dt (v_0 + ... + v_{n-1}); a step
    of dt adds process_noise * dt / step."""
    f = reference()
    d = f.settings.damping
    dt, n = 1 / 120, 60
    x, walls = fly(f, [-0.5, 0.0, 0.6, -0.3, 0.2, 1.0], n, dt)
    assert walls == [None] * n
    factor = np.array([1 - dt * d[0], 1 - dt * d[1]])
    np.testing.assert_allclose(x[2:4], np.array([0.6, -0.3]) * factor ** n, rtol=1e-12)
    travelled = np.array([0.6, -0.3]) * dt * (1 - factor ** n) / (1 - factor)
    np.testing.assert_allclose(x[:2], np.array([-0.5, 0.0]) + travelled, rtol=1e-12)
    assert x[4] == pytest.approx(0.2 + n * dt * 1.0) and x[5] == 1.0
    _, q, _ = f.model.step(np.array([0.0, 0.0, 0.5, 0.5, 0.0, 0.0]), dt)
    np.testing.assert_allclose(np.diag(q), np.array(load_reference_params()["process_noise"]) * dt / 0.02)


def test_a_scored_puck_and_one_off_the_table_are_held():
    f = reference()
    t = f.model.table
    state = np.array([t.x_limit - 0.005, 0.05, 2.0, 0.1, 0.0, 3.0])  # in the goal band, crossing the line
    matrix, q, wall = f.model.step(state, 1 / 120)
    assert wall is None and np.array_equal(matrix, np.eye(6)) and not q.any()
    off = np.array([0.2, t.y_limit + 0.002, 0.5, 0.5, 0.0, 0.0])  # the centre beyond a long rim's line
    matrix, q, _ = f.model.step(off, 1 / 120)
    assert np.array_equal(matrix, np.eye(6)) and not q.any()


def test_every_pose_on_the_table_is_fused_from_a_standing_start():
    f = reference()
    f.process(0.0, [0.1, 0.2, 0.3])
    assert f.initialised and np.array_equal(f.x, [0.1, 0.2, 0.0, 0.0, 0.3, 0.0])
    assert np.array_equal(f.P, np.eye(6)) and f.last_nis is None
    for k in range(1, 30):
        f.process(k / 120, [0.1, 0.2, 0.3])
    assert f.last_nis < 1.0
    f.process(30 / 120, [0.4, 0.2, 0.3])  # a 0.3 m jump: no gate, fused
    assert f.x[0] > 0.2 and f.last_nis > 100 and f.stats.outliers_rejected == 0
    f.process(31 / 120, [5.0, 0.0, 0.0])  # off the table: not a measurement
    assert f.stats.off_table == 1 and f.last_nis is None
    f.process(31 / 120 - 0.001, [0.4, 0.2, 0.3])  # a late stamp: not fused, the track goes on
    assert f.stats.repeated_frames == 1 and f.stats.reinitialisations == 1 and f.last_nis is None
    f.process(10.0, [0.0, 0.0, 0.0])  # after a gap: a new track
    assert f.stats.reinitialisations == 2 and np.array_equal(f.x, np.zeros(6))
    f.process(5.0, [0.1, 0.0, 0.0])  # time ran back farther than the gap (a replay loop): a new track
    assert f.stats.reinitialisations == 3 and f.stamp == 5.0


def test_on_its_own_model_its_predictions_are_exact():
    """A stream flown by the reference's own model, without noise: from its converged estimates the
    predictions through several rim impacts are within a fraction of a millimetre (the evaluation predicts
    with the reference's model and compares with the same stream)."""
    f = reference()
    dt = 1 / 120
    x = np.array([-0.6, 0.1, 1.6, 1.1, 0.0, 0.0])
    frames = []
    for k in range(600):
        frames.append((k * dt, [x[0], x[1], math.remainder(x[4], 2 * math.pi)]))
        matrix, _, _ = f.model.step(x, dt)
        x = matrix @ x
    totals = EvaluationTotals((0.5,))
    evaluate_stream(f, frames, totals)
    errors = np.array(totals.errors["0.5"])
    assert errors.size > 400
    assert np.median(errors) < 2e-4  # the first frames' standing start converges within a few frames


def test_the_closed_form_flight_between_impacts_is_the_stepwise_flight():
    """The evaluation's predictions fly between impacts in closed form: the same states as step by step
    (rims, goals and pucks held off the table included) for random starts over 1.5 s."""
    f = reference()
    rng = np.random.default_rng(3)
    dt, impacts = 1 / 120, 0
    for _ in range(200):
        start = np.array([rng.uniform(-0.95, 0.95), rng.uniform(-0.5, 0.5), *rng.uniform(-4.0, 4.0, 2),
                          rng.uniform(-3.0, 3.0), rng.uniform(-30.0, 30.0)])
        x, walls = start.copy(), []
        for k in range(180):
            matrix, _, wall = f.model.step(x, dt)
            x = matrix @ x
            x[4] = math.remainder(x[4], 2 * math.pi)
            if wall is not None:
                walls.append((k + 1, wall))
        fast, met = f.model.propagate(start, dt, 180)
        np.testing.assert_allclose(fast[:4], x[:4], atol=1e-9)
        assert abs(math.remainder(fast[4] - x[4], 2 * math.pi)) < 1e-9 and fast[5] == pytest.approx(x[5], abs=1e-9)
        assert met == walls
        impacts += len(walls)
    assert impacts > 200  # most starts meet rims

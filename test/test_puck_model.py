"""Puck model step (eq. 3.1-3.4): closed forms, impacts on every rim, goals, exact Jacobians."""
import math

import numpy as np
import pytest

from air_hockey_agent.core.puck.model import PuckParams, wrap_angle
from air_hockey_agent.core.table import (FIRST_POST, WALL_FAR, WALL_LEFT, WALL_NEAR, WALL_RIGHT, contact_rim,
                                         post_contact_time)
from model_fixtures import DT, TABLE, finite_difference_jacobian, model

X, Y = TABLE.x_limit, TABLE.y_limit
# One state per rim and branch: puck 4 mm from the rim, hitting it within the step.
IMPACT_CASES = {
    "left-sticking": (np.array([0.3, -Y + 0.004, 0.2, -1.5, 0.1, 1.0]), WALL_LEFT, False),
    "left-sliding": (np.array([0.3, -Y + 0.004, 2.5, -1.2, 0.1, 40.0]), WALL_LEFT, True),
    "far-sticking": (np.array([X - 0.004, 0.3, 1.5, 0.3, 0.1, -3.0]), WALL_FAR, False),
    "far-sliding": (np.array([X - 0.004, 0.3, 1.0, -2.0, 0.1, -3.0]), WALL_FAR, True),
    "right-sticking": (np.array([0.3, Y - 0.005, 0.5, 1.5, 0.1, 1.0]), WALL_RIGHT, False),
    "right-sliding": (np.array([0.3, Y - 0.005, -2.5, 1.0, 0.1, 10.0]), WALL_RIGHT, True),
    "near-sticking": (np.array([-X + 0.004, -0.3, -1.5, 0.3, 0.1, -3.0]), WALL_NEAR, False),
    "near-sliding": (np.array([-X + 0.004, -0.3, -1.0, 2.5, 0.1, 0.0]), WALL_NEAR, True),
}


def test_free_motion_matches_closed_form_without_friction():
    m = model(friction_surface=0.0)
    s = np.array([-0.5, 0.0, 1.0, 0.2, 0.0, 3.0])
    n = 30
    for _ in range(n):
        s = m.step(s, DT).state
    a = 1 - DT * 0.5
    travelled = DT * (1 - a ** n) / (1 - a)
    assert s[0] == pytest.approx(-0.5 + 1.0 * travelled, abs=1e-12)
    assert s[2] == pytest.approx(a ** n * 1.0, abs=1e-12)
    assert s[4] == pytest.approx(wrap_angle(3.0 * n * DT))


def test_spin_decays_at_its_rate_and_the_angle_follows_the_sum_of_the_spins():
    """omega_n = b^n omega_0 with b = 1 - dt k; the angle advances by dt omega before each decay, so it is
    dt omega_0 (1 - b^n) / (1 - b); position and velocity are the spinless model's."""
    k, om0, n = 0.4, 6.0, 90
    m, spinless = model(spin_damping=k), model()
    s = t = np.array([-0.5, 0.0, 1.0, 0.2, 0.0, om0])
    for _ in range(n):
        s, t = m.step(s, DT).state, spinless.step(t, DT).state
    b = 1 - DT * k
    assert s[5] == pytest.approx(om0 * b ** n, rel=1e-12)
    assert s[4] == pytest.approx(wrap_angle(DT * om0 * (1 - b ** n) / (1 - b)), abs=1e-10)
    assert np.array_equal(s[:4], t[:4])
    assert s[5] == pytest.approx(om0 * math.exp(-k * n * DT), rel=1e-3)  # the continuous decay, to the step's order


def test_surface_friction_decelerates_along_the_velocity_and_stops_the_puck():
    m = model(damping=0.0, friction_surface=0.5)
    s = np.array([0.0, 0.0, 0.03, 0.04, 0.0, 0.0])  # 0.05 m/s
    s1 = m.step(s, DT).state
    assert math.hypot(s1[2], s1[3]) == pytest.approx(0.05 - 0.5 * DT)
    assert s1[3] / s1[2] == pytest.approx(0.04 / 0.03)  # direction kept (isotropic friction)
    for _ in range(40):
        s1 = m.step(s1, DT).state
    assert s1[2] == 0.0 and s1[3] == 0.0


def test_table_acceleration_follows_its_closed_form_and_friction_holds_a_resting_puck():
    # the discrete model's v_{n+1} = a (v_n + dt g), a = 1 - dt d: v_n = c + (v0 - c) a^n with c = a g / d
    g = np.array([0.02, -0.03])
    m = model(friction_surface=0.0, table_acceleration=tuple(g))
    s = np.array([0.0, 0.0, 0.4, 0.0, 0.0, 0.0])
    n = 120
    for _ in range(n):
        s = m.step(s, DT).state
    a = 1 - DT * 0.5
    c = a * g / 0.5
    v = c + (np.array([0.4, 0.0]) - c) * a ** n
    travelled = DT * (c * n + (np.array([0.4, 0.0]) - c) * (1 - a ** n) / (1 - a))
    assert s[2:4] == pytest.approx(v, abs=1e-12) and s[0:2] == pytest.approx(travelled, abs=1e-12)
    held = model(friction_surface=0.05, table_acceleration=(0.03, 0.0))  # |g| < mu_s: static friction
    rest = np.zeros(6)
    for _ in range(50):
        rest = held.step(rest, DT).state
    assert np.all(rest == 0.0)


def test_table_acceleration_matches_the_test_beds_tilted_surface():
    # an independent integrator (core/puck/real_table.py, semi-implicit Euler at 1 kHz) on a tilted table
    from air_hockey_agent.core.puck.real_table import RealTablePuck, TableEffects
    from air_hockey_agent.core.puck.surface_field import GRAVITY
    tilt, heading = 0.003, 2.0
    effects = TableEffects(damping=0.1, tilt=tilt, tilt_heading=heading)
    start = np.array([-0.4, -0.2, 0.6, 0.1, 0.0, 0.0])
    _, truth = RealTablePuck(TABLE, effects, np.random.default_rng(0)).simulate(start, 1.0, 1e-3)
    g = GRAVITY * math.sin(tilt) * np.array([math.cos(heading), math.sin(heading)])
    m, s = model(friction_surface=0.0, damping=0.1, table_acceleration=tuple(g)), start
    for _ in range(120):
        s = m.step(s, DT).state
    assert np.linalg.norm(s[:2] - truth[-1, :2]) < 5e-4  # the two integrators' step difference
    flat = start
    for _ in range(120):
        flat = model(friction_surface=0.0, damping=0.1).step(flat, DT).state
    assert np.linalg.norm(flat[:2] - truth[-1, :2]) > 0.01  # what the term is worth over 1 s


@pytest.mark.parametrize("name", list(IMPACT_CASES))
def test_impact_on_each_rim_with_each_branch(name):
    state, wall, sliding = IMPACT_CASES[name]
    res = model().step(state, DT)
    assert [(i.wall, i.sliding) for i in res.impacts] == [(wall, sliding)]
    nx, ny = [(0, 1), (-1, 0), (0, -1), (1, 0)][wall]
    assert nx * res.state[2] + ny * res.state[3] > 0  # moving away from the rim afterwards


def _toward_post(normal_degrees: float, degrees: float, speed: float) -> np.ndarray:
    """A spinning puck that touches the far rim's +y post in the middle of the next step: its centre then at
    one radius from the post along ``normal_degrees``, moving at ``speed`` [m/s] along ``degrees``."""
    phi, heading = math.radians(normal_degrees), math.radians(degrees)
    contact = np.array([TABLE.length / 2 + TABLE.puck_radius * math.cos(phi),
                        TABLE.goal_width / 2 + TABLE.puck_radius * math.sin(phi)])
    v = speed * np.array([math.cos(heading), math.sin(heading)])
    return np.array([*(contact - 0.4 * DT * v), *v, 0.2, 7.0])


@pytest.mark.parametrize("slope,accel,beta,knee,spin,delay", [
    (0.0, (0.0, 0.0), 0.0, 0.0, 0.0, 0.0), (0.15, (0.0, 0.0), 0.0, 0.0, 0.0, 0.0),
    (0.15, (0.0, 0.0), 0.0, 1.1, 0.0, 0.0),
    (0.0, (0.03, -0.02), 0.0, 0.0, 0.0, 0.0), (0.0, (0.0, 0.0), -0.6, 0.0, 0.0, 0.0),
    (0.0, (0.0, 0.0), 0.0, 0.0, 0.4, 0.0), (0.15, (0.0, 0.0), -0.6, 0.0, 0.0, 0.002)],
                         ids=["constant e", "e falls with speed", "e falls beyond a knee", "tilted table",
                              "soft tangential impulse", "spin decays", "a compliant rim"])
@pytest.mark.parametrize("name", list(IMPACT_CASES) + ["free", "corner", "goal", "post", "steep at a post",
                                                       "grazing a post", "past the line"])
def test_step_jacobian_matches_central_finite_differences(name, slope, accel, beta, knee, spin, delay):
    states = {"free": np.array([0.1, 0.2, 1.0, 0.5, 0.3, 2.0]),
              "corner": np.array([X - 0.004, Y - 0.007, 1.0, 1.3, 0.1, 5.0]),
              "goal": np.array([X - 0.004, 0.02, 1.5, 0.1, 0.1, 5.0]),
              "post": _toward_post(200.0, 10.0, 1.5), "steep at a post": _toward_post(225.0, 60.0, 1.0),
              "grazing a post": _toward_post(250.0, 30.0, 2.5),
              "past the line": np.array([X + 0.001, 0.3, 1.0, 0.2, 0.1, 3.0])}  # a compliant rim's contact
    state = states.get(name, IMPACT_CASES.get(name, (None,))[0])
    m = model(restitution_slope=slope, table_acceleration=accel, tangential_restitution=beta, restitution_knee=knee,
              spin_damping=spin, impact_delay=delay)
    assert np.allclose(m.step(state, DT).jacobian, finite_difference_jacobian(m, state, DT), atol=2e-6)


def test_corner_gives_two_impacts_in_one_step():
    res = model().step(np.array([X - 0.004, Y - 0.007, 1.0, 1.3, 0.1, 5.0]), DT)
    assert [i.wall for i in res.impacts] == [WALL_FAR, WALL_RIGHT]


def test_goal_opening_has_no_rim():
    m = model()
    s = np.array([X - 0.004, 0.02, 1.5, 0.1, 0.1, 5.0])
    for _ in range(10):
        res = m.step(s, DT)
        assert not res.impacts
        s = res.state
    assert s[0] > TABLE.length / 2  # left the table through the goal


def test_a_puck_a_radius_past_the_goal_face_has_scored_and_stays():
    """Through the opening and a radius past the face (no post within reach) the puck stays where it is,
    its velocity and spin 0 from then on (a goal swallows it), in the step and its Jacobian; a step before
    it still flies."""
    m = model()
    s = np.array([X - 0.004, 0.02, 1.5, 0.1, 0.1, 5.0])
    path = [s]
    for _ in range(40):
        path.append(m.step(path[-1], DT).state)
    scored = [p for p in path if abs(p[0]) > TABLE.scored_x]
    assert TABLE.scored_x == pytest.approx(TABLE.length / 2 + TABLE.puck_radius)
    assert scored and scored[0][0] - TABLE.scored_x < 1.5 * DT * 1.01  # held within a step of the line
    assert all(np.allclose(p, scored[1]) for p in scored[1:]) and scored[1][2:4].tolist() == [0.0, 0.0]
    flying = next(p for p in path if TABLE.x_limit < p[0] < TABLE.scored_x)
    assert m.step(flying, DT).state[2] > 1.0
    jac = m.step(scored[0], DT).jacobian
    assert np.allclose(jac, finite_difference_jacobian(m, scored[0], DT)) and not jac[2:4].any()


@pytest.mark.parametrize("y, degrees, scores", [(0.0, 0.0, True), (0.05, 6.0, True), (0.047, 70.0, False),
                                                (-0.047, -70.0, False), (0.09, 11.0, False), (0.08, 30.0, False),
                                                (0.0, 60.0, True), (0.11, 0.0, False), (0.1, 10.0, False)])
def test_a_puck_meets_a_post_as_a_corner_on_its_way_into_the_goal(y, degrees, scores):
    """A puck crossing the far goal line at (x_limit, y) inside the opening at ``degrees`` from the table's axis
    meets a post (the rim's end at x = L/2, |y| = goal_width/2) where its centre first comes within one radius
    of it before passing the rim's face, and leaves with the impact in the frame of the normal from the post
    to its centre; clear of both posts it scores. References, independent of the model's arithmetic: the
    path sampled finely (first contact), and a frictionless impact's closed form v' = v - (1 + e)(v . n) n."""
    v = 2.0 * np.array([math.cos(math.radians(degrees)), math.sin(math.radians(degrees))])
    half = TABLE.length / 2
    times = np.linspace(0.0, (half - X) / v[0], 200001)
    path = np.array([X, y]) + times[:, None] * v
    posts = np.array([[half, g] for g in (TABLE.goal_width / 2, -TABLE.goal_width / 2)])
    near = [np.flatnonzero(np.linalg.norm(path - post, axis=1) < TABLE.puck_radius) for post in posts]
    assert (not any(len(k) for k in near)) == scores
    m = model(damping=0.0, friction_surface=0.0, friction_rim=0.0, tangential_restitution=-1.0)
    first = np.array([X, y]) if scores else path[min(k[0] for k in near if len(k))]
    res = m.step(np.array([*(first - 0.3 * DT * v), *v, 0.0, 0.0]), DT)  # the line or the contact mid-step
    if scores:
        for _ in range(10):
            assert not res.impacts
            res = m.step(res.state, DT)
        assert res.state[0] > half  # past the face: in the goal
        return
    post = posts[[len(k) > 0 for k in near].index(True)]
    (impact,) = res.impacts
    assert impact.wall == WALL_FAR and np.hypot(impact.x - first[0], impact.y - first[1]) < 2e-5
    n = (np.array([impact.x, impact.y]) - post) / TABLE.puck_radius
    assert res.state[2:4] == pytest.approx(v - (1.0 + 0.9) * (v @ n) * n, abs=1e-9)
    assert np.linalg.norm(res.state[2:4]) <= np.linalg.norm(v)  # energy never grows


def test_invalid_parameters_are_refused_with_the_name():
    with pytest.raises(ValueError, match="restitution must be in"):
        PuckParams(0.0, 0.5, 1.2, 0.1).validate()
    with pytest.raises(ValueError, match="friction_rim must be >= 0"):
        model(friction_rim=-0.1)
    with pytest.raises(ValueError, match="table_acceleration must be two finite numbers"):
        model(table_acceleration=(0.0, math.nan))
    with pytest.raises(ValueError, match="restitution_knee must be >= 0"):
        model(restitution_knee=-0.5)
    with pytest.raises(ValueError, match=r"tangential_restitution must be in \[-1, 1\]"):
        model(tangential_restitution=-1.5)
    with pytest.raises(ValueError, match="spin_damping must be >= 0"):
        model(spin_damping=-0.1)


def test_the_post_contact_time_against_its_geometry():
    """A post's first contact along a straight path: the time its centre is one radius from the post
    (a closed form: a head-on puck 0.1 m away at 2 m/s touches after (0.1 - r) / 2 s), the time since it
    touched when it already overlaps while approaching, none when it moves away, passes wide, or would touch
    only behind the face."""
    r, half, post = TABLE.puck_radius, TABLE.length / 2, TABLE.goal_width / 2
    assert post_contact_time(half - 0.1, post, 2.0, 0.0, half, post, r) == pytest.approx((0.1 - r) / 2.0, rel=1e-12)
    # overlapping and approaching: the time since its path touched, (sqrt 2 - 1) r / 2 at this speed and angle
    assert post_contact_time(half - 0.5 * r, post - 0.5 * r, 1.0, 1.0, half, post, r) == pytest.approx(
        -(math.sqrt(2.0) - 1.0) * r / 2.0, rel=1e-12)
    assert post_contact_time(half - 0.5 * r, post - 0.5 * r, -1.0, -1.0, half, post, r) == math.inf
    assert post_contact_time(half - 0.1, post - 2.0 * r, 2.0, 0.0, half, post, r) == math.inf  # passes below
    # in the goal, moving back out past the post's far side: its contact would be behind the face
    assert post_contact_time(half + 0.1, post - 0.5 * r, -2.0, 0.0, half, post, r) == math.inf
    positions = np.array([TABLE.post_position(c) for c in range(FIRST_POST, FIRST_POST + 4)])
    assert positions == pytest.approx(np.array([(half, -post), (half, post), (-half, -post), (-half, post)]))
    assert [contact_rim(c) for c in range(FIRST_POST, FIRST_POST + 4)] == [WALL_FAR, WALL_FAR, WALL_NEAR, WALL_NEAR]


@pytest.mark.parametrize("speed, degrees", [(0.5, 0.0), (2.0, 0.0), (3.0, 35.0)])
def test_a_compliant_rims_paths_before_and_after_meet_beyond_it(speed, degrees):
    """impact_delay s: the impact comes s after the centre reaches the rim line, so the straight paths before
    and after meet s |vn| beyond it, the outgoing path that much farther out than a rigid rim's (closed form:
    no friction or damping, a frictionless rim, constant e)."""
    e, s = 0.8, 0.002
    m = model(friction_surface=0.0, damping=0.0, restitution=e, friction_rim=0.0, tangential_restitution=-1.0,
              impact_delay=s)
    v = speed * np.array([math.cos(math.radians(degrees)), math.sin(math.radians(degrees))])
    state, t = np.array([X - 0.1, -0.3, *v, 0.0, 0.0]), 0.0  # the far rim beside the goal
    for _ in range(30):
        res = m.step(state, DT)
        state, t = res.state, t + DT
        if res.impacts:
            assert res.impacts[0].time == pytest.approx(0.1 / v[0] + s - (t - DT), abs=1e-12)
            assert res.impacts[0].x == pytest.approx(X + s * v[0], abs=1e-12)
    touch = 0.1 / v[0]
    assert state[0] == pytest.approx(X + s * v[0] - e * v[0] * (t - touch - s), abs=1e-12)  # meets beyond the line
    assert state[1] == pytest.approx(-0.3 + v[1] * t, abs=1e-12) and state[2] == pytest.approx(-e * v[0])
    rigid = model(friction_surface=0.0, damping=0.0, restitution=e, friction_rim=0.0, tangential_restitution=-1.0)
    after = np.array([X - 0.1, -0.3, *v, 0.0, 0.0])
    for _ in range(30):
        after = rigid.step(after, DT).state
    assert state[0] - after[0] == pytest.approx((1.0 + e) * s * v[0], abs=1e-12)  # (1 + e) s |vn| farther out


def test_a_puck_past_the_goal_line_is_in_the_goal_even_with_a_compliant_rim():
    """Behind a short rim line by more than the delay's travel, beside the opening, a puck is in the goal (no rim
    impact pulls it back); within it, the rim's impact is still due."""
    m = model(impact_delay=0.002)
    inside = m.first_impact(X + 0.001, 0.3, 1.0, 0.0, DT)
    assert inside is not None and inside[1] == WALL_FAR and inside[0] == pytest.approx(0.001, abs=1e-12)
    assert m.first_impact(X + 0.003, 0.3, 1.0, 0.0, DT) is None

"""Routh wall impact (thesis eq. 3.2-3.4) against closed forms and physics."""
import numpy as np
import pytest

from air_hockey_agent.core.puck.impact import is_sliding, rim_impact, speed_restitution

R, E, MU = 0.03165, 0.9, 0.1


def test_straight_in_impact_keeps_tangential_velocity_and_scales_normal_by_minus_e():
    res = rim_impact(vb=0.0, vn=-2.0, omega=0.0, radius=R, restitution=E, friction=MU)
    assert (res.vb, res.vn, res.omega) == pytest.approx((0.0, 1.8, 0.0))


def test_sticking_impact_ends_with_zero_slip():
    res = rim_impact(vb=0.3, vn=-2.0, omega=1.0, radius=R, restitution=E, friction=MU)
    assert not res.sliding
    assert res.vb + R * res.omega == pytest.approx(0.0, abs=1e-12)


def test_sliding_impact_uses_coulomb_impulse_against_the_slip():
    vb, vn, om = 2.0, -1.0, 0.0
    res = rim_impact(vb, vn, om, R, E, MU)
    assert res.sliding
    impulse_b = MU * (1 + E) * abs(vn)  # |P_b| / m = mu |P_n| / m
    assert res.vb == pytest.approx(vb - impulse_b)
    assert res.omega == pytest.approx(om - 2 * impulse_b / R)
    assert res.vn == pytest.approx(-E * vn)


def test_branches_agree_on_the_switching_boundary():
    vn, om = -1.5, 0.0
    boundary = 3 * MU * (1 + E) * abs(vn)  # |c| at the switch
    below = rim_impact(boundary * (1 - 1e-9), vn, om, R, E, MU)
    above = rim_impact(boundary * (1 + 1e-9), vn, om, R, E, MU)
    assert not below.sliding and above.sliding
    assert np.allclose([below.vb, below.vn, below.omega], [above.vb, above.vn, above.omega], atol=1e-7)


def test_energy_never_increases():
    rng = np.random.default_rng(3)
    for _ in range(500):
        vb, om = rng.uniform(-3, 3), rng.uniform(-50, 50)
        vn = -rng.uniform(0.01, 3)
        e, mu = rng.uniform(0, 1), rng.uniform(0, 0.6)
        res = rim_impact(vb, vn, om, R, e, mu)
        before = vb ** 2 + vn ** 2 + 0.5 * R ** 2 * om ** 2  # 2 KE / m with I = m r^2 / 2
        after = res.vb ** 2 + res.vn ** 2 + 0.5 * R ** 2 * res.omega ** 2
        assert after <= before * (1 + 1e-12)


@pytest.mark.parametrize("slope,floor", [(0.0, 0.0), (0.2, 0.0), (0.2, 0.6)],
                         ids=["constant", "falling", "falling to its floor"])
@pytest.mark.parametrize("state", [(0.3, -2.0, 1.0), (2.0, -1.0, 5.0), (-2.0, -1.0, -5.0)],
                         ids=["sticking", "sliding+", "sliding-"])
def test_branch_jacobian_matches_finite_differences(state, slope, floor):
    h = 1e-7
    res = rim_impact(*state, R, E, MU, slope, floor)
    fd = np.zeros((3, 3))
    for i in range(3):
        d = np.zeros(3)
        d[i] = h
        plus = rim_impact(*(np.add(state, d)), R, E, MU, slope, floor)
        minus = rim_impact(*(np.subtract(state, d)), R, E, MU, slope, floor)
        fd[:, i] = (np.array(plus[:3]) - np.array(minus[:3])) / (2 * h)
    assert np.allclose(res.jacobian, fd, atol=1e-6)


def test_branch_condition_is_the_friction_cone():
    assert is_sliding(1.0, -0.1, 0.0, R, E, MU)
    assert not is_sliding(0.01, -3.0, 0.0, R, E, MU)


def test_restitution_falls_with_the_normal_speed_and_never_below_zero():
    slow = rim_impact(0.0, -0.5, 0.0, R, 0.95, MU, 0.2)
    fast = rim_impact(0.0, -2.0, 0.0, R, 0.95, MU, 0.2)
    assert slow.vn == pytest.approx((0.95 - 0.2 * 0.5) * 0.5) and fast.vn == pytest.approx((0.95 - 0.2 * 2.0) * 2.0)
    assert speed_restitution(0.95, 0.2, -10.0) == (0.0, 0.0)
    assert speed_restitution(0.95, 0.0, -3.0) == (0.95, 0.0)


def test_restitution_levels_off_at_its_floor():
    assert speed_restitution(1.0, 0.15, -1.0, 0.67) == pytest.approx((0.85, 0.15))
    assert speed_restitution(1.0, 0.15, -3.0, 0.67) == (0.67, 0.0)  # 1 - 0.45 is below the floor
    assert rim_impact(0.0, -4.0, 0.0, R, 1.0, MU, 0.15, 0.67).vn == pytest.approx(0.67 * 4.0)
    assert speed_restitution(0.6, 0.15, -3.0, 0.67) == (0.6, 0.0)  # a floor above e: e stays constant


@pytest.mark.parametrize("beta", [-1.0, -0.6, 0.0, 0.5])
def test_a_sticking_impact_leaves_minus_beta_of_the_slip(beta):
    vb, vn, om = 0.3, -2.0, 1.0
    res = rim_impact(vb, vn, om, R, E, MU, tangential=beta)
    assert not res.sliding
    assert res.vb + R * res.omega == pytest.approx(-beta * (vb + R * om), abs=1e-12)
    # the angular momentum about the contact point is conserved in a rim impact (the impulse acts there)
    assert res.vb - 0.5 * R * res.omega == pytest.approx(vb - 0.5 * R * om, abs=1e-12)


@pytest.mark.parametrize("beta", [-0.7, 0.5])
def test_branches_agree_on_the_switching_boundary_with_a_tangential_restitution(beta):
    vn, om = -1.5, 0.0
    boundary = 3 * MU * (1 + E) * abs(vn) / (1 + beta)  # |c| at the switch
    below = rim_impact(boundary * (1 - 1e-9), vn, om, R, E, MU, tangential=beta)
    above = rim_impact(boundary * (1 + 1e-9), vn, om, R, E, MU, tangential=beta)
    assert not below.sliding and above.sliding
    assert np.allclose([below.vb, below.vn, below.omega], [above.vb, above.vn, above.omega], atol=1e-7)


@pytest.mark.parametrize("beta", [-0.7, 0.4])
@pytest.mark.parametrize("state", [(0.3, -2.0, 1.0), (2.0, -1.0, 5.0)], ids=["sticking", "sliding"])
def test_branch_jacobian_with_a_tangential_restitution_matches_finite_differences(state, beta):
    h = 1e-7
    res = rim_impact(*state, R, E, MU, 0.2, 0.6, beta)
    fd = np.zeros((3, 3))
    for i in range(3):
        d = np.zeros(3)
        d[i] = h
        plus = rim_impact(*(np.add(state, d)), R, E, MU, 0.2, 0.6, beta)
        minus = rim_impact(*(np.subtract(state, d)), R, E, MU, 0.2, 0.6, beta)
        fd[:, i] = (np.array(plus[:3]) - np.array(minus[:3])) / (2 * h)
    assert np.allclose(res.jacobian, fd, atol=1e-6)


def test_energy_never_increases_with_a_tangential_restitution_up_to_one():
    rng = np.random.default_rng(4)
    for _ in range(500):
        vb, om = rng.uniform(-3, 3), rng.uniform(-50, 50)
        vn = -rng.uniform(0.01, 3)
        e, mu, beta = rng.uniform(0, 1), rng.uniform(0, 0.6), rng.uniform(-1, 1)
        res = rim_impact(vb, vn, om, R, e, mu, tangential=beta)
        before = vb ** 2 + vn ** 2 + 0.5 * R ** 2 * om ** 2
        after = res.vb ** 2 + res.vn ** 2 + 0.5 * R ** 2 * res.omega ** 2
        assert after <= before * (1 + 1e-12)


def test_restitution_holds_below_its_knee_then_falls_to_its_floor():
    # another engine's rims (issue #13): 0.96 below 0.5 m/s, 0.67 above 2 m/s
    slope = 0.29 / 1.5
    assert speed_restitution(0.96, slope, -0.3, 0.67, 0.5) == (0.96, 0.0)
    assert speed_restitution(0.96, slope, -1.25, 0.67, 0.5) == pytest.approx(((0.96 + 0.67) / 2, slope))
    assert speed_restitution(0.96, slope, -2.5, 0.67, 0.5) == (0.67, 0.0)
    assert rim_impact(0.0, -1.25, 0.0, R, 0.96, MU, slope, 0.67, knee=0.5).vn == pytest.approx(0.815 * 1.25)


@pytest.mark.parametrize("vn", [-0.3, -1.2, -3.0], ids=["below the knee", "falling", "on the floor"])
def test_branch_jacobian_with_a_knee_matches_finite_differences(vn):
    h = 1e-7
    state = (0.3, vn, 1.0)
    args = (R, 0.96, MU, 0.2, 0.67, -0.4, 0.5)
    res = rim_impact(*state, *args)
    fd = np.zeros((3, 3))
    for i in range(3):
        d = np.zeros(3)
        d[i] = h
        fd[:, i] = (np.array(rim_impact(*np.add(state, d), *args)[:3])
                    - np.array(rim_impact(*np.subtract(state, d), *args)[:3])) / (2 * h)
    assert np.allclose(res.jacobian, fd, atol=1e-6)

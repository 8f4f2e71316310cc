"""The simulation's rim impacts against Routh's closed form (core.puck.impact) and conservation laws."""
import math

import numpy as np
import pytest

from air_hockey_agent.core.puck.impact import rim_impact
from air_hockey_agent.core.table import TableGeometry
from air_hockey_agent.sim.rim_contact import PuckBody, RimContacts, RimLaw, impact_impulse, rim_segments

TABLE = TableGeometry(length=1.956, width=1.042, goal_width=0.25, puck_radius=0.03165)
M, R = 0.01, 0.03165
DISC = PuckBody(R, M, M * R * R / 2)


def contacts(body=DISC, e=0.9, mu=0.1, **law):
    return RimContacts(TABLE, body, RimLaw(e, mu, **law))


def random_approach(rng):
    """Random incoming (vb, vn, omega) with vn < 0, and random e and mu."""
    return (rng.uniform(-2, 2), -rng.uniform(0.05, 3), rng.uniform(-60, 60),
            rng.uniform(0.5, 1.0), rng.uniform(0.0, 0.5))


@pytest.mark.parametrize("wall", ["right", "left", "far", "near"])
def test_a_disc_on_a_straight_rim_gives_rouths_closed_form(wall):
    """Rim frame: b along the rim, n into the table, n = Rz(+90 deg) b (core.puck.impact)."""
    centre, n = {"right": ((0.3, TABLE.y_limit), (0.0, -1.0)), "left": ((-0.2, -TABLE.y_limit), (0.0, 1.0)),
                 "far": ((TABLE.x_limit, 0.4), (-1.0, 0.0)), "near": ((-TABLE.x_limit, -0.4), (1.0, 0.0))}[wall]
    b = (n[1], -n[0])
    rng = np.random.default_rng(1)
    sticking = sliding = 0
    for _ in range(300):
        vb, vn, om, e, mu = random_approach(rng)
        vx, vy = vb * b[0] + vn * n[0], vb * b[1] + vn * n[1]
        # 0.1 mm inside the rim, so the contact is found and the push-out is small
        x, y = centre[0] - 1e-4 * n[0], centre[1] - 1e-4 * n[1]
        _, _, vx2, vy2, om2 = contacts(e=e, mu=mu).resolve(x, y, vx, vy, om)
        ref = rim_impact(vb, vn, om, R, e, mu)
        got = (vx2 * b[0] + vy2 * b[1], vx2 * n[0] + vy2 * n[1], om2)
        assert got == pytest.approx((ref.vb, ref.vn, ref.omega), rel=1e-9, abs=1e-9)
        sliding, sticking = sliding + ref.sliding, sticking + (not ref.sliding)
    assert sliding > 30 and sticking > 30  # both branches exercised


def test_a_restitution_falling_with_the_impact_speed_follows_its_law_and_routhes_closed_form():
    """With rim_restitution_slope (config/sim.yaml) a head-on impact returns e(vn) of its normal speed:
    e up to the knee, then falling linearly, then the floor (numbers worked by hand for e 0.96, knee
    0.5 m/s, slope 0.2 s/m, floor 0.7); an oblique spinning one is Routh's with the same law."""
    law = dict(slope=0.2, floor=0.7, knee=0.5)
    c = contacts(e=0.96, mu=0.1, **law)
    x, y = 0.1, TABLE.y_limit + 1e-4  # 0.1 mm into the right rim: n = (0, -1)
    for speed, e in ((0.4, 0.96), (1.5, 0.76), (3.0, 0.7)):  # 0.96 - 0.2 (1.5 - 0.5) = 0.76; floor at 3 m/s
        _, _, vx, vy, om = c.resolve(x, y, 0.0, speed, 0.0)
        assert (vx, vy, om) == pytest.approx((0.0, -e * speed, 0.0), abs=1e-12)
    ref = rim_impact(0.4, -1.5, 20.0, R, 0.96, 0.1, 0.2, 0.7, 0.0, 0.5)
    _, _, vx, vy, om = c.resolve(x, y, -0.4, 1.5, 20.0)  # b = (-1, 0), n = (0, -1)
    assert (-vx, -vy, om) == pytest.approx((ref.vb, ref.vn, ref.omega), rel=1e-9, abs=1e-9)


def test_a_softer_tangential_impulse_is_the_test_beds_impact():
    """RimLaw.tangential_scale (config/sim.yaml rim_tangential_scale) against the synthetic test bed's
    impact (core/puck/real_table.py real_rim_impact: Routh's closed form with its tangential impulse
    scaled, written apart from this solver), with the test bed's restitution falling from 0.96 at
    0.5 m/s to 0.67 at 2 m/s (= knee 0.5, slope 0.29 / 1.5, floor 0.67)."""
    from air_hockey_agent.core.puck.real_table import TableEffects, real_rim_impact
    effects = TableEffects(restitution_slow=0.96, restitution_fast=0.67, restitution_speed_low=0.5,
                           restitution_speed_high=2.0, friction_rim=0.1, tangential_scale=0.3)
    c = contacts(e=0.96, mu=0.1, slope=0.29 / 1.5, floor=0.67, knee=0.5, tangential_scale=0.3)
    x, y = 0.1, TABLE.y_limit + 1e-4  # 0.1 mm into the right rim: b = (-1, 0), n = (0, -1)
    rng = np.random.default_rng(7)
    for _ in range(200):
        vb, vn, om = rng.uniform(-2, 2), -rng.uniform(0.05, 3), rng.uniform(-60, 60)
        _, _, vx, vy, om2 = c.resolve(x, y, -vb, -vn, om)
        assert (-vx, -vy, om2) == pytest.approx(real_rim_impact(vb, vn, om, R, effects), rel=1e-9, abs=1e-9)


def test_angular_momentum_about_the_contact_point_is_conserved_and_energy_never_grows():
    """The impulse acts at the contact point, so L_c = m (G - c) x v + I omega is conserved; friction
    and restitution e <= 1 can only remove kinetic energy. A ring (I = m r^2) as well as a disc."""
    rng = np.random.default_rng(2)
    for body in (DISC, PuckBody(R, M, M * R * R)):
        for _ in range(200):
            vb, vn, om, e, mu = random_approach(rng)
            x, y = 0.1, TABLE.y_limit + 2e-4  # against the right rim (y = +W/2): n = (0, -1), b = (-1, 0)
            _, _, vx2, vy2, om2 = contacts(body, e, mu).resolve(x, y, -vb, -vn, om)

            def momentum(vx, w):  # G - c = (0, -r): (G - c) x v = r vx
                return body.mass * R * vx + body.inertia * w

            def energy(vx, vy, w):
                return 0.5 * body.mass * (vx * vx + vy * vy) + 0.5 * body.inertia * w * w
            assert momentum(vx2, om2) == pytest.approx(momentum(-vb, om), rel=1e-9, abs=1e-15)
            assert energy(vx2, vy2, om2) <= energy(vb, vn, om) * (1 + 1e-12)


def test_frictionless_elastic_impact_conserves_energy_and_plastic_sticking_impact_stops_the_contact_point():
    k = ((1 / M, 0.0), (0.0, 3 / M))
    elastic = impact_impulse(-1.5, 0.7, k, restitution=1.0, friction=0.0)
    assert elastic.normal == pytest.approx(2 * M * 1.5) and elastic.tangential == 0.0
    plastic = impact_impulse(-1.5, 0.7, k, restitution=0.0, friction=2.0)
    assert plastic.normal == pytest.approx(M * 1.5)  # normal contact speed 0 after
    assert 0.7 + 3 / M * plastic.tangential == pytest.approx(0.0, abs=1e-12) and not plastic.sliding


def test_coupled_contact_where_sticking_cannot_hold_slides_and_still_separates():
    """An off-centre lever arm couples normal and tangential impulse (k_tn != 0); with small friction the
    contact reverses slip direction instead of sticking, and the bodies still separate."""
    k = ((2.0 / M, 1.5 / M), (1.5 / M, 2.0 / M))
    imp = impact_impulse(-1.0, -0.05, k, restitution=0.8, friction=0.2)
    ut_after = -0.05 + k[1][0] * imp.normal + k[1][1] * imp.tangential
    assert imp.sliding and ut_after > 0.0  # the slip reversed and did not stop
    assert abs(imp.tangential) < 0.2 * imp.normal  # friction changed sign with the slip (|P_t| < mu P_n)
    un_after = -1.0 + k[0][0] * imp.normal + k[0][1] * imp.tangential
    assert un_after > 0.0


def test_goal_post_corner_pushes_along_the_line_from_the_corner_to_the_centre():
    corner = (TABLE.length / 2, TABLE.goal_width / 2)
    angle = math.radians(30)
    d = R - 1e-4
    x, y = corner[0] - d * math.cos(angle), corner[1] - d * math.sin(angle)
    speed = 1.0
    x2, y2, vx, vy, _ = contacts(mu=0.0, e=1.0).resolve(x, y, speed * math.cos(angle), speed * math.sin(angle), 0.0)
    assert (vx, vy) == pytest.approx((-speed * math.cos(angle), -speed * math.sin(angle)), abs=1e-12)
    assert math.hypot(x2 - corner[0], y2 - corner[1]) == pytest.approx(R + 1e-4)  # mirrored out


def test_a_puck_through_the_goal_mouth_or_leaving_a_rim_is_untouched():
    c = contacts()
    mouth = (TABLE.length / 2 + 0.01, 0.0, 1.0, 0.2, 3.0)
    assert c.resolve(*mouth) == mouth
    leaving = (0.0, TABLE.y_limit + 1e-3, 0.5, -0.5, 10.0)  # overlaps the right rim, moving away
    assert c.resolve(*leaving) == leaving


def test_rim_segments_outline_the_surface_and_the_goal_openings():
    segs = rim_segments(TABLE)
    ends = {p for s in segs for p in (s.a, s.b)}
    hl, hw, hg = TABLE.length / 2, TABLE.width / 2, TABLE.goal_width / 2
    assert {(hl, hw), (-hl, -hw), (hl, hg), (-hl, -hg)} <= ends
    on_rim = [s for s in segs if s.closest_point(hl, 0.0) == (hl, 0.0)]
    assert not on_rim  # nothing spans the goal opening

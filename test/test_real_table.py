"""The test bed's real-table physics (core/puck/real_table.py), against independent references: the
thesis's Routh impact, closed forms of the flight law and of a tilted surface, and energy."""
import math

import numpy as np
import pytest

from air_hockey_agent.core.estimation.synthetic import (MocapImperfections, MocapSampler, ShotRanges, stepped_state_at,
                                                       synthetic_session)
from air_hockey_agent.core.puck.impact import rim_impact
from air_hockey_agent.core.puck.real_table import RealTablePuck, TableEffects, real_rim_impact
from air_hockey_agent.core.puck.surface_field import GRAVITY
from air_hockey_agent.core.table import TableGeometry

TABLE = TableGeometry(1.956, 1.042, 0.25, 0.03165)  # config/table.yaml
RADIUS = TABLE.puck_radius


def test_constant_restitution_and_full_tangential_impulse_is_the_routh_impact():
    rng = np.random.default_rng(0)
    effects = TableEffects(restitution_slow=0.8, restitution_fast=0.8, friction_rim=0.15, tangential_scale=1.0)
    for _ in range(500):
        vb, vn, omega = rng.uniform(-3, 3), -rng.uniform(0.01, 4), rng.uniform(-60, 60)
        expected = rim_impact(vb, vn, omega, RADIUS, 0.8, 0.15)
        assert real_rim_impact(vb, vn, omega, RADIUS, effects) == pytest.approx(expected[:3], abs=1e-12)


@pytest.mark.parametrize("scale", [0.3, 0.75])
def test_a_scaled_tangential_impulse_is_the_models_tangential_restitution(scale):
    """The test bed scales Routh's stick impulse and Coulomb's bound alike; the model's impact reaches the
    same with beta = scale - 1 and scale x mu_rim (written apart: a check of both)."""
    rng = np.random.default_rng(5)
    effects = TableEffects(restitution_slow=0.8, restitution_fast=0.8, friction_rim=0.15, tangential_scale=scale)
    for _ in range(500):
        vb, vn, omega = rng.uniform(-3, 3), -rng.uniform(0.01, 4), rng.uniform(-60, 60)
        expected = rim_impact(vb, vn, omega, RADIUS, 0.8, scale * 0.15, tangential=scale - 1.0)
        assert real_rim_impact(vb, vn, omega, RADIUS, effects) == pytest.approx(expected[:3], abs=1e-12)


def test_restitution_falls_linearly_between_its_speeds():
    effects = TableEffects(restitution_slow=0.96, restitution_fast=0.67, restitution_speed_low=0.5,
                           restitution_speed_high=2.0)
    assert effects.restitution(0.2) == 0.96 and effects.restitution(3.0) == 0.67
    assert effects.restitution(1.25) == pytest.approx((0.96 + 0.67) / 2)
    _, vn_slow, _ = real_rim_impact(0.0, -0.3, 0.0, RADIUS, effects)
    _, vn_fast, _ = real_rim_impact(0.0, -3.0, 0.0, RADIUS, effects)
    assert vn_slow == pytest.approx(0.96 * 0.3) and vn_fast == pytest.approx(0.67 * 3.0)


def test_a_softer_tangential_impulse_changes_less_and_energy_never_grows():
    rng = np.random.default_rng(1)
    soft = TableEffects(restitution_slow=0.9, restitution_fast=0.6, friction_rim=0.3, tangential_scale=0.3)
    full = TableEffects(restitution_slow=0.9, restitution_fast=0.6, friction_rim=0.3, tangential_scale=1.0)
    for _ in range(500):
        vb, vn, omega = rng.uniform(-3, 3), -rng.uniform(0.01, 4), rng.uniform(-60, 60)
        energy = vb ** 2 + vn ** 2 + RADIUS ** 2 * omega ** 2 / 2  # per unit mass x2: disc, I = m r^2 / 2
        for effects in (soft, full):
            b, n, w = real_rim_impact(vb, vn, omega, RADIUS, effects)
            assert b ** 2 + n ** 2 + RADIUS ** 2 * w ** 2 / 2 <= energy + 1e-12
        assert abs(real_rim_impact(vb, vn, omega, RADIUS, soft)[0] - vb) == pytest.approx(
            0.3 * abs(real_rim_impact(vb, vn, omega, RADIUS, full)[0] - vb), abs=1e-12)


def test_flight_follows_the_closed_form_of_damping_and_constant_deceleration():
    # dv/dt = -d v - mu along a straight line: v(t) = (v0 + mu/d) exp(-d t) - mu/d until it stops
    effects = TableEffects(damping=0.2, friction_surface=0.05)
    puck = RealTablePuck(TABLE, effects, np.random.default_rng(2))
    _, states = puck.simulate(np.array([-0.5, 0.0, 0.6, 0.0, 0.0, 0.0]), 1.0, 1e-4)
    v_closed = (0.6 + 0.05 / 0.2) * math.exp(-0.2) - 0.05 / 0.2
    assert states[-1, 2] == pytest.approx(v_closed, rel=1e-3)
    assert states[-1, 3] == 0.0


def test_a_tilted_surface_accelerates_a_free_puck_by_g_sin_tilt_and_friction_holds_a_resting_one():
    tilt = 0.003
    puck = RealTablePuck(TABLE, TableEffects(tilt=tilt, tilt_heading=math.pi / 2), np.random.default_rng(3))
    _, states = puck.simulate(np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.0]), 1.0, 1e-3)
    assert states[-1, 3] == pytest.approx(GRAVITY * math.sin(tilt) * 1.0, rel=1e-2)
    assert states[-1, 1] == pytest.approx(GRAVITY * math.sin(tilt) / 2, rel=2e-2)
    held = RealTablePuck(TABLE, TableEffects(tilt=tilt, friction_surface=0.05), np.random.default_rng(3))
    _, still = held.simulate(np.zeros(6), 1.0, 1e-3)
    assert np.all(still[:, :4] == 0.0)


def test_rims_keep_the_puck_on_the_table_and_a_goal_mouth_lets_it_through():
    effects = TableEffects(restitution_slow=0.96, restitution_fast=0.67, tangential_scale=0.3, friction_rim=0.1)
    puck = RealTablePuck(TABLE, effects, np.random.default_rng(4))
    _, states = puck.simulate(np.array([0.0, 0.3, 1.0, 3.0, 0.0, 0.0]), 2.0, 1e-3)
    assert np.all(np.abs(states[:, 1]) <= TABLE.y_limit + 1e-9) and np.all(np.abs(states[:, 0]) <= TABLE.x_limit)
    _, into_goal = puck.simulate(np.array([0.5, 0.0, 3.0, 0.0, 0.0, 0.0]), 0.5, 1e-3)
    assert into_goal[-1, 0] > TABLE.x_limit
    # in through the mouth at an angle, then sideways beyond the mouth's width inside the goal: it stays in
    _, slanted = puck.simulate(np.array([0.85, 0.0, 2.0, 1.0, 0.0, 0.0]), 0.5, 1e-3)
    inside = np.flatnonzero(slanted[:, 0] > TABLE.x_limit)
    assert inside.size and abs(slanted[-1, 1]) > TABLE.goal_mouth and np.all(slanted[inside[0]:, 0] > TABLE.x_limit)


def test_a_human_hit_moves_a_resting_puck_at_its_time():
    puck = RealTablePuck(TABLE, TableEffects(), np.random.default_rng(5))
    times, states = puck.simulate(np.array([0.1, 0.2, 0.0, 0.0, 0.0, 0.0]), 1.0, 1e-3, 0.4, np.array([1.0, 0.0]))
    before, after = states[times < 0.399], states[times > 0.401]
    assert np.all(before[:, :4] == [0.1, 0.2, 0.0, 0.0])
    assert after[-1, 0] == pytest.approx(0.1 + 1.0 * 0.6, abs=2e-3)


def test_a_hit_that_pushes_brings_the_puck_to_its_speed_evenly():
    """testbed.hit_duration: a 10 ms push to 1 m/s raises the speed evenly in 1 ms steps (5.5 mm covered in
    them where the impulse covers 10), then the puck flies as after an impulse, 4.5 mm behind."""
    start, velocity = np.array([0.1, 0.2, 0.0, 0.0, 0.0, 0.0]), np.array([1.0, 0.0])
    impulse = RealTablePuck(TABLE, TableEffects(), np.random.default_rng(5)).simulate(start, 1.0, 1e-3, 0.4, velocity)
    pushed = RealTablePuck(TABLE, TableEffects(hit_duration=0.01), np.random.default_rng(5)).simulate(
        start, 1.0, 1e-3, 0.4, velocity)
    times = pushed[0]
    speeds = pushed[1][(times > 0.3995) & (times < 0.4115), 2]  # from 0.400 s: the push's steps, then full speed
    assert speeds == pytest.approx([0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0, 1.0, 1.0, 1.0], abs=1e-3)
    assert pushed[1][np.searchsorted(times, 0.409), 0] - 0.1 == pytest.approx(0.0055, abs=1e-6)
    after = times > 0.42
    assert pushed[1][after, 2] == pytest.approx(impulse[1][after, 2], abs=1e-9)
    assert impulse[1][after, 0] - pushed[1][after, 0] == pytest.approx(np.full(after.sum(), 0.0045), abs=1e-6)


def test_marker_noise_grows_with_speed():
    noise = MocapImperfections(position_std=1e-4, position_std_per_speed=4e-4, angle_std=0.0, jitter_std=0.0)
    sampler = MocapSampler(noise, np.random.default_rng(6))
    resting = np.array([sampler.sample(k / 120, lambda _t: (0.0, 0.0, 0.0, 0.0))[1][0] for k in range(4000)])
    fast = np.array([sampler.sample(k / 120, lambda _t: (0.0, 0.0, 0.0, 3.0))[1][0] for k in range(4000)])
    assert np.std(resting) == pytest.approx(1e-4, rel=0.05)
    assert np.std(fast) == pytest.approx(math.hypot(1e-4, 3.0 * 4e-4), rel=0.05)


def test_between_its_samples_the_truth_is_the_test_beds_own_step_cut_short():
    """stepped_state_at (the truth at a mocap stamp between the test bed's 1 ms samples) equals the test
    bed's own step from the sample before, cut at the stamp (to what a shorter step's velocity changes:
    dt' (dt - dt') |a| <= dt^2 |a| / 4, below 1e-7 m at |a| < 0.4 m/s^2), in flight on a tilted, filmy table;
    the angle wraps across pi."""
    effects = TableEffects(tilt=0.01, random_acceleration=0.0)
    puck = RealTablePuck(TABLE, effects, np.random.default_rng(3))
    times, states = puck.simulate(np.array([0.0, 0.0, 0.8, 0.3, 3.1, 20.0]), 0.2, 1e-3)
    wrap = int(np.flatnonzero(np.abs(np.diff(states[:, 4])) > math.pi)[0])  # the step the angle wraps in
    rng = np.random.default_rng(4)
    for t in [times[wrap] + 5e-4, *rng.uniform(0.0, 0.2, 200)]:
        i = int(t / 1e-3)
        own = puck.step(states[i], times[i], t - times[i])
        truth = stepped_state_at(times, states, t)
        assert truth[:2] == pytest.approx(own[:2], abs=1e-7)
        assert abs(math.remainder(truth[4] - own[4], 2 * math.pi)) < 1e-12
    assert np.array_equal(stepped_state_at(times, states, times[7]), states[7])


def test_a_test_bed_session_takes_no_step_of_the_trackers_model(monkeypatch):
    """With the test bed as the truth, the puck model is never stepped: not even between samples."""
    from air_hockey_agent.core.puck.model import PuckModel, PuckParams
    from air_hockey_agent.core.puck.real_table import testbed_shots

    def forbidden(*_args, **_kwargs):
        raise AssertionError("the tracker's model was stepped")
    monkeypatch.setattr(PuckModel, "step", forbidden)
    model = PuckModel(TABLE, PuckParams(0.0, 0.125, 1.0, 0.1))
    shots = ShotRanges(speed=(0.5, 2.0), spin=(-5.0, 5.0), duration=1.5, pause=0.2)
    rng = np.random.default_rng(8)
    frames = synthetic_session(model, shots, 3, 120.0, MocapImperfections(jitter_std=2e-4), rng, 1e-3,
                               testbed_shots(TableEffects(), TABLE, (0.3, 0.6), 1e-3, rng))
    assert len(frames) > 300 and any(f.measurement is not None for f in frames)


def test_a_post_returns_a_puck_along_the_line_from_it_and_a_clear_puck_scores():
    """The posts (the short rims' ends beside a goal opening): a spinless puck flying at a post along the
    line from the post to its centre comes straight back with the restitution (no tangential impulse);
    a steep puck inside the mouth (70 deg) and one grazing a post (y = 0.11, along x) come back out, the
    grazing one also pushed away from the post in y; a puck through the middle scores. Energy never grows."""
    effects = TableEffects(restitution_slow=0.8, restitution_fast=0.8, friction_rim=0.15, tangential_scale=1.0)
    half_l, post = TABLE.length / 2, TABLE.goal_width / 2

    def run(state, duration=0.3):
        puck = RealTablePuck(TABLE, effects, np.random.default_rng(0))
        return puck.simulate(np.array(state, float), duration, 1e-4)[1]

    u = np.array([math.cos(math.radians(30)), math.sin(math.radians(30))])  # from the post into the table
    start = np.array([half_l, -post]) + (RADIUS + 0.05) * np.array([-u[0], u[1]])  # left of the lower post
    head_on = run([*start, 1.5 * u[0], -1.5 * u[1], 0.0, 0.0])
    assert head_on[-1, 2:4] == pytest.approx(-0.8 * 1.5 * np.array([u[0], -u[1]]), abs=1e-9)
    assert head_on[-1, 5] == pytest.approx(0.0, abs=1e-9)
    steep = run([half_l - RADIUS - 0.02, 0.0, 0.7, 1.9, 0.0, 0.0])
    assert steep[-1, 2] < 0.0 and abs(steep[-1, 0]) < half_l
    grazing = run([half_l - 0.2, 0.11, 2.0, 0.0, 0.0, 0.0])
    assert grazing[-1, 2] < 0.0 and grazing[-1, 3] < 0.0
    middle = run([half_l - 0.2, 0.0, 2.0, 0.0, 0.0, 0.0])
    assert middle[-1, 0] > half_l + RADIUS
    for states in (head_on, steep, grazing):
        energy = states[:, 2] ** 2 + states[:, 3] ** 2 + 0.5 * RADIUS ** 2 * states[:, 5] ** 2  # disc: I = m r^2/2
        assert np.all(np.diff(energy) <= 1e-12)


def test_a_hand_carries_the_puck_on_a_minimum_jerk_path_and_holds_it_still():
    """A carry (HandCarry.draw's tuple) takes the puck where it is, stops it, slides it to the target along
    the minimum-jerk path, then holds it: positions and velocities against the closed form (peak speed
    1.875 D / T halfway) and against the positions' finite differences; before the carry the shot is the
    one without it; the angle turns the short way."""
    from air_hockey_agent.core.puck.real_table import HandCarry, minimum_jerk
    start = np.array([0.2, -0.1, 0.0, 0.0, 3.0, 0.0])
    velocity = np.array([-1.0, 0.4])
    target = np.array([-0.5, 0.3, -3.0])
    dt, carry_at, carry_time = 1e-3, 1.2, 1.5

    def run(carry):
        return RealTablePuck(TABLE, TableEffects(damping=0.1), np.random.default_rng(2)).simulate(
            start, 3.5, dt, 0.3, velocity, carry)
    times, free = run(None)
    _, carried = run((carry_at, carry_time, target))
    grab = int(round(carry_at / dt)) - 1
    assert np.array_equal(carried[:grab + 1], free[:grab + 1])
    end = grab + int(round(carry_time / dt))
    assert carried[end, :2] == pytest.approx(target[:2], abs=1e-12)
    assert np.all(carried[end:, 2:4] == pytest.approx(0.0, abs=1e-12))
    assert np.allclose(carried[end:, :2], target[:2], rtol=0.0, atol=1e-12)
    assert abs(math.remainder(carried[end, 4] - target[2], 2 * math.pi)) < 1e-9
    turned = float(np.sum(carried[grab + 1:end + 1, 5]) * dt)  # the short way: 3.0 -> -3.0 across pi is 0.28 rad
    assert turned == pytest.approx(2 * math.pi - 6.0, abs=1e-3)
    middle = grab + int(round(carry_time / 2 / dt))
    distance = math.dist(carried[grab, :2], target[:2])
    assert math.hypot(*carried[middle, 2:4]) == pytest.approx(1.875 * distance / carry_time, rel=1e-6)
    finite = np.diff(carried[grab + 1:end + 1, :2], axis=0) / dt
    mean_velocity = 0.5 * (carried[grab + 1:end, 2:4] + carried[grab + 2:end + 1, 2:4])
    assert np.max(np.abs(finite - mean_velocity)) < 1e-5
    pose, rate = minimum_jerk(np.zeros(1), np.ones(1), 0.0, 2.0)
    assert pose[0] == 0.0 and rate[0] == 0.0
    assert not HandCarry().enabled and HandCarry((1.0, 2.0), 0.5).enabled


def test_a_carry_is_drawn_within_the_shot_and_the_table():
    """HandCarry.draw: the carry ends hold seconds before the shot does, its target lies margin inside the
    rims; a carry longer than the shot starts at its beginning."""
    from air_hockey_agent.core.puck.real_table import HandCarry
    carry, rng = HandCarry((1.0, 2.0), 0.5), np.random.default_rng(4)
    for _ in range(200):
        start, time, target = carry.draw(TABLE, 7.0, rng)
        assert 1.0 <= time <= 2.0 and start + time + 0.5 == pytest.approx(7.0)
        assert abs(target[0]) <= TABLE.x_limit - 0.1 and abs(target[1]) <= TABLE.y_limit - 0.1
    assert HandCarry((5.0, 5.0), 0.5).draw(TABLE, 3.0, rng)[0] == 0.0


def test_another_engines_shots_end_in_the_same_carry():
    """with_hand_carries ends any engine's shot (here a straight line at 0.5 m/s, standing in for one) in the
    hand's carry drawn as the test bed draws it: up to the grab the engine's states, from it the carry's,
    ending still at the target; without a carry the simulator itself comes back."""
    from air_hockey_agent.core.puck.real_table import HandCarry, carried_state, with_hand_carries

    def straight(state, duration):
        times = np.arange(0.0, duration + 1e-9, 1e-3)
        states = np.tile(np.asarray(state, float), (len(times), 1))
        states[:, 0] += 0.5 * times
        states[:, 2] = 0.5
        return times, states
    carry = HandCarry((1.0, 1.5), 0.5)
    start, time, target = carry.draw(TABLE, 4.0, np.random.default_rng(7))
    times, states = with_hand_carries(straight, TABLE, carry, np.random.default_rng(7))(np.zeros(6), 4.0)
    grab = int(np.searchsorted(times, start))
    assert np.array_equal(states[:grab], straight(np.zeros(6), 4.0)[1][:grab])
    assert np.allclose(states[grab + 10], carried_state(states[grab - 1], target, times[grab + 10] - times[grab - 1], time))
    assert np.allclose(states[-1, :2], target[:2]) and np.allclose(states[-1, 2:4], 0.0)
    assert with_hand_carries(straight, TABLE, HandCarry(), np.random.default_rng(7)) is straight

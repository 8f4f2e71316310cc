"""The surface's own push (core/puck/surface_field.py) against its formula written out and a brute-force
maximum."""
import math

import numpy as np
import pytest

from air_hockey_agent.core.puck.surface_field import SurfaceField, tilt_acceleration


def test_a_tilt_pushes_by_g_sin_tilt_toward_its_heading_everywhere():
    field = SurfaceField(tilt=0.01, tilt_heading=-math.pi / 2)
    for x, y in ((0.0, 0.0), (0.7, -0.3)):
        assert field.at(x, y) == pytest.approx((0.0, -9.81 * math.sin(0.01)), abs=1e-12)
    assert tilt_acceleration(0.0, 1.0) == (0.0, 0.0) and SurfaceField().is_zero and not field.is_zero


def test_the_air_film_is_a_wave_across_the_track_of_each_component():
    field = SurfaceField(air_film_amplitude=0.02, air_film_wavelength=0.4, air_film_phase=(0.5, -1.5))
    k = 2 * math.pi / 0.4
    assert field.at(0.3, -0.2) == pytest.approx((0.02 * math.sin(-0.2 * k + 0.5), 0.02 * math.sin(0.3 * k - 1.5)))
    assert field.at(0.3, -0.2)[0] == pytest.approx(field.at(-0.6, -0.2)[0])  # x-push depends on y only
    assert field.at(0.3, 0.0)[0] != pytest.approx(field.at(0.3, 0.1)[0])


@pytest.mark.parametrize("tilt, heading, amplitude", [(0.002, 1.5708, 0.01), (0.003, 2.5, 0.02), (0.0, 0.0, 0.01)])
def test_max_push_is_the_largest_push_anywhere(tilt, heading, amplitude):
    field = SurfaceField(tilt, heading, amplitude, 0.5, (1.0, 2.0))
    grid = np.linspace(-2.0, 2.0, 801)  # four wavelengths each way: every pair of phases of the two sines
    pushes = [math.hypot(*field.at(x, y)) for x in grid[::4] for y in grid]
    assert max(pushes) == pytest.approx(field.max_push, rel=1e-3)
    assert max(pushes) <= field.max_push + 1e-15


def test_a_random_push_holds_each_draw_for_its_time_and_has_its_std():
    """RandomPush: constant over ``hold``, a new draw at the first time at or after its end, zero-mean with the
    configured std per axis (2000 draws: the sample std within 5 %); std 0 never draws."""
    from air_hockey_agent.core.puck.surface_field import RandomPush
    push = RandomPush(0.02, 0.09, np.random.default_rng(3))
    times = np.arange(8000) * 0.025  # a draw at every fourth sample (the first at or after its hold's end)
    values = np.array([push.at(t).copy() for t in times])
    assert np.all(values[1::4] == values[0::4]) and np.all(values[3::4] == values[0::4])
    draws = values[0::4]
    assert np.all(np.any(draws[1:] != draws[:-1], axis=1))  # a new value every hold
    assert draws.std(axis=0) == pytest.approx([0.02, 0.02], rel=0.05)
    assert np.all(np.abs(draws.mean(axis=0)) < 4 * 0.02 / math.sqrt(len(draws)))
    rng = np.random.default_rng(3)
    state = rng.bit_generator.state
    assert not RandomPush(0.0, 0.1, rng).at(5.0).any() and rng.bit_generator.state == state

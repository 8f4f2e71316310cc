"""Frame conversions round-trip and follow the conventions of README "Frames and units"."""
import math

import numpy as np
import pytest

from air_hockey_agent.core.frames import (mocap_to_table, quaternion_from_yaw, robot_to_table, table_to_mocap,
                                          table_to_robot, yaw_from_quaternion)


def test_mocap_table_round_trip():
    rng = np.random.default_rng(0)
    for _ in range(100):
        pose = (*rng.uniform(-2, 2, 3), rng.uniform(-math.pi, math.pi))
        p = tuple(rng.uniform(-1, 1, 2)) + (rng.uniform(-3, 3),)
        back = table_to_mocap(*mocap_to_table(*p, pose), pose)
        assert back[:2] == pytest.approx(p[:2])
        assert math.remainder(back[2] - p[2], 2 * math.pi) == pytest.approx(0.0, abs=1e-12)


def test_thesis_table_centre_maps_to_origin():
    assert mocap_to_table(1.504, 0.0, 0.2, (1.504, 0.0, 0.0, 0.0)) == pytest.approx((0.0, 0.0, 0.2))


def test_back_robot_sees_the_table_rotated_by_pi():
    assert table_to_robot(0.5, 0.2, 0.1, "iiwa_back") == pytest.approx((-0.5, -0.2, 0.1 - math.pi))
    assert table_to_robot(0.5, 0.2, 0.1, "iiwa_front") == pytest.approx((0.5, 0.2, 0.1))
    assert robot_to_table(*table_to_robot(0.5, 0.2, 0.1, "iiwa_back"), "iiwa_back") == pytest.approx((0.5, 0.2, 0.1))


def test_quaternion_yaw_round_trip():
    for yaw in np.linspace(-3.1, 3.1, 13):
        assert yaw_from_quaternion(*quaternion_from_yaw(yaw)) == pytest.approx(yaw)

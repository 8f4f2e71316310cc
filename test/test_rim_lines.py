"""Where the rims are (core/identification/rim_lines.py): the table's centre and size from the offsets of
its rims' impacts, their errors from the offsets' covariance, and the tracker parameters that move the
model's rims there."""
import math
from types import SimpleNamespace

import numpy as np
import pytest

from air_hockey_agent.core.identification.impact_fit import DelayFit, fit_delay
from air_hockey_agent.core.identification.preprocess import GridTrajectory
from air_hockey_agent.core.identification.rim_lines import corrected_geometry, recentred, rim_lines
from air_hockey_agent.core.table import WALL_FAR, WALL_LEFT, WALL_NEAR, WALL_RIGHT

BOUNDS = (-0.02, 0.02)       # [m]
YAW_BOUNDS = (-0.02, 0.02)   # [rad]


def delay_fit(offsets: dict, variance: float = 1e-8, yaw: tuple = (0.0, 1e-4)) -> DelayFit:
    """Independent offsets (rim -> m, > 0 inside), each with ``variance`` [m^2], and a yaw (value, std) [rad]."""
    cov = {(a, b): (variance if a == b else 0.0) for a in offsets for b in offsets}
    return DelayFit(0.0, 0.0, 0.0, {w: (o, math.sqrt(variance)) for w, o in offsets.items()}, 100, cov, yaw)


def test_a_table_frame_off_sideways_and_a_table_longer_than_configured():
    """The table frame 3 mm off toward +y: the left rim (y = -W/2) is met 3 mm beyond its line, the right one
    3 mm inside; a table 4 mm longer: both short rims 2 mm beyond."""
    lines = rim_lines(delay_fit({WALL_LEFT: -0.003, WALL_RIGHT: 0.003, WALL_FAR: -0.002, WALL_NEAR: -0.002}), 3.0,
                      BOUNDS, YAW_BOUNDS)
    assert lines.values["centre_y"] == pytest.approx(-0.003) and lines.values["centre_x"] == pytest.approx(0.0)
    assert lines.values["length"] == pytest.approx(0.004) and lines.values["width"] == pytest.approx(0.0)
    assert lines.taken == {"centre_x": False, "centre_y": True, "length": True, "width": False, "yaw": False}
    # a part's error from the two offsets' (independent here): half their root sum of squares, or the whole
    assert lines.std["centre_y"] == pytest.approx(math.sqrt(2e-8) / 2)
    assert lines.std["length"] == pytest.approx(math.sqrt(2e-8))
    assert lines.centre() == pytest.approx((0.0, -0.003))


def test_the_parts_errors_come_from_the_offsets_covariance():
    """Offsets moving together (a shared delay's error) leave the centre certain and the size not."""
    offsets = {WALL_LEFT: 0.001, WALL_RIGHT: 0.001}
    fit = DelayFit(0.0, 0.0, 0.0, {w: (o, 1e-4) for w, o in offsets.items()}, 50,
                   {(a, b): (1e-8 if a == b else 0.9e-8) for a in offsets for b in offsets})
    lines = rim_lines(fit, 3.0, BOUNDS, YAW_BOUNDS)
    assert lines.std["centre_y"] == pytest.approx(math.sqrt((1e-8 + 1e-8 - 2 * 0.9e-8) / 4))
    assert lines.std["width"] == pytest.approx(math.sqrt(1e-8 + 1e-8 + 2 * 0.9e-8))


def test_what_is_not_taken():
    """Within the noise, beyond the bounds, a rim pair not met, a centre the poses' transform fixes."""
    noisy = rim_lines(delay_fit({WALL_LEFT: 0.0002, WALL_RIGHT: -0.0002}, variance=1e-8), 3.0, BOUNDS, YAW_BOUNDS)
    assert not noisy.any_taken and not any(noisy.beyond.values())
    far = rim_lines(delay_fit({WALL_LEFT: -0.03, WALL_RIGHT: 0.03}), 3.0, BOUNDS, YAW_BOUNDS)
    assert far.beyond["centre_y"] and not far.taken["centre_y"] and far.centre() == (0.0, 0.0)
    one_short = rim_lines(delay_fit({WALL_LEFT: 0.001, WALL_RIGHT: 0.001, WALL_FAR: 0.003}), 3.0, BOUNDS,
                          YAW_BOUNDS)
    assert math.isnan(one_short.values["length"]) and not one_short.taken["length"] and one_short.taken["width"]
    fixed = rim_lines(delay_fit({WALL_LEFT: -0.003, WALL_RIGHT: 0.001}, yaw=(0.003, 1e-4)), 3.0, BOUNDS, YAW_BOUNDS,
                      centre=False)
    assert not fixed.taken["centre_y"] and fixed.taken["width"] and fixed.centre() == (0.0, 0.0) and fixed.yaw() == 0
    turned = rim_lines(delay_fit({WALL_LEFT: 0.0}, yaw=(0.05, 1e-4)), 3.0, BOUNDS, YAW_BOUNDS)
    assert turned.beyond["yaw"] and turned.yaw() == 0.0


@pytest.mark.parametrize("yaw", [0.0, math.pi / 2, -0.3])
def test_the_corrected_pose_puts_the_table_origin_at_the_rims_centre(yaw):
    """The moved pose's origin is the rims' centre: a mocap point there reads (0, 0) in the new table frame
    and the old frame's reading minus the centre anywhere else; the size changes by the parts found."""
    from air_hockey_agent.core.frames import mocap_to_table, table_to_mocap
    tracker = {"mocap_table_pose": [1.5, 0.2, 0.01, yaw], "table.length": 1.956, "table.width": 1.042}
    turn = 0.004  # [rad]
    lines = rim_lines(delay_fit({WALL_LEFT: -0.003, WALL_RIGHT: 0.004, WALL_FAR: -0.002, WALL_NEAR: 0.004},
                                yaw=(turn, 1e-4)), 3.0, BOUNDS, YAW_BOUNDS)
    new = corrected_geometry(tracker, lines)
    assert new["table.length"] == pytest.approx(1.956 - 0.002) and new["table.width"] == pytest.approx(1.042 - 0.001)
    assert new["mocap_table_pose"][2] == 0.01 and new["mocap_table_pose"][3] == pytest.approx(yaw + turn)
    cx, cy = lines.centre()
    assert (cx, cy) == pytest.approx((0.003, -0.0035)) and lines.yaw() == turn
    for x, y in ((0.3, -0.2), (-0.9, 0.45)):  # the new frame: the old one's reading moved by the centre and turned
        mx, my, _ = table_to_mocap(x, y, 0.0, tracker["mocap_table_pose"])
        nx, ny, _ = mocap_to_table(mx, my, 0.0, new["mocap_table_pose"])
        c, s = math.cos(turn), math.sin(turn)
        assert (nx, ny) == pytest.approx((c * (x - cx) + s * (y - cy), -s * (x - cx) + c * (y - cy)), abs=1e-12)
        moved = recentred(GridTrajectory(0.0, 0.01, np.array([[x, y, 0.1]])), (cx, cy), turn)
        assert moved.z[0] == pytest.approx([nx, ny, 0.1 - turn], abs=1e-12)
    fixed = rim_lines(delay_fit({WALL_LEFT: -0.003, WALL_RIGHT: 0.004}, yaw=(turn, 1e-4)), 3.0, BOUNDS, YAW_BOUNDS,
                      centre=False)
    assert corrected_geometry(tracker, fixed) == {"table.width": pytest.approx(1.042 - 0.001)}
    assert corrected_geometry(tracker, rim_lines(delay_fit({WALL_LEFT: 0.0}), 3.0, BOUNDS, YAW_BOUNDS)) == {}


def test_recentring_copies_and_leaves_the_input_alone():
    z = np.array([[0.1, 0.2, 0.3], [np.nan, np.nan, np.nan], [0.2, 0.25, 0.31]])
    traj = GridTrajectory(5.0, 1 / 120, z.copy())
    moved = recentred(traj, (0.001, -0.002))
    assert np.array_equal(traj.z, z, equal_nan=True)
    assert moved.t0 == 5.0 and moved.dt == traj.dt
    assert moved.z[0] == pytest.approx([0.099, 0.202, 0.3]) and np.isnan(moved.z[1]).all()


def test_the_offsets_are_where_the_model_delay_puts_the_rims():
    """Paths meeting 1 ms x speed inside a rigid model's lines (a stiff simulator's overshoot): the free fit
    says -1 ms; at the model's delay (the bound 0, or 0 as known) each rim's offset is its mean depth, and a
    known delay gives the offsets at it."""
    speeds = np.linspace(0.3, 2.5, 12)
    rng = np.random.default_rng(1)
    impacts = []
    for wall, offset in ((WALL_LEFT, 0.002), (WALL_RIGHT, -0.001)):
        impacts += [_impact(wall, v, offset + 0.001 * v + rng.normal(0, 1e-5)) for v in speeds]
    free = fit_delay(impacts, (-1.0, 1.0), 10.0)
    assert free.value == pytest.approx(-0.001, abs=2e-5)
    assert free.offsets[WALL_LEFT][0] == pytest.approx(0.002, abs=2e-5)
    clamped = fit_delay(impacts, (0.0, 0.01), 10.0)
    assert clamped.value == 0.0 and clamped.fitted == pytest.approx(-0.001, abs=2e-5)
    for wall, offset in ((WALL_LEFT, 0.002), (WALL_RIGHT, -0.001)):
        assert clamped.offsets[wall][0] == pytest.approx(offset + 0.001 * speeds.mean(), abs=2e-5)
    known = fit_delay(impacts, (0.0, 0.01), 10.0, known=0.0005)
    assert known.value == 0.0005 and known.std == 0.0
    assert known.offsets[WALL_LEFT][0] == pytest.approx(0.002 + 0.0015 * speeds.mean(), abs=2e-5)
    assert known.covariance[(WALL_LEFT, WALL_RIGHT)] == pytest.approx(0.0, abs=1e-15)  # apart when the delay is fixed


def test_a_turned_table_shows_as_offsets_growing_along_every_rim():
    """A table turned by 3 mrad from the model's: each rim's paths meet 3 mrad x (position along the rim, b =
    (n_y, -n_x)) inside its line (the left rim's at +x, the far one's at +y, ...); fit_delay finds the turn
    with the offsets at the rims' middles."""
    rng = np.random.default_rng(2)
    impacts = []
    for wall in (WALL_LEFT, WALL_FAR, WALL_RIGHT, WALL_NEAR):
        for along in rng.uniform(-0.8 if wall in (WALL_LEFT, WALL_RIGHT) else -0.4, 0.8, 25):
            impacts.append(_impact(wall, rng.uniform(0.3, 2.0), 0.001 * (wall == WALL_LEFT) + 0.003 * along
                                   + rng.normal(0, 5e-5), along))
    fit = fit_delay(impacts, (0.0, 0.01), 10.0)
    assert fit.yaw[0] == pytest.approx(0.003, abs=3 * fit.yaw[1]) and fit.yaw[1] < 2e-4
    assert fit.offsets[WALL_LEFT][0] == pytest.approx(0.001, abs=1e-4) and abs(fit.offsets[WALL_FAR][0]) < 1e-4


def _impact(wall: int, speed: float, depth: float, along: float = 0.0) -> SimpleNamespace:
    """What fit_delay reads of an impact: its rim, incoming (tangential, normal < 0, spin), meeting depth and
    where along the rim."""
    return SimpleNamespace(wall=wall, before=(0.0, -speed, 0.0), depth=depth, along=along)


def test_the_sysid_report_of_a_rim_pair_not_met_is_null_and_readable():
    """Impacts on the long rims only: the length and the centre along x are unknown; sysid's --json gives
    them as null (strict JSON, no NaN) and its report line and warnings print "?" for them."""
    import json
    from air_hockey_agent.tools.sysid import _geometry_report
    from air_hockey_agent.tools.sysid_report import geometry_text, geometry_warnings
    fit = delay_fit({WALL_LEFT: -0.003, WALL_RIGHT: 0.003})
    lines = rim_lines(fit, 3.0, BOUNDS, YAW_BOUNDS, centre=False)
    split = SimpleNamespace(rim_lines=lines, first_delay=fit, geometry={})
    tracker = {"mocap_table_pose": [1.504, 0.0, 0.0, 0.0], "table.length": 1.956, "table.width": 1.042}
    report = {**_geometry_report(split, tracker, posed=False), "read_without_table_frame": False}
    text = json.dumps(report, allow_nan=False)
    assert json.loads(text)["values_m"]["length"] is None and json.loads(text)["values_m"]["centre_x"] is None
    assert "length ? +- ? mm" in geometry_text(report)
    warned = geometry_warnings(report, {"split.significance": 3.0, "bounds.table_geometry": BOUNDS})
    assert len(warned) == 1 and "(?, -3.00) mm" in warned[0]

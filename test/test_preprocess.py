"""Preprocessing (thesis algorithm 2 and sec. 4.5.1) on hand-made streams with known answers."""
import math

import numpy as np
import pytest

from air_hockey_agent.core.identification.preprocess import (GridTrajectory, _gridded_pieces, cut_rest, grid_glitches,
                                                             interpolate_frozen, preprocess, split_trajectories,
                                                             to_model_grid)

DT = 1 / 120


def test_grid_inserts_blanks_for_lost_frames_and_drops_duplicates():
    stamps = [0.0, DT + 1e-4, 3 * DT - 2e-4, 3 * DT + 1e-3, 4 * DT]  # frame 2 lost, frame 3 twice
    z = [[0.0, 0, 0], [0.01, 0, 0], [0.03, 0, 0], [0.031, 0, 0], [0.04, 0, 0]]
    grid = to_model_grid(stamps, z, DT)
    assert len(grid) == 5 and grid.t0 == 0.0
    assert np.isnan(grid.z[2, 0])
    assert grid.z[3, 0] == 0.03  # the nearer of the two
    assert grid.measured() == 4


def test_unsorted_stamps_and_lost_poses_are_handled():
    grid = to_model_grid([2 * DT, 0.0, DT], [[2, 0, 0], [0, 0, 0], None], DT)
    assert grid.z[0, 0] == 0 and np.isnan(grid.z[1, 0]) and grid.z[2, 0] == 2


def test_frozen_frames_are_interpolated():
    z = np.array([[0.0, 0, 0.0], [0.01, 0, 0.1], [0.01, 0, 0.1], [0.03, 0, 0.3]])
    traj = GridTrajectory(0.0, DT, z)
    assert interpolate_frozen(traj, 1e-6) == 1
    assert traj.z[2] == pytest.approx([0.02, 0.0, 0.2])


def test_frozen_angle_interpolation_wraps():
    z = np.array([[0.0, 0, math.pi - 0.1], [0.0, 0, math.pi - 0.1], [0.02, 0, -math.pi + 0.1]])
    z[1, 0] = 0.0  # frozen copy of row 0
    traj = GridTrajectory(0.0, DT, z)
    interpolate_frozen(traj, 1e-6)
    assert abs(math.remainder(traj.z[1, 2] - math.pi, 2 * math.pi)) < 1e-9


def test_split_at_long_gaps_and_cut_rest():
    n = 400
    x = np.concatenate([np.zeros(100), np.linspace(0, 1.0, 200), np.full(100, 1.0)])  # rest, move, rest
    z = np.column_stack([x, np.zeros(n), np.zeros(n)])
    z = np.vstack([z, np.full((300, 3), np.nan), z])  # 2.5 s without frames between two recordings
    pieces = split_trajectories(GridTrajectory(10.0, DT, z), max_gap=1.0)
    assert len(pieces) == 2 and pieces[1].t0 == pytest.approx(10.0 + 700 * DT)
    cut = cut_rest(pieces[0], rest_speed=0.05, window=0.1)  # window = 12 steps
    # the motion (rows 100-299) is kept from its first moved frame (the start, where a hit would be, and the
    # rest before it are cut), with at most one window of rest at the end
    assert cut is not None and round((cut.t0 - 10.0) / DT) in (100, 101)
    assert 198 * DT <= cut.duration <= (199 + 12) * DT
    assert cut_rest(GridTrajectory(0.0, DT, np.zeros((50, 3))), 0.05, 0.1) is None


def test_cut_rest_starts_after_a_human_hit_not_before_it():
    """A resting puck (0.1 mm marker noise) hit to 2 m/s at row 60: the kept part starts at the hit's first
    moved frame, so no prediction is made from the rest before the hit (thesis sec. 4.5.1 cuts the hitting)."""
    rng = np.random.default_rng(0)
    x = np.concatenate([np.zeros(60), 2.0 * DT * np.arange(1, 241)]) + rng.normal(0.0, 1e-4, 300)
    z = np.column_stack([x, np.zeros(300), np.zeros(300)])
    cut = cut_rest(GridTrajectory(0.0, DT, z), rest_speed=0.05, window=0.1)
    assert round(cut.t0 / DT) in (60, 61)
    assert cut.z[0, 0] > 1e-3 or cut.z[1, 0] > 1e-2  # moving from its first frames


def test_a_marker_glitch_in_the_rest_does_not_start_the_trajectory():
    """A one-frame glitch (10 cm) at row 30 of the rest looks like motion to the window test; screened as
    a glitch (a pose jumping faster than glitch_speed from both neighbours) it no longer starts the
    trajectory, which starts at the hit (row 60)."""
    rng = np.random.default_rng(1)
    x = np.concatenate([np.zeros(60), 2.0 * DT * np.arange(1, 241)])
    z = np.column_stack([x, np.zeros(300), np.zeros(300)]) + rng.normal(0.0, 1e-4, (300, 3))
    z[30, 1] += 0.1
    traj = GridTrajectory(0.0, DT, z)
    assert round(cut_rest(traj, 0.05, 0.1).t0 / DT) <= 30  # fooled without the screen: starts at the glitch
    glitches = grid_glitches(traj, speed=10.0, max_gap=0.5)
    assert glitches == [30]
    assert round(cut_rest(traj, 0.05, 0.1, glitches).t0 / DT) in (60, 61)
    prep = {"frozen_threshold": 1e-6, "max_gap": 0.5, "rest_speed": 0.05, "rest_window": 0.1, "min_duration": 1.0}
    stamps = list(np.arange(300) * DT)
    (cut,) = preprocess(stamps, list(z), DT, prep, glitch_speed=10.0).trajectories
    assert round(cut.t0 / DT) in (60, 61)


PUSH_PREP = {"frozen_threshold": 1e-6, "max_gap": 0.5, "rest_speed": 0.05, "rest_window": 0.1, "min_duration": 1.0,
             "push_window": 0.2, "push_speed_gain": 0.1, "push_rim_margin": 0.05, "push_memory": 1.0}


def _shot_with_carry(carry, seed: int, second_hit: bool = False):
    """A test-bed puck (core/puck/real_table.py, the filter's model not involved) resting, hit at 0.5 s across
    the table's middle, then ``carry`` (start, time, target) by a hand and held; with ``second_hit`` hit
    again from where it was put, 1 s after the carry. Poses at 120 Hz with 0.2 mm noise."""
    from air_hockey_agent.core.puck.real_table import RealTablePuck, TableEffects
    from air_hockey_agent.core.table import TableGeometry
    table = TableGeometry(1.956, 1.042, 0.25, 0.03165)
    effects = TableEffects(damping=0.1, friction_surface=0.02, restitution_slow=0.9, restitution_fast=0.9)
    puck = RealTablePuck(table, effects, np.random.default_rng(seed))
    _, states = puck.simulate(np.array([-0.6, -0.2, 0.0, 0.0, 0.0, 0.0]), 7.0, 1e-3, 0.5, np.array([1.2, 0.5]), carry)
    if second_hit:
        _, more = puck.simulate(states[-1], 4.0, 1e-3, 0.5, np.array([-1.0, 0.3]))
        states = np.concatenate([states, more[1:]])
    rng = np.random.default_rng(seed + 100)
    rows = states[::8][:, [0, 1, 4]] + rng.normal(0.0, 2e-4, (len(states[::8]), 3))
    return table, list(np.arange(len(rows)) * 8e-3 + 1000.0), list(rows)


def test_a_hands_carry_ends_the_trajectory_and_what_follows_the_rest_starts_a_new_one():
    """The hand takes the puck at 4.0 s and carries it 0.7 m in 1.5 s: the trajectory ends at most 0.45 s
    before the grab (two windows) and not after it; the carry is dropped; a second hit after the puck rested
    again starts a second trajectory. Without the table's limits nothing is cut (the thesis's preprocessing)."""
    from air_hockey_agent.core.identification.preprocess import push_limits
    carry = (4.0, 1.5, np.array([0.3, 0.1, 1.0]))
    table, stamps, z = _shot_with_carry(carry, 3, second_hit=True)
    limits = push_limits(table, 0.05)
    done = preprocess(stamps, z, 8e-3, PUSH_PREP, 10.0, limits)
    first, second = done.trajectories
    end = first.t0 + first.duration - 1000.0
    assert 4.0 - 0.45 <= end <= 4.0 and done.pushes >= 1  # the grab, and the carry's own speed-up
    assert 7.0 + 0.5 <= second.t0 - 1000.0 <= 7.0 + 0.7  # the second hit, not the carry
    (whole,) = preprocess(stamps, z, 8e-3, PUSH_PREP, 10.0).trajectories
    assert whole.t0 + whole.duration - 1000.0 > 6.0  # the carry and the second shot kept as one


def test_no_push_is_found_in_shots_without_a_hand_bounces_lost_frames_and_glitches_included():
    """Test-bed sessions with every mocap imperfection (lost frames and dropouts, glitches, five times noisier
    frames) or the harsh test bed's tilt and random accelerations (a slow puck gains speed downhill), and
    MuJoCo's soft rims: cutting at pushes changes no trajectory."""
    from air_hockey_agent.core.estimation.ekf import PuckEKF
    from air_hockey_agent.core.identification.preprocess import push_limits
    from air_hockey_agent.tracker_params import load_tracker_params
    from model_fixtures import session_on_mujoco, session_on_testbed
    ekf = PuckEKF.from_params(load_tracker_params())
    limits = push_limits(ekf.model.table, 0.05)
    for frames in (session_on_testbed(ekf, 8, 3, lost_rate=0.3, glitch_rate=0.005, heavy_tail_rate=0.03),
                   session_on_testbed(ekf, 8, 4, {"tilt": 0.006, "random_acceleration": 0.03}),  # the harsh bed's
                   session_on_mujoco(ekf, 4, 11)):
        stamps, z = [f.stamp for f in frames], [f.measurement for f in frames]
        cut = preprocess(stamps, z, DT, PUSH_PREP, 10.0, limits)
        plain = preprocess(stamps, z, DT, PUSH_PREP, 10.0)
        assert cut.pushes == 0 and len(cut.trajectories) == len(plain.trajectories) >= 3
        assert all(np.array_equal(a.z, b.z, equal_nan=True) for a, b in zip(cut.trajectories, plain.trajectories))


def test_a_slow_carry_that_gains_little_from_one_chord_to_the_next_is_found_over_a_second():
    """The hand takes the puck at 2.5 s and slides it 0.98 m in 4 s (0.48 m/s at the most, gaining at most 0.07
    m/s from one 0.2 s chord to the next): with push_memory 1 s the carry is dropped (one trajectory, ending
    at the grab); chord against chord alone (push_memory 0) keeps it as a second trajectory of 3.3 s."""
    from air_hockey_agent.core.identification.preprocess import push_limits
    table, stamps, z = _shot_with_carry((2.5, 4.0, np.array([-0.4, -0.2, 1.0])), 5)
    limits = push_limits(table, 0.05)
    (first,) = preprocess(stamps, z, 8e-3, PUSH_PREP, 10.0, limits).trajectories
    assert 2.5 - 0.45 <= first.t0 + first.duration - 1000.0 <= 2.5
    kept = preprocess(stamps, z, 8e-3, {**PUSH_PREP, "push_memory": 0.0}, 10.0, limits).trajectories
    assert len(kept) == 2 and kept[1].t0 - 1000.0 > 2.5 and kept[1].duration >= 1.0


PREP = {"frozen_threshold": 1e-6, "max_gap": 0.5, "rest_speed": 0.05, "rest_window": 0.1, "push_window": 0.2,
        "push_speed_gain": 0.1, "push_memory": 1.0, "min_duration": 0.5}


def _shots(t0: float, count: int = 2) -> tuple[list, list]:
    """``count`` shots of 2 s at 1 m/s along x with 0.1 mm of noise, 3 s apart (a pause without frames)."""
    rng, stamps, poses = np.random.default_rng(0), [], []
    for shot in range(count):
        for k in range(240):
            stamps.append(t0 + 5.0 * shot + k * DT)
            poses.append((-0.8 + k * DT + rng.normal(0, 1e-4), rng.normal(0, 1e-4), 0.0))
    return stamps, poses


def test_a_stamp_far_off_or_not_finite_neither_blows_up_the_grid_nor_changes_the_trajectories():
    """A zero header stamp among epoch times asked for a grid of 2e11 rows (MemoryError in sysid and in
    eval-prediction's thesis-style columns, found by fuzzing); blocks far apart are gridded apart on one grid,
    frames without a finite stamp left out. Empty input has no trajectories."""
    stamps, poses = _shots(1.7e9)
    clean = preprocess(stamps, poses, DT, PREP)
    assert len(clean.trajectories) == 2
    for bad in (0.0, -1e12, 5e9, math.nan, math.inf):
        odd = list(stamps)
        odd[100] = bad
        got = preprocess(odd, poses, DT, PREP)
        assert [round(t.t0 / DT) for t in got.trajectories] == [round(t.t0 / DT) for t in clean.trajectories]
        assert [len(t) for t in got.trajectories] == [len(t) for t in clean.trajectories]
    assert preprocess([], [], DT, PREP).trajectories == []


def test_pieces_gridded_apart_lie_on_the_first_pieces_grid():
    """The second shot's rows keep the phase of the recording's first stamp, to the last bit (the same
    grid as one array over the whole recording gave), and a frozen last frame of a shot is not filled in
    toward the next shot's first frame 3 s later (the whole-recording grid did that)."""
    stamps, poses = _shots(100.0 + 0.3 * DT)
    stamps[300] += 0.4 * DT  # a late frame in the second shot: still its row's nearest
    whole = split_trajectories(to_model_grid(stamps, poses, DT), PREP["max_gap"])
    apart, _ = _gridded_pieces(stamps, poses, DT, PREP["max_gap"], PREP["frozen_threshold"])
    assert [t.t0 for t in apart] == [t.t0 for t in whole] and len(apart) == 2
    assert all(np.array_equal(a.z, w.z) for a, w in zip(apart, whole))
    poses[239] = poses[238]  # the first shot's last frame repeats the one before
    pieces, frozen = _gridded_pieces(stamps, poses, DT, PREP["max_gap"], PREP["frozen_threshold"])
    assert frozen == 1 and len(pieces[0]) == 239  # ends at the last good frame

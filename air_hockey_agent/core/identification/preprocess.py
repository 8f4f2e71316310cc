"""Preprocessing of recorded mocap data for system identification (thesis sec. 4.5.1, algorithm 2).

* :func:`to_model_grid`: map irregular stamps onto the filter's fixed grid (``t0 + k dt``): each grid
  slot takes the nearest recorded frame within half a step, a slot without one gets a blank (lost
  frame), and of two frames in one slot only the nearer is kept (duplicates dropped).
* :func:`interpolate_frozen`: frames whose position repeats the previous one within ``threshold``
  (1e-6 m in the thesis) are replaced by linear interpolation between the neighbouring good frames.
* :func:`split_trajectories`: a long recording is cut where more than ``max_gap`` seconds have no frame
  (:func:`preprocess` grids the stamps in blocks apart where they leave such a gap, on one grid: a stamp
  far off cannot ask for billions of rows, and a frozen frame is not filled in across a gap).
* :func:`cut_rest`: the start of a trajectory up to the human's hit and its end where the puck is at rest
  or moved slowly by hand are cut (speed below ``rest_speed`` over a window).
* :func:`cut_pushes`: a trajectory ends where a hand (or a mallet) takes the puck: a speed change no table
  gives away from its rims (``push_speed_gain`` gained, or half the speed lost, from one ``push_window`` to
  the next; or ``push_speed_gain`` gained within ``push_memory``); what follows is the hand's until the
  puck rests again, and a new trajectory may start after.

A grid trajectory is a :class:`GridTrajectory`: start time, step and an (n, 3) array of
(x, y, theta) with NaN rows for blanks.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Mapping, Sequence

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from air_hockey_agent.core.estimation.evaluation import marker_glitches


@dataclass
class GridTrajectory:
    t0: float          # [s] stamp of row 0
    dt: float          # [s] grid step
    z: np.ndarray      # (n, 3) measurements (x, y, theta), NaN rows = blank

    def __len__(self) -> int:
        return len(self.z)

    @property
    def duration(self) -> float:
        return (len(self.z) - 1) * self.dt

    def frames(self) -> list[tuple[float, np.ndarray | None]]:
        """(stamp, measurement or None) per grid step: the stream the filter consumes."""
        return [(self.t0 + k * self.dt, None if np.isnan(row[0]) else row) for k, row in enumerate(self.z)]

    def measured(self) -> int:
        return int(np.sum(~np.isnan(self.z[:, 0])))


def to_model_grid(stamps: Sequence[float], z: Sequence[Sequence[float] | None], dt: float,
                  origin: float | None = None) -> GridTrajectory:
    """Algorithm 2: one row per model step from the first to the last stamp; blanks where frames are lost.
    The rows lie at ``origin + k dt`` (default: the first stamp), so pieces of one recording gridded apart
    share its grid."""
    t = np.asarray(stamps, float)
    order = np.argsort(t, kind="stable")
    origin = float(t[order[0]]) if origin is None else origin
    first = int(math.floor((t[order[0]] - origin) / dt + 0.5))
    t0 = origin + first * dt
    n = int(math.floor((t[order[-1]] - origin) / dt + 0.5)) - first + 1
    grid = np.full((n, 3), np.nan)
    offset = np.full(n, np.inf)
    for i in order:
        if z[i] is None:
            continue
        k = int(math.floor((t[i] - origin) / dt + 0.5)) - first
        miss = abs(t[i] - (t0 + k * dt))
        if miss < offset[k]:  # nearest frame wins the slot; the other is a duplicate
            grid[k], offset[k] = z[i], miss
    return GridTrajectory(t0, dt, grid)


def interpolate_frozen(traj: GridTrajectory, threshold: float) -> int:
    """Replace frozen frames (position unchanged within ``threshold`` [m]) in place; returns their count."""
    z = traj.z
    valid = np.flatnonzero(~np.isnan(z[:, 0]))
    frozen = [b for a, b in zip(valid[:-1], valid[1:]) if math.hypot(*(z[b, :2] - z[a, :2])) < threshold]
    z[frozen] = np.nan
    good = np.flatnonzero(~np.isnan(z[:, 0]))
    for k in frozen:
        after = np.searchsorted(good, k)
        if 0 < after < len(good):
            a, b = good[after - 1], good[after]
            w = (k - a) / (b - a)
            z[k] = (1 - w) * z[a] + w * z[b]
            z[k, 2] = z[a, 2] + w * math.remainder(z[b, 2] - z[a, 2], 2 * math.pi)
    return len(frozen)


def split_trajectories(traj: GridTrajectory, max_gap: float) -> list[GridTrajectory]:
    """Cut where more than ``max_gap`` [s] pass without a measurement."""
    valid = np.flatnonzero(~np.isnan(traj.z[:, 0]))
    if valid.size == 0:
        return []
    breaks = np.flatnonzero(np.diff(valid) * traj.dt > max_gap)
    pieces = np.split(valid, breaks + 1)
    return [GridTrajectory(traj.t0 + p[0] * traj.dt, traj.dt, traj.z[p[0]:p[-1] + 1].copy()) for p in pieces]


def grid_glitches(traj: GridTrajectory, speed: float, max_gap: float) -> list[int]:
    """Rows of ``traj`` that are marker glitches: poses that jump faster than ``speed`` [m/s] from both
    neighbouring poses (the definition the evaluation screens ground truth with)."""
    poses = [None if np.isnan(row[0]) else row for row in traj.z]
    return marker_glitches([traj.t0 + k * traj.dt for k in range(len(traj))], poses,
                           [p is not None for p in poses], speed, max_gap)


def cut_rest(traj: GridTrajectory, rest_speed: float, window: float,
             glitches: Sequence[int] = ()) -> GridTrajectory | None:
    """Drop the start and end where the puck moves slower than ``rest_speed`` [m/s] over ``window`` [s].

    The kept part starts at the end of the first window with motion: for a human hit (which moves the puck
    farther than ``rest_speed * window`` within a frame or two) the frame after it, so the hit and the
    rest before it are cut, as the thesis cuts "the hitting" (sec. 4.5.1); predictions from the rest
    before a hit would miss the whole shot, whatever the model. It ends at most one window into the rest
    after the motion. Rows in ``glitches`` (marker glitches, :func:`grid_glitches`) count as lost here: a
    glitch in the rest would look like motion and start the trajectory at it. None if it never moves.
    """
    steps = max(1, int(round(window / traj.dt)))
    z = traj.z
    if len(glitches):
        z = z.copy()
        z[list(glitches)] = np.nan
    moving = np.zeros(len(z), bool)
    for k in range(len(z) - steps):
        a, b = z[k, :2], z[k + steps, :2]
        if not (np.isnan(a[0]) or np.isnan(b[0])):
            moving[k] = math.hypot(*(b - a)) / (steps * traj.dt) >= rest_speed
    idx = np.flatnonzero(moving)
    if idx.size == 0:
        return None
    first, last = idx[0] + steps, min(idx[-1] + steps, len(z) - 1)
    return GridTrajectory(traj.t0 + first * traj.dt, traj.dt, z[first:last + 1].copy())


def _chord_speeds(z: np.ndarray, steps: int, dt: float) -> np.ndarray:
    """Speed [m/s] over each window of ``steps`` rows from row k (NaN where an end is blank)."""
    speeds = np.full(len(z), np.nan)
    if len(z) > steps:
        speeds[:-steps] = np.hypot(*(z[steps:, :2] - z[:-steps, :2]).T) / (steps * dt)
    return speeds


def _rim_room(z: np.ndarray, limits: tuple[float, float]) -> tuple[np.ndarray, np.ndarray]:
    """Per row: how far [m] the puck is inside ``limits`` (|x|, |y| [m]; negative beyond them, infinite where
    the frame is lost) and the length of the run of lost frames the row is in (0 where measured)."""
    room = np.minimum(limits[0] - np.abs(z[:, 0]), limits[1] - np.abs(z[:, 1]))
    lost = np.isnan(room)
    room[lost] = np.inf
    gap = np.zeros(len(z), int)
    for k in np.flatnonzero(lost):
        gap[k] = gap[k - 1] + 1 if k and lost[k - 1] else 1
    for k in range(len(z) - 2, -1, -1):
        if lost[k] and lost[k + 1]:
            gap[k] = gap[k + 1]
    return room, gap


def _rim_free(room: np.ndarray, gap: np.ndarray, span: slice, speed: float, dt: float) -> bool:
    """The puck, at ``speed`` [m/s], cannot have met a rim unseen over the rows in ``span``: every frame inside
    the limits by more than it travels over the longest run of lost frames there (a chord across a bounce
    is short)."""
    return room[span].min() >= speed * (gap[span].max() + 1) * dt


def _speed_floors(speeds: np.ndarray, room: np.ndarray, gap: np.ndarray, steps: int, dt: float) -> np.ndarray:
    """Per row k: the highest chord speed [m/s] of the half window of chords from k (NaN where under half of
    them are measured or the puck could have met a rim in them): a speed the puck kept that low over half
    a window, which a marker glitch (shortening a chord or two) does not fake."""
    half = max(1, steps // 2)
    span = half + steps + 1  # the rows the half window of chords covers
    floors = np.full(len(speeds), np.nan)
    if len(speeds) < span:
        return floors
    runs = sliding_window_view(speeds, half + 1)[:len(speeds) - span + 1]
    seen = (~np.isnan(runs)).sum(axis=1)
    top = np.where(np.isnan(runs), -np.inf, runs).max(axis=1)
    free = sliding_window_view(room, span).min(axis=1) >= top * (sliding_window_view(gap, span).max(axis=1) + 1) * dt
    floors[:len(top)] = np.where((2 * seen >= half + 1) & free, top, np.nan)
    return floors


def _first_push(z: np.ndarray, steps: int, dt: float, gain: float, limits: tuple[float, float],
                memory: int = 0) -> int | None:
    """Row of the first of the windows in a row, spanning half a window at least, after each of which the
    speed over the next window has gained more than ``gain`` [m/s] on the one before or on the lowest
    speed held over half a window in the ``memory`` rows before (:func:`_speed_floors`: a slow hand's
    rise adds up where one window's gain stays under ``gain``; a table's tilt does not), or fallen below
    half (from at least twice ``gain``); judged only where the puck cannot have met a rim within the
    windows (:func:`_rim_free`); None without one."""
    speeds = _chord_speeds(z, steps, dt)
    room, gap = _rim_room(z, limits)
    floors = _speed_floors(speeds, room, gap, steps, dt) if memory else None
    half = max(1, steps // 2)
    first = None  # the first of the windows in a row that show it (windows not judged do not break a row)
    for k in range(len(z) - 2 * steps):
        before, after = speeds[k], speeds[k + steps]
        if np.isnan(before) or np.isnan(after):
            continue
        if not _rim_free(room, gap, slice(k, k + 2 * steps + 1), max(before, after), dt):
            continue
        slowest = before
        if floors is not None and k >= half:
            held = floors[max(0, k - memory):k - half + 1]
            slowest = before if np.isnan(held).all() else min(before, float(np.nanmin(held)))
        if after - slowest > gain or (before > 2.0 * gain and after < 0.5 * before):
            first = k if first is None else first
            if k - first >= steps // 2:  # over half a window: a marker glitch at a chord's end changes a few
                return first               # windows a window apart, a hand all of them
        else:
            first = None
    return None


def cut_pushes(traj: GridTrajectory, window: float, gain: float, limits: tuple[float, float],
               rest_speed: float, rest_window: float, memory: float = 0.0) -> tuple[list[GridTrajectory], int]:
    """Cut a trajectory (from :func:`cut_rest`) where a hand or a mallet takes the puck (thesis sec. 4.5.1
    cuts "the adjustment of the puck in the end for the next trajectory"): at the first window after
    which the speed changes as no table makes it change between two ``window`` [s] chords away from the
    rims (:func:`_first_push`: a table's tilt gains about 0.01 m/s in 0.2 s, a hand sliding a puck away
    tenths of a m/s; a flight law loses a tenth of the speed there at the most, a hand's grab all of it),
    or where it has gained more than ``gain`` on the lowest speed held over the ``memory`` [s] before (a
    slow hand: a table's tilt gains 0.03-0.06 m/s in a second). The hand's motion after it is dropped
    until the puck rests (``rest_speed`` over ``rest_window``); what moves after that is cut again (a new
    hit). Returns the pieces in order and the pushes found."""
    steps = max(1, int(round(window / traj.dt)))
    k = _first_push(traj.z, steps, traj.dt, gain, limits, int(round(memory / traj.dt)))
    if k is None:
        return [traj], 0
    pieces = [GridTrajectory(traj.t0, traj.dt, traj.z[:k + 1].copy())] if k > 0 else []
    rest_steps = max(1, int(round(rest_window / traj.dt)))
    slow = np.flatnonzero(_chord_speeds(traj.z[k + steps:], rest_steps, traj.dt) < rest_speed)
    if not slow.size:
        return pieces, 1
    start = k + steps + int(slow[0])
    after = cut_rest(GridTrajectory(traj.t0 + start * traj.dt, traj.dt, traj.z[start:]), rest_speed, rest_window)
    if after is None:
        return pieces, 1
    more, pushes = cut_pushes(after, window, gain, limits, rest_speed, rest_window, memory)
    return pieces + more, pushes + 1


@dataclass
class Preprocessed:
    """The trajectories of one recording, and what preprocessing did to get them."""

    trajectories: list      # GridTrajectory
    frozen: int = 0         # frozen frames interpolated
    at_rest: int = 0        # pieces dropped because the puck never moved in them
    too_short: int = 0      # pieces dropped because their motion was shorter than min_duration
    pushes: int = 0         # trajectories ended by a hand or mallet taking the puck (cut_pushes)


def preprocess(stamps: Sequence[float], z: Sequence[Sequence[float] | None], dt: float,
               prep: Mapping[str, Any], glitch_speed: float | None = None,
               limits: tuple[float, float] | None = None) -> Preprocessed:
    """Algorithm 2 and the cleaning after it on one recording (table-frame (x, y, theta) per stamp, None
    for a lost frame): grid, interpolate frozen frames, split at gaps, cut rest, cut where a hand takes the
    puck (with ``limits``: the |x|, |y| [m] of the table's centre clear of the rims, :func:`cut_pushes`),
    drop short pieces (``prep``: the sysid parameters ``frozen_threshold``, ``max_gap``, ``rest_*``,
    ``push_*``, ``min_duration``). With ``glitch_speed`` [m/s] (the tracker's), marker glitches do not count
    as motion when the rest is cut."""
    pieces, frozen = _gridded_pieces(stamps, z, dt, prep["max_gap"], prep["frozen_threshold"])
    result = Preprocessed([], frozen)
    for piece in pieces:
        glitches = grid_glitches(piece, glitch_speed, prep["max_gap"]) if glitch_speed else []
        traj = cut_rest(piece, prep["rest_speed"], prep["rest_window"], glitches)
        if traj is None:
            result.at_rest += 1
            continue
        cut, pushes = ([traj], 0) if limits is None else cut_pushes(
            traj, prep["push_window"], prep["push_speed_gain"], limits, prep["rest_speed"], prep["rest_window"],
            prep["push_memory"])
        result.pushes += pushes
        for part in cut:
            if part.duration < prep["min_duration"]:
                result.too_short += 1
            else:
                result.trajectories.append(part)
    return result


def _gridded_pieces(stamps: Sequence[float], z: Sequence[Sequence[float] | None], dt: float, max_gap: float,
                    frozen_threshold: float) -> tuple[list[GridTrajectory], int]:
    """The recording on the model's grid (:func:`to_model_grid`, frozen frames interpolated) cut at gaps
    longer than ``max_gap`` [s] (:func:`split_trajectories`), and the number of frozen frames. The stamps are
    gridded in blocks apart wherever they leave a gap longer than ``max_gap + dt`` (a cut there anyway), on
    one grid: a recording with one stamp far off (a zero header stamp among epoch times) would otherwise
    ask for a grid of billions of rows. Frames with a non-finite stamp are left out."""
    t = np.asarray(stamps, float)
    finite = np.flatnonzero(np.isfinite(t))
    order = finite[np.argsort(t[finite], kind="stable")]
    if not order.size:
        return [], 0
    origin, pieces, frozen = float(t[order[0]]), [], 0
    for block in np.split(order, np.flatnonzero(np.diff(t[order]) > max_gap + dt) + 1):
        grid = to_model_grid(t[block], [z[i] for i in block], dt, origin)
        frozen += interpolate_frozen(grid, frozen_threshold)
        for piece in split_trajectories(grid, max_gap):
            piece.t0 = origin + round((piece.t0 - origin) / dt) * dt  # to the bit as on one grid from origin
            pieces.append(piece)
    return pieces, frozen


def push_limits(table, margin: float) -> tuple[float, float]:
    """|x|, |y| [m] of the puck centre ``margin`` clear of every rim line of ``table`` (a TableGeometry)."""
    return table.x_limit - margin, table.y_limit - margin

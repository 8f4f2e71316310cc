"""How well the tactics' contact law predicted the puck's exit at a robot's mallet contacts in a recorded game
(ROS-free): `air-hockey game-check`'s contact report.

The tactics aim every Cut, Prepare and Smash with :func:`~air_hockey_agent.core.puck.mallet_impact.puck_after_contact`
(Routh's impact with the mallet as a moving wall, ``mallet_restitution`` and ``mallet_friction`` of
``config/agent.yaml``, neither measured on a real table). Here each contact is measured from the puck's
positions alone: a straight line fitted to the positions in a window before the contact and another after it
give the velocities in and out (a line's velocity is the puck's at the mean time of its window, 35 ms from the
contact, carried to the contact under the flight law, eq. 3.1, where the table's physics are known: on the
thesis's table a puck at 3 m/s slows by 0.05 m/s in that time), the mallet's position and velocity come from
the arm's joint states (the motion layer's kinematics), and the law's exit from the same inputs is compared
with the one measured. Contacts whose windows hold a rim impact, another contact or too few positions are left
out. A least-squares fit of the law's two constants to the measured exits says what they would have to be (on
a real robot: what to configure). Two more inputs matter as much as the law: the puck's spin (Routh's impact
turns it into tangential speed; a line fitted to the puck's yaw before the contact, where the recording has
it) and the mallet's velocity at the contact's very moment (the joint states come at 100 Hz and a hitting
mallet changes its speed by 0.1 m/s in 5 ms: a cubic Hermite curve through the samples' positions and
velocities, not a straight line between the velocities). Without the three, on pybullet's table, the law
seemed to miss a game's contacts by a median 0.16 m/s where, given pybullet's states 1 ms before each
contact, it misses by 0.04 m/s, as measured with them (README "The game").
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np
from scipy.interpolate import CubicHermiteSpline

from air_hockey_agent.core.puck.mallet_impact import puck_after_contact

TOUCH_MARGIN = 0.005   # [m] the centres closer than the contact distance plus this and half the way the puck
#                        moved against the mallet since the frame before or until the frame after count as
#                        touching (the mocap noise is a fraction of a millimetre; a 120 Hz frame moves a puck
#                        closing at 3 m/s 25 mm, so a fast contact may fall between two frames)
FIT_WINDOW = 0.05      # [s] positions fitted on either side: 6 frames at 120 Hz
FIT_GUARD = 0.01       # [s] left out next to the contact (the contact lasts a few ms; the mallet may still be
#                        within the margin)
MIN_POSITIONS = 4      # a side with fewer positions in its window is not measured
RIM_CLEARANCE = 0.01   # [m] a window whose puck comes this near a rim (beyond its radius) is not measured
PARKED_SPEED = 0.05    # [m/s] a mallet slower than this counts as parked
FAST_SPEED = 0.6       # [m/s] ... faster than this as fast (the report's three classes)
FIT_SCALE = 0.05       # [m/s] the fit's soft-L1 scale: about the error a well-measured contact leaves (0.03-0.05)
JUMP = 0.01            # [m] two mallet samples whose positions differ by this much more than their velocities
#                        carry it (the trapezoid rule; over a 10 ms joint-state interval in which the mallet's
#                        acceleration changes by 50 m/s^2 it errs by 0.4 mm) were not one motion: a reset, or
#                        the arm put somewhere by hand

Acceleration = Callable[[np.ndarray], np.ndarray]  # the flight law: velocity [m/s] -> acceleration [m/s^2]
FlightAt = Callable[[float], Acceleration]          # the flight law in effect at a time [s]


@dataclass(frozen=True)
class ContactGeometry:
    """What the check needs of the table and the law: the contact distance (puck plus mallet radius) [m], the
    puck's radius [m], the half length and half width of the playing surface [m], and the law's restitution
    and Coulomb friction [-] as configured."""

    contact_distance: float
    puck_radius: float
    half_length: float
    half_width: float
    restitution: float
    friction: float

    @classmethod
    def from_settings(cls, st) -> "ContactGeometry":
        """A robot's tactics settings' (:class:`~air_hockey_agent.core.game.tactics.settings.TacticsSettings`:
        table, contact distance, the configured law)."""
        return cls(st.contact_distance, st.table.puck_radius, st.table.length / 2, st.table.width / 2,
                   st.mallet_restitution, st.mallet_friction)


@dataclass(frozen=True)
class MeasuredContact:
    """One contact (own frame of the robot): when it began [s], the puck's state (x, y, vx, vy) [m, m/s] at
    that time from the fit before, the mallet's position [m] and velocity [m/s] then, the unit normal (mallet
    to puck), the puck's velocity after it, measured and by the law [m/s], and the puck's spin before it
    [rad/s] (0 where the recording has no yaw)."""

    time: float
    puck: np.ndarray
    mallet: np.ndarray
    mallet_velocity: np.ndarray
    normal: np.ndarray
    exit_measured: np.ndarray
    exit_law: np.ndarray
    spin: float = 0.0

    @property
    def mallet_speed(self) -> float:
        return float(np.hypot(*self.mallet_velocity))

    @property
    def closing(self) -> float:
        """The puck's speed toward the mallet along the normal before the contact [m/s]."""
        return float((self.mallet_velocity - self.puck[2:4]) @ self.normal)

    @property
    def error(self) -> float:
        """|measured - law| [m/s]."""
        return float(np.hypot(*(self.exit_measured - self.exit_law)))

    @property
    def along(self) -> float:
        """The measured exit minus the law's along the law's exit direction [m/s] (negative: slower)."""
        speed = float(np.hypot(*self.exit_law))
        return 0.0 if speed <= 0.0 else float((self.exit_measured - self.exit_law) @ self.exit_law) / speed


def line_fit(t: np.ndarray, xy: np.ndarray, at: float) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares straight line through positions ``xy`` (n, 2) [m] at times ``t`` (n,) [s]: its position at
    ``at`` [s] and its velocity [m/s]."""
    dt = np.asarray(t, float) - at
    a = np.column_stack([np.ones_like(dt), dt])
    coef, *_ = np.linalg.lstsq(a, np.asarray(xy, float), rcond=None)
    return coef[0], coef[1]


def touching_spans(close: np.ndarray) -> list[tuple[int, int]]:
    """(first, last) index of every run of consecutive True in ``close``."""
    spans, start = [], None
    for i, c in enumerate(close):
        if c and start is None:
            start = i
        elif not c and start is not None:
            spans.append((start, i - 1))
            start = None
    if start is not None:
        spans.append((start, len(close) - 1))
    return spans


def measure_contacts(puck_t: np.ndarray, puck_xy: np.ndarray, mallet_t: np.ndarray, mallet_xy: np.ndarray,
                     mallet_v: np.ndarray, g: ContactGeometry, puck_yaw: np.ndarray | None = None,
                     flight: FlightAt | None = None) -> list[MeasuredContact]:
    """Every measurable contact between the puck (positions ``puck_xy`` (n, 2) [m] at ``puck_t`` [s], and its
    yaw ``puck_yaw`` (n,) [rad] where known) and the mallet (positions and velocities (m, 2) [m, m/s] at
    ``mallet_t`` [s]), all in one frame, times increasing; ``flight``: the table's flight law in effect at a
    time, in that frame (None: straight lines, no deceleration)."""
    puck_t, puck_xy = np.asarray(puck_t, float), np.asarray(puck_xy, float)
    mallet = MalletPath(mallet_t, mallet_xy, mallet_v)
    if len(puck_t) < 2 * MIN_POSITIONS or mallet.path is None:
        return []
    yaw = None if puck_yaw is None else np.unwrap(np.asarray(puck_yaw, float))
    rel = puck_xy - mallet.position(puck_t)
    step = np.hypot(*np.diff(rel, axis=0).T)
    moved = np.maximum(np.concatenate([[0.0], step]), np.concatenate([step, [0.0]]))
    spans = touching_spans(np.hypot(*rel.T) <= g.contact_distance + TOUCH_MARGIN + moved / 2)
    out = []
    for k, (i0, i1) in enumerate(spans):
        t0, t1 = puck_t[i0], puck_t[i1]
        before = (puck_t >= t0 - FIT_GUARD - FIT_WINDOW) & (puck_t < t0 - FIT_GUARD)
        after = (puck_t > t1 + FIT_GUARD) & (puck_t <= t1 + FIT_GUARD + FIT_WINDOW)
        previous_end = puck_t[spans[k - 1][1]] if k else -math.inf
        next_start = puck_t[spans[k + 1][0]] if k + 1 < len(spans) else math.inf
        if (previous_end >= t0 - FIT_GUARD - FIT_WINDOW or next_start <= t1 + FIT_GUARD + FIT_WINDOW
                or before.sum() < MIN_POSITIONS or after.sum() < MIN_POSITIONS
                or _near_rim(puck_xy[before | after], g)):
            continue
        spin = 0.0 if yaw is None else float(line_fit(puck_t[before], yaw[before, None], t0)[1][0])
        spin = spin if math.isfinite(spin) else 0.0  # a yaw the recording lacks in that window
        law = None if flight is None else flight(t0)
        contact = _measured(t0, t1, (puck_t[before], puck_xy[before]), (puck_t[after], puck_xy[after]), mallet, spin,
                            law, g)
        if contact is not None:
            out.append(contact)
    return out


class MalletPath:
    """The mallet between its samples (positions (m, 2) [m] and velocities (m, 2) [m/s] at times (m,) [s]): the
    cubic Hermite curve through both (scipy's), so a mallet that speeds up between two joint states is not read
    at the mean of their velocities; held at the first and last sample outside them. Between two samples whose
    positions and velocities disagree by more than ``JUMP`` (the arm put somewhere by hand, a reset) the curve
    would swing at tens of m/s: there it is NaN, and no contact is measured. ``path`` is None with fewer than
    two distinct times."""

    def __init__(self, times: np.ndarray, positions: np.ndarray, velocities: np.ndarray) -> None:
        times, keep = np.unique(np.asarray(times, float), return_index=True)  # sorted; a repeated stamp once
        positions, velocities = np.asarray(positions, float)[keep], np.asarray(velocities, float)[keep]
        self.span = (times[0], times[-1]) if len(times) else (0.0, 0.0)
        self.path = CubicHermiteSpline(times, positions, velocities, axis=0) if len(times) >= 2 else None
        if self.path is not None:
            moved = np.diff(positions, axis=0) - np.diff(times)[:, None] * (velocities[1:] + velocities[:-1]) / 2
            self.times, self.broken = times, np.hypot(*moved.T) > JUMP  # per interval between samples

    def position(self, t) -> np.ndarray:
        """[m] at ``t`` [s] (a time: (2,); times (n,): (n, 2))."""
        return self._trusted(t, self.path(np.clip(t, *self.span)))

    def velocity(self, t) -> np.ndarray:
        """[m/s] at ``t`` [s]."""
        return self._trusted(t, self.path(np.clip(t, *self.span), 1))

    def _trusted(self, t, values: np.ndarray) -> np.ndarray:
        interval = np.clip(np.searchsorted(self.times, t) - 1, 0, len(self.broken) - 1)
        return np.where(self.broken[interval][..., None], np.nan, values)


def _near_rim(xy: np.ndarray, g: ContactGeometry) -> bool:
    reach = g.puck_radius + RIM_CLEARANCE
    return bool(np.any(np.abs(xy[:, 0]) > g.half_length - reach) or np.any(np.abs(xy[:, 1]) > g.half_width - reach))


def carried_line(t: np.ndarray, xy: np.ndarray,
                 acceleration: Acceleration | None) -> Callable[[float], tuple[np.ndarray, np.ndarray]]:
    """A puck seen at ``xy`` (n, 2) at times ``t`` (n,): its position [m] and velocity [m/s] as functions of a
    time [s]. The line fitted to them (once) holds the velocity at their mean time, carried from there under
    ``acceleration`` (the flight law ``v -> a`` [m/s^2]; None: none)."""
    mean = float(np.mean(t))
    p, v = line_fit(t, xy, mean)
    a = np.zeros(2) if acceleration is None else acceleration(v)

    def at(time: float) -> tuple[np.ndarray, np.ndarray]:
        dt = time - mean
        return p + v * dt + a * (dt * dt / 2), v + a * dt
    return at


def _measured(t0, t1, before: tuple, after: tuple, mallet_path: MalletPath, spin: float,
              acceleration: Acceleration | None, g: ContactGeometry) -> MeasuredContact | None:
    """The contact first seen at ``t0`` and last at ``t1`` [s], from the fits to the (times, positions) on
    either side; None when the puck was not closing on the mallet (the law then leaves it alone). It began where
    the puck's line before it and the mallet, carried along its velocity, first came within the contact distance
    (:func:`meeting`): the first frame seen touching lies up to a frame (25 mm at 3 m/s) past that, which would
    turn the normal. The exit is the puck's velocity after it, carried back to that start."""
    incoming = carried_line(*before, acceleration)
    p_in, v_in = incoming(t0)
    mallet, velocity = mallet_path.position(t0), mallet_path.velocity(t0)
    s = meeting(p_in - mallet, v_in - velocity, g.contact_distance)
    if s is None or not -FIT_GUARD <= s <= t1 - t0 + FIT_GUARD:  # not between the windows: not this contact
        return None
    p_in, v_in = incoming(t0 + s)
    mallet, velocity = mallet_path.position(t0 + s), mallet_path.velocity(t0 + s)
    if not (np.all(np.isfinite(mallet)) and np.all(np.isfinite(velocity))):
        return None  # the mallet's samples broken there (:class:`MalletPath`)
    normal = (p_in - mallet) / np.linalg.norm(p_in - mallet)
    _, v_out = carried_line(*after, acceleration)(t0 + s)
    puck = np.array([*p_in, *v_in])
    law = law_exit(puck, velocity, normal, g.restitution, g.friction, g.puck_radius, spin)
    return MeasuredContact(float(t0 + s), puck, mallet, velocity, normal, v_out, law, spin)


def meeting(rel: np.ndarray, closing: np.ndarray, distance: float) -> float | None:
    """When [s, from now] a puck at ``rel`` [m] from the mallet, moving at ``closing`` [m/s] relative to it along
    a straight line, enters the disc of ``distance`` [m] around it (negative: that long ago); None when the line
    passes outside."""
    a, b = float(closing @ closing), float(rel @ closing)
    c = float(rel @ rel) - distance ** 2
    disc = b * b - a * c
    if a <= 0.0 or disc < 0.0:
        return None
    return (-b - math.sqrt(disc)) / a


def law_exit(puck: np.ndarray, mallet_velocity: np.ndarray, normal: np.ndarray, restitution: float,
             friction: float, radius: float, spin: float = 0.0) -> np.ndarray:
    """The law's exit velocity [m/s] for a puck state (x, y, vx, vy) spinning at ``spin`` [rad/s]."""
    return puck_after_contact(np.array([*puck[:4], 0.0, spin]), mallet_velocity, normal, restitution, friction,
                              radius)[2:4]


Bounds = tuple[tuple[float, float], tuple[float, float]]  # (lower e, lower mu), (upper e, upper mu)


def fit_law(contacts: list[MeasuredContact], radius: float,
            bounds: Bounds = ((0.0, 0.0), (1.0, 1.0))) -> tuple[float, float, float]:
    """The restitution and friction [-] (within ``bounds``: (lower e, lower mu), (upper e, upper mu)) whose exits
    come nearest the measured ones (robust least squares over the velocity components: an error beyond
    ``FIT_SCALE`` counts about linearly, so one odd contact does not swing the fit), and the median error [m/s]
    they leave."""
    from scipy.optimize import least_squares

    def residuals(x: np.ndarray) -> np.ndarray:
        return np.concatenate([law_exit(c.puck, c.mallet_velocity, c.normal, x[0], x[1], radius, c.spin)
                               - c.exit_measured for c in contacts])
    fit = least_squares(residuals, np.clip([0.8, 0.1], *bounds), bounds=bounds, loss="soft_l1", f_scale=FIT_SCALE)
    left = np.hypot(*residuals(fit.x).reshape(-1, 2).T)
    return float(fit.x[0]), float(fit.x[1]), float(np.median(left))


def summary(contacts: list[MeasuredContact], g: ContactGeometry) -> dict:
    """The report of one robot's contacts: how many, the law's error [m/s] (median, p90; the exit along the
    law's own direction, median: negative is slower than predicted) over all and by the mallet's speed
    (parked, moving, fast), the law's constants fitted to them (with at least 5 contacts), and each contact
    (``each``: its time [s], the mallet's speed and the closing speed along the normal [m/s], the puck's spin
    before it [rad/s], the exit measured and by the law [m/s], own frame)."""
    def stats(group: list[MeasuredContact]) -> dict:
        if not group:
            return {"n": 0}
        errors, along = [c.error for c in group], [c.along for c in group]
        return {"n": len(group), "error_median": float(np.median(errors)),
                "error_p90": float(np.percentile(errors, 90)), "along_median": float(np.median(along))}
    speeds = [c.mallet_speed for c in contacts]
    out = {"configured": {"restitution": g.restitution, "friction": g.friction}, "all": stats(contacts),
           "parked": stats([c for c, s in zip(contacts, speeds) if s < PARKED_SPEED]),
           "moving": stats([c for c, s in zip(contacts, speeds) if PARKED_SPEED <= s <= FAST_SPEED]),
           "fast": stats([c for c, s in zip(contacts, speeds) if s > FAST_SPEED])}
    if len(contacts) >= 5:
        e, mu, left = fit_law(contacts, g.puck_radius)
        out["fitted"] = {"restitution": e, "friction": mu, "error_median": left}
    out["each"] = [{"time": c.time, "mallet_speed": c.mallet_speed, "closing": c.closing, "spin": c.spin,
                    "exit_measured": c.exit_measured.tolist(), "exit_law": c.exit_law.tolist()} for c in contacts]
    return out

"""What the tracker learns online of its table (issue #13 item 3): the rim law, the table acceleration and
the spin's decay.

The configured physics is a prior, not a given table's. After each mocap frame the filter hands this
module the frame and the state it predicted from:

* **rim impacts** (:mod:`.rim_adaptation`): an impact the model puts between two frames, with a
  well-known incoming velocity, is watched for ``rim_adaptation.window`` seconds of fused poses, whose
  line fit gives the outgoing velocity and spin; the rim law's scales learn from it;
* **free flight** (``acceleration_adaptation.*``, :mod:`.flight_adaptation`): fused poses of a moving
  puck between rim impacts are cut into windows of ``window`` seconds (the first half of each learned
  from provisionally, replaced by the whole; one an impact or a slow-down cuts short learned from as it
  is); a quadratic fit per window
  gives its acceleration, and what the configured flight law (eq. 3.1) does not explain of it is the
  table's own acceleration (a tilt, an air film's mean: issue #13 measured about 0.03 m/s^2 across the
  track in the lab's free flight; the thesis's conclusion proposes this constant-acceleration
  extension). The estimate is Gaussian: the configured ``table_acceleration`` with std ``prior_std`` as
  the prior, each window's fit with its own variance (from its residuals) plus ``field_std`` squared,
  for what the constant cannot follow (an uneven air film), so the estimate is the mean over windows
  across the table; the same windows' angles give the spin's decay (:mod:`.spin_adaptation`) unless
  ``spin_prior_std`` is 0, and their measured positions the mocap pivot's offset from the disc's centre
  (:mod:`.marker_offset`) unless ``marker_offset_prior_std`` is 0, in the same Gaussian as the flight
  law: a spinning puck's circling about a wrongly known pivot looks like an acceleration, so each
  window's acceleration depends on the offset too, and the windows learned from before the offset was
  known are put right as it becomes known (learned apart, on a table whose pivot was 2.2 mm off, the
  first windows taught the flight law a wrong acceleration that then refused the right windows for
  seven shots).

A re-initialisation or a restart ends any watch or window (a hit). A frame the gate rejects does not:
it gives the window nothing, but the puck flew on (a marker glitch, or a filter not yet right about the
table: a window ended at every rejection left a filter that rejected often, as one with the pivot's
offset still unlearned, with no whole window to learn the offset from). What was learned stays: it is
the table's, not the track's.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Mapping

import numpy as np

from air_hockey_agent.core.identification.local_fit import paths_meet
from air_hockey_agent.core.estimation.noise_adaptation import describe_noise
from air_hockey_agent.core.estimation.process_noise_adaptation import describe_process_noise
from air_hockey_agent.core.estimation.rim_adaptation import (AdaptationSettings, RimAdaptation, describe, outgoing_fit,
                                                             rim_frame)
from air_hockey_agent.core.estimation.delay_adaptation import DelayAdaptation
from air_hockey_agent.core.estimation.flight_adaptation import (AccelerationAdaptation, AccelerationSettings,
                                                                quadratic_fit)
from air_hockey_agent.core.estimation.marker_offset import centres_of, offset_sensitivity, pivot_shift
from air_hockey_agent.core.estimation.spin_adaptation import SpinAdaptation, describe_spin
from air_hockey_agent.core.puck.model import PuckModel, PuckParams, flight_acceleration
from air_hockey_agent.core.table import FIRST_POST, WALL_NORMALS, TableGeometry


REPORT_KEYS = ("rim_law", "table_acceleration", "spin_damping", "impact_delay", "marker_offset")  # report's, in order


def _flight_law_of(damping: float, friction_surface: float, table_acceleration) -> tuple[float, float, float, float]:
    """(damping [1/s], surface friction [m/s^2], gx, gy [m/s^2]): what an outgoing fit takes of a flight law
    (a :class:`PuckParams`' or :meth:`AccelerationAdaptation.flight_law`'s)."""
    return damping, friction_surface, float(table_acceleration[0]), float(table_acceleration[1])


def _law_of(p: PuckParams) -> tuple[float, float, float, float]:
    """:func:`_flight_law_of` the parameters ``p``."""
    return _flight_law_of(p.damping, p.friction_surface, p.table_acceleration)


def _law_moved(old: tuple, new: tuple, speed: float) -> float:
    """[m/s^2] How far the acceleration of flight law ``old`` is from ``new``'s (:func:`_flight_law_of`) at
    ``speed`` [m/s], at most."""
    return math.hypot(new[2] - old[2], new[3] - old[3]) + abs(new[0] - old[0]) * speed + abs(new[1] - old[1])


def _line_at_impact(times: list, poses: list, t_impact: float, p: PuckParams):
    """A line fit of ``poses`` at ``times`` [s] taken to the impact at ``t_impact`` [s] with the flight law of
    ``p`` (:func:`~.rim_adaptation.outgoing_fit`): the frames after it give the outgoing path, those before
    it the incoming one."""
    return outgoing_fit(times, poses, t_impact,
                        flight_acceleration(p.damping, p.friction_surface, p.table_acceleration), p.spin_damping)


@dataclass
class _ImpactWatch:
    """A rim impact the model put between two frames, awaiting the fused frames after it."""

    t: float              # [s] impact time
    wall: int
    before: tuple         # incoming (vb, vn, omega) in the rim's frame
    path: tuple = ()      # the incoming straight path at the impact time: position, velocity (x, y) [m, m/s]
    times: list = field(default_factory=list)
    poses: list = field(default_factory=list)
    law: tuple = ()       # the flight law when it was watched (:func:`_flight_law_of`)
    earlier: tuple = ((), ())  # the flight window's frames before it (times, poses), kept to derive it again


class TableLearning:
    """The rim law and the table acceleration learned online on top of ``base`` (either may be off)."""

    def __init__(self, base: PuckParams, table: TableGeometry, rim: AdaptationSettings | None,
                 acceleration: AccelerationSettings | None, angle_variance: float,
                 marker_offset: tuple[float, float] = (0.0, 0.0)) -> None:
        self.base, self.table = base, table
        self.configured_offset = (float(marker_offset[0]), float(marker_offset[1]))  # [m] puck frame
        self.rim = None if rim is None else RimAdaptation(base, table, rim)
        self.acceleration = (None if acceleration is None
                             else AccelerationAdaptation(base, acceleration, self.configured_offset))
        self.learns_offset = self.acceleration is not None and self.acceleration.learns_offset
        self.angle_variance = angle_variance  # [rad^2] the measured angle's noise (R's last entry)
        self.spin = (SpinAdaptation(base.spin_damping, acceleration.spin_prior_std, acceleration.spin_gate,
                                    angle_variance)
                     if acceleration is not None and acceleration.spin_prior_std > 0.0 else None)
        self.delay = None if rim is None else DelayAdaptation(base.impact_delay, rim.prior_impacts, rim.max_delay,
                                                              rim.offset_warning, rim.offset_significance)
        self.windows = 0  # free-flight windows learned from (the acceleration's, the spin's or both)
        self._watch: _ImpactWatch | None = None
        # the first impacts watched, kept to be derived again as the flight law is learned (None: beyond
        # rim_adaptation.rederive_impacts, no more), the flight law they were last derived with, their top speed
        self._kept: list[_ImpactWatch] | None = [] if rim is not None and rim.rederive_impacts > 0 else None
        self._kept_law: tuple[float, float, float, float] | None = None
        self._kept_speed = 0.0
        self._times: list[float] = []   # the free-flight window being collected
        self._poses: list = []          # its poses, the position taken back to the centre (as fused)
        self._pivots: list = []         # and as measured (the pivot's), kept while the offset is learned
        self._halfway = False   # its first half was learned from (provisionally)
        self._counted = False   # it was counted in windows

    @classmethod
    def from_params(cls, base: PuckParams, table: TableGeometry, params: Mapping[str, Any]) -> "TableLearning | None":
        """The learning ``params`` switch on, or None when both are off."""
        rim, acc = AdaptationSettings.from_params(params), AccelerationSettings.from_params(params)
        if not (rim.enabled or acc.enabled):
            return None
        return cls(base, table, rim if rim.enabled else None, acc if acc.enabled else None,
                   params["measurement_noise"][2], tuple(params["marker_offset"]))

    def restarted(self, base: PuckParams) -> "TableLearning":
        """The same learning from new configured parameters (nothing learned yet)."""
        return TableLearning(base, self.table, None if self.rim is None else self.rim.settings,
                             None if self.acceleration is None else self.acceleration.settings, self.angle_variance,
                             self.configured_offset)

    def params(self) -> PuckParams:
        """The configured parameters with what was learned so far."""
        p = self.base if self.rim is None else self.rim.params()
        if self.acceleration is not None and self.acceleration.windows:
            p = p.with_values(**self.acceleration.flight_law())
        if self.spin is not None and self.spin.windows:
            p = p.with_values(spin_damping=self.spin.value)
        if self.delay is not None and self.delay.impacts:
            p = p.with_values(impact_delay=self.delay.value)
        return p

    @property
    def marker_offset(self) -> tuple[float, float]:
        """[m] The pivot's offset from the centre (puck frame): learned, or the configured one."""
        return self.acceleration.offset if self.learns_offset else self.configured_offset

    def forget(self) -> None:
        """The track broke (a hit, a restart): drop the impact being watched and the flight window."""
        self._watch = None
        self._new_window()

    def _new_window(self) -> None:
        """Start collecting a flight window (what the last one learned provisionally stays learned)."""
        if self.acceleration is not None:
            self.acceleration.commit()
        self._times, self._poses, self._pivots, self._halfway, self._counted = [], [], [], False, False

    def after_frame(self, model: PuckModel, t: float, z, before: np.ndarray, p: np.ndarray,
                    stamp: float) -> PuckParams | None:
        """Frame ``t`` [s] was handled without a restart; ``z`` is its fused pose (None if it fused none:
        lost or rejected), ``before`` / ``p`` the state and covariance at the previous frame ``stamp`` [s].
        Returns the parameters to use from now on when something was learned, else None."""
        dt = t - stamp
        state = before[:4].tolist()
        vx, vy = state[2], state[3]
        hit = None if dt <= 0.0 or self.table.clear_of_rims(*state, dt) else model.first_impact(*state, dt)
        learned = False
        if hit is not None:
            earlier = (self._times, self._poses)
            learned |= self._end_window()  # its frames all came before the impact
            self._watch = self._new_watch(before, p, stamp, hit) if self.rim is not None else None
            if self._watch is not None and self._kept is not None:
                self._watch.law, self._watch.earlier = _law_of(model.params), earlier
        if z is not None:
            if self._watch is not None and t > self._watch.t:
                learned |= self._watch_rim(model, t, z)
            if self.acceleration is not None and hit is None:
                learned |= self._fly(t, z, math.hypot(vx, vy))
        return self.params() if learned else None

    def _new_watch(self, before: np.ndarray, p: np.ndarray, stamp: float, hit) -> _ImpactWatch | None:
        tau, wall = hit
        x, y, vx, vy, _, omega = before.tolist()
        if wall >= FIRST_POST:
            return None  # a post, met as a corner (core/table.py): the rim law is learned from the rims' faces
        vb, vn = rim_frame(wall, vx, vy)
        settings = self.rim.settings
        certain = p[2, 2] + p[3, 3] <= (settings.max_incoming_uncertainty ** 2) * (vx * vx + vy * vy)
        fast = -vn >= settings.min_normal_speed
        path = (np.array([x + tau * vx, y + tau * vy]), np.array([vx, vy]))
        return _ImpactWatch(stamp + tau, wall, (vb, vn, omega), path) if certain and fast else None

    def _watch_rim(self, model: PuckModel, t: float, z) -> bool:
        watch, settings = self._watch, self.rim.settings
        watch.times.append(t)
        watch.poses.append(z)
        if t - watch.t < settings.window:
            return False
        self._watch = None
        if len(watch.times) < settings.min_frames:
            return False
        p = model.params
        fit = _line_at_impact(watch.times, watch.poses, watch.t, p)
        if fit is None:
            return False
        self._keep(watch, p)
        if not self.rim.observe(watch.before, (*rim_frame(watch.wall, fit.vx, fit.vy), fit.omega)):
            return False
        met = paths_meet(WALL_NORMALS[watch.wall], *watch.path, fit.position, np.array([fit.vx, fit.vy]))
        if met is not None:  # how far beyond the rim line the paths meet: a compliant rim's delay
            self.delay.observe(met[1] + self.table.wall_offset(watch.wall), -watch.before[1], watch.wall)
        return True

    def _keep(self, watch: _ImpactWatch, p: PuckParams) -> None:
        """Keep an impact about to be learned from (derived with the flight law of ``p``) while there is room."""
        if self._kept is None:
            return
        if len(self._kept) >= self.rim.settings.rederive_impacts:
            self._kept = None  # the law is learned by now: what was derived stays
            return
        self._kept.append(watch)
        self._kept_law = self._kept_law or _law_of(p)
        self._kept_speed = max(self._kept_speed, math.hypot(watch.before[0], watch.before[1]))

    def _rederive(self) -> bool:
        """Derive the kept impacts again, in order, into a new rim law when the learned flight law's
        acceleration at their speeds has moved by ``rederive_tolerance`` since they were; True if so."""
        if not self._kept:
            return False
        law = _flight_law_of(**self.acceleration.flight_law())  # as self.params() takes it (a window was learned)
        if _law_moved(self._kept_law, law, self._kept_speed) < self.rim.settings.rederive_tolerance:
            return False
        p = self.params()
        rim = RimAdaptation(self.base, self.table, self.rim.settings)
        for watch in self._kept:
            fit = _line_at_impact(watch.times, watch.poses, watch.t, p)
            if fit is not None:
                rim.observe(self._incoming(watch, p, law), (*rim_frame(watch.wall, fit.vx, fit.vy), fit.omega))
        self.rim, self._kept_law = rim, law
        return True

    def _incoming(self, watch: _ImpactWatch, p: PuckParams, law: tuple) -> tuple:
        """The watched impact's incoming (vb, vn, omega): the filter's state before it, or, when the flight
        law then was off by more than ``rederive_incoming`` at its speed (the filter lagged), a line fit of
        the rim window's frames before it with the law ``p`` learned since, taken to the impact."""
        settings, then = self.rim.settings, watch.law
        off = _law_moved(then, law, math.hypot(watch.before[0], watch.before[1]))
        times, poses = watch.earlier
        near = [i for i, t in enumerate(times) if t >= watch.t - settings.window]
        if off <= settings.rederive_incoming or len(near) < settings.min_frames:
            return watch.before
        fit = _line_at_impact([times[i] for i in near], [poses[i] for i in near], watch.t, p)
        return watch.before if fit is None else (*rim_frame(watch.wall, fit.vx, fit.vy), fit.omega)

    def _fly(self, t: float, z, speed: float) -> bool:
        """Collect frame ``t`` of a puck at ``speed`` [m/s] into the flight window. The window's first half
        is learned from provisionally (an estimate as early as a window half as long gives); the whole
        window, or what was collected when an impact or a slow-down (below ``min_speed``: at rest the
        surface may hold the puck) cut it short, replaces it."""
        settings = self.acceleration.settings
        if speed < settings.min_speed:
            return self._end_window()
        self._times.append(t)
        self._poses.append(z)
        if self.learns_offset:
            dx, dy = pivot_shift(float(z[2]), self.acceleration.offset)
            self._pivots.append((z[0] + dx, z[1] + dy, z[2]))
        span = t - self._times[0]
        if span >= settings.window:
            return self._end_window()
        if not self._halfway and span >= 0.5 * settings.window:
            self._halfway = True
            return self._learn_window(provisional=True)
        return False

    def _end_window(self) -> bool:
        """Learn from the flight window collected so far and start a new one; True when learned from."""
        learned = self._learn_window(provisional=False)
        self._new_window()
        return learned

    def _learn_window(self, provisional: bool) -> bool:
        """Learn the acceleration (and, from a whole window, the spin's decay) from the window's frames when
        it holds ``min_frames``; count each window once."""
        times, poses = self._times, self._poses
        if self.acceleration is None or len(times) < self.acceleration.settings.min_frames:
            return False
        sensitivity = None
        if self.learns_offset:  # the positions taken back with the offset learned so far
            pivots = np.array(self._pivots)
            poses = centres_of(pivots, self.acceleration.offset)
            sensitivity = offset_sensitivity(times, pivots[:, 2])
        fit = quadratic_fit(times, poses)
        learned = fit is not None and self.acceleration.observe(*fit, provisional=provisional,
                                                                sensitivity=sensitivity)
        if learned and not provisional:  # a window the table alone moved
            self._rederive()  # the flight law moved: the first impacts derived with it again
            if self.learns_offset:
                self.acceleration.observe_offset(times, pivots)
        if self.spin is not None and not provisional:
            learned |= self.spin.observe(times, [pose[2] for pose in poses])
        self.windows += int(learned and not self._counted)
        self._counted |= learned
        return learned

    @property
    def counts(self) -> tuple[int, int]:
        """(rim impacts, free-flight windows) learned from so far."""
        return 0 if self.rim is None else self.rim.impacts, self.windows

    @property
    def events(self) -> int:
        """Rim impacts and free-flight windows learned from so far."""
        return sum(self.counts)

    def report(self) -> dict:
        """What was learned: ``rim_law`` (:meth:`RimAdaptation.report`), ``table_acceleration``
        (windows, value and std [m/s^2], the damping and surface friction), ``spin_damping`` (windows,
        value and std [1/s]), ``impact_delay`` and ``marker_offset`` (windows, value and std [m]), each
        None when not learned."""
        parts = (self.rim, self.acceleration, self.spin, self.delay)
        report = {key: None if part is None else part.report() for key, part in zip(REPORT_KEYS, parts)}
        report["marker_offset"] = self.acceleration.offset_report() if self.learns_offset else None
        return report


def learning_report(learning: TableLearning | None) -> dict:
    """:meth:`TableLearning.report`, or its keys all None when the tracker learns nothing."""
    return {key: None for key in REPORT_KEYS} if learning is None else learning.report()


def describe_learning(report: dict) -> str:
    """A :meth:`TableLearning.report` in words, for logs and tables."""
    parts = []
    if report["rim_law"] is not None:
        parts.append("rim law " + describe(report["rim_law"]))
    flight = report["table_acceleration"]
    if flight is not None:
        (gx, gy), (sx, sy) = flight["value"], flight["std"]
        friction = ("" if flight.get("friction_surface_std") is None else
                    f", surface friction {flight['friction_surface']:.4f} +- {flight['friction_surface_std']:.4f} "
                    f"m/s^2")
        parts.append(f"table acceleration ({gx:+.4f} +- {sx:.4f}, {gy:+.4f} +- {sy:.4f}) m/s^2, damping "
                     f"{flight['damping']:.4f} +- {flight['damping_std']:.4f} 1/s{friction} from "
                     f"{flight['windows']} free-flight window{'' if flight['windows'] == 1 else 's'}")
    if report.get("spin_damping") is not None:
        parts.append(describe_spin(report["spin_damping"]))
    delay = report.get("impact_delay")
    if delay is not None and delay["impacts"]:
        parts.append(f"impact delay {delay['value'] * 1e3:.3f} ms from {delay['impacts']} "
                     f"impact{'' if delay['impacts'] == 1 else 's'}")
        if delay.get("rims_off"):
            parts.append(rims_off_text(delay["rim_offsets"], delay["rims_off"]))
    offset = report.get("marker_offset")
    if offset is not None and offset["windows"]:
        (ox, oy), (sx, sy) = offset["value"], offset["std"]
        parts.append(f"marker offset ({ox * 1e3:+.2f} +- {sx * 1e3:.2f}, {oy * 1e3:+.2f} +- {sy * 1e3:.2f}) mm from "
                     f"{offset['windows']} window{'' if offset['windows'] == 1 else 's'}")
    noise = report.get("marker_noise")
    if noise is not None and noise["windows"]:
        parts.append(describe_noise(noise))
    process = report.get("process_noise")
    if process is not None and describe_process_noise(process):
        parts.append(describe_process_noise(process))
    return "; ".join(parts)


def rims_off_text(offsets: dict, names: list) -> str:
    """The rims whose impacts meet off their lines, in words."""
    each = ", ".join(f"{name} {abs(o['offset_m']) * 1e3:.2f} +- {o['std_m'] * 1e3:.2f} mm "
                     f"{'inside' if o['offset_m'] > 0 else 'beyond'} ({o['impacts']} impacts)"
                     for name, o in ((n, offsets[n]) for n in names))
    return (f"rims met off their lines: {each}: the table's pose or size is off there (mocap_table_pose, "
            f"table.length / table.width; `sysid --method split` moves them)")

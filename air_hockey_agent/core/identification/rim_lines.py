"""Where a table's rims are, from where its impacts' paths meet (issue #13 item 5; ``sysid --method split
--identify table_geometry``).

Each rim's offset (:class:`~.impact_fit.DelayFit`: where the straight paths before and after its impacts
meet at no speed, from the model's rim line, > 0 inside the table) places it; two opposite rims give
their axis's centre and the distance between them:

* centre, in the table frame the poses were read in: x = (o_near - o_far) / 2, y = (o_left - o_right) / 2
  (the left rim is at y = -W/2, :data:`~air_hockey_agent.core.table.WALL_NAMES`); a ``mocap_table_pose``
  a few millimetres off moves opposite rims apart, and every impact's outgoing path by about twice that;
* size: length' = length - (o_far + o_near), width' = width - (o_left + o_right) (a table measured a
  little larger or smaller than its rims stand, or rims whose cushion the puck reaches sooner);
* yaw: a table turned by a small angle from the model's makes each rim's offset grow along it at that
  rate (:attr:`~.impact_fit.DelayFit.yaw`: one rate shared by the four rims, along b = (n_y, -n_x)).

A part is taken only where both of its rims were met and it differs from the configured geometry by more
than ``significance`` standard errors (the offsets' covariance, :attr:`~.impact_fit.DelayFit.covariance`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from air_hockey_agent.core.frames import table_to_mocap
from air_hockey_agent.core.identification.impact_fit import DelayFit
from air_hockey_agent.core.identification.local_fit import beyond_noise
from air_hockey_agent.core.identification.preprocess import GridTrajectory
from air_hockey_agent.core.table import WALL_FAR, WALL_LEFT, WALL_NEAR, WALL_RIGHT

# (name, rims and their signs) of each part: centre = (sign_a o_a + sign_b o_b) / 2, size = -(o_a + o_b)
PARTS = (("centre_x", ((WALL_NEAR, 0.5), (WALL_FAR, -0.5))), ("centre_y", ((WALL_LEFT, 0.5), (WALL_RIGHT, -0.5))),
         ("length", ((WALL_FAR, -1.0), (WALL_NEAR, -1.0))), ("width", ((WALL_LEFT, -1.0), (WALL_RIGHT, -1.0))))


@dataclass(frozen=True)
class RimLines:
    """The rims' centre (x, y) [m] in the table frame as read, the change of the distances between them
    (length, width) [m] and their turn (yaw [rad]), each with its standard error (NaN where a rim of the
    pair was not met), which parts are taken (significant and within bounds) and which lie beyond the
    bounds."""

    values: dict    # part name (PARTS) -> [m]
    std: dict       # part name -> [m]
    taken: dict     # part name -> bool
    beyond: dict    # part name -> bool: significant but outside the bounds (not taken)

    def centre(self) -> tuple[float, float]:
        """The taken centre (x, y) [m]: 0 along an axis not taken."""
        return tuple(self.values[n] if self.taken[n] else 0.0 for n in ("centre_x", "centre_y"))

    def yaw(self) -> float:
        """The taken turn [rad]: 0 when not taken."""
        return self.values["yaw"] if self.taken["yaw"] else 0.0

    @property
    def any_taken(self) -> bool:
        return any(self.taken.values())


def rim_lines(delay: DelayFit, significance: float, bounds: tuple[float, float], yaw_bounds: tuple[float, float],
              centre: bool = True) -> RimLines:
    """The rims' centre, size changes and turn from ``delay``'s offsets, their covariance and its yaw; a part
    is taken when it is beyond ``significance`` standard errors and within ``bounds`` (low, high) [m] (the
    yaw within ``yaw_bounds`` [rad]; farther, the table's configuration is wrong, not its calibration); the
    centre and yaw only with ``centre`` (poses read through ``mocap_table_pose``, which can move)."""
    values, std = {}, {}
    for name, terms in PARTS:
        if not all(rim in delay.offsets for rim, _ in terms):
            values[name] = std[name] = math.nan
            continue
        values[name] = float(sum(sign * delay.offsets[rim][0] for rim, sign in terms))
        variance = sum(sa * sb * delay.covariance.get((a, b), 0.0) for a, sa in terms for b, sb in terms)
        std[name] = math.sqrt(max(variance, 0.0))
    values["yaw"], std["yaw"] = delay.yaw
    taken, beyond = {}, {}
    for name in values:
        low, high = yaw_bounds if name == "yaw" else bounds
        significant = beyond_noise(values[name], std[name], significance)
        inside = low <= values[name] <= high
        movable = centre or name not in ("centre_x", "centre_y", "yaw")
        taken[name], beyond[name] = significant and inside and movable, significant and not inside
    return RimLines(values, std, taken, beyond)


def corrected_geometry(tracker: Mapping[str, Any], lines: RimLines) -> dict:
    """Tracker parameters that put the model's rims where ``lines`` found them: ``mocap_table_pose`` moved by
    the taken centre (turned into the mocap frame by its yaw) and turned by the taken yaw, ``table.length``
    and ``table.width`` changed by the taken sizes. Only the parameters that change."""
    out = {}
    (cx, cy), yaw = lines.centre(), lines.yaw()
    if cx or cy or yaw:
        p = [float(v) for v in tracker["mocap_table_pose"]]
        x, y, turned = table_to_mocap(cx, cy, yaw, p)
        out["mocap_table_pose"] = [x, y, p[2], turned]
    for part, name in (("length", "table.length"), ("width", "table.width")):
        if lines.taken[part]:
            out[name] = float(tracker[name] + lines.values[part])
    return out


def recentred(trajectory: GridTrajectory, centre: tuple[float, float], yaw: float = 0.0) -> GridTrajectory:
    """A copy of ``trajectory`` measured in the moved table frame: origin at the rims' ``centre`` (x, y) [m],
    turned by ``yaw`` [rad] (positions and angles); the input is not changed."""
    z = np.array(trajectory.z, float)
    c, s = math.cos(yaw), math.sin(yaw)
    dx, dy = z[:, 0] - centre[0], z[:, 1] - centre[1]
    z[:, 0], z[:, 1] = c * dx + s * dy, -s * dx + c * dy
    if yaw:
        z[:, 2] = np.angle(np.exp(1j * (z[:, 2] - yaw)))
    return GridTrajectory(trajectory.t0, trajectory.dt, z)

"""Table geometry in the table frame (README "Frames and units").

The puck centre moves inside the rectangle |x| <= L/2 - r, |y| <= W/2 - r. Each rim is a line of that
rectangle described by its inward unit normal ``n`` (pointing from the rim into the table) and the
signed distance ``n . p + offset`` of the puck centre from it (positive inside). The short rims have
the goal opening: where a short rim line is crossed with |y| < goal_width/2 there is no rim face behind it
(no line impact), but the rim's two ends beside the opening, the posts at x = +-L/2, y = +-goal_width/2,
stand there: a puck whose edge reaches a post before its centre is past the rim's face x = +-L/2 meets it
as a corner, with the normal from the post to its centre (:func:`post_contact_time`); a puck whose
centre gets past the face is in the goal. Contacts are numbered: the four rims (``WALL_*``), then the
four posts (``FIRST_POST`` + k, :func:`post_position`; :func:`contact_rim` names a post's rim).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Mapping

WALL_LEFT, WALL_FAR, WALL_RIGHT, WALL_NEAR = 0, 1, 2, 3  # same values as air_hockey_msgs/WallImpact
WALL_NAMES = ("left", "far", "right", "near")
# Inward normals: left rim y = -W/2, far rim x = +L/2, right rim y = +W/2, near rim x = -L/2.
WALL_NORMALS = ((0.0, 1.0), (-1.0, 0.0), (0.0, -1.0), (1.0, 0.0))
SHORT_WALLS = (WALL_FAR, WALL_NEAR)
FIRST_POST = 4  # contact ids FIRST_POST + k, k = 0..3: the far rim's posts at y = -, + goal_width/2, then the near's
POST_COUNT = 4


@dataclass(frozen=True)
class TableGeometry:
    """Playing surface and puck size [m]; thesis sec. 4.5, ``config/table.yaml``."""

    length: float
    width: float
    goal_width: float
    puck_radius: float

    @classmethod
    def from_params(cls, params: Mapping[str, Any]) -> "TableGeometry":
        return cls(params["table.length"], params["table.width"], params["table.goal_width"],
                   params["puck.radius"])

    @property
    def x_limit(self) -> float:
        """Largest |x| of the puck centre before it touches a short rim [m]."""
        return self.length / 2 - self.puck_radius

    @property
    def y_limit(self) -> float:
        """Largest |y| of the puck centre before it touches a long rim [m]."""
        return self.width / 2 - self.puck_radius

    @property
    def goal_mouth(self) -> float:
        """Largest |y| at which the puck centre passes through a goal opening [m]."""
        return self.goal_width / 2 - self.puck_radius

    def wall_offset(self, wall: int) -> float:
        """Offset h of rim ``wall``: the puck centre's distance from it is ``n . p + h``."""
        return self.x_limit if wall in SHORT_WALLS else self.y_limit

    def distance_to_wall(self, wall: int, x: float, y: float) -> float:
        """Signed distance of the puck centre from the rim line (positive inside the table) [m]."""
        nx, ny = WALL_NORMALS[wall]
        return nx * x + ny * y + self.wall_offset(wall)

    @property
    def scored_x(self) -> float:
        """|x| [m] beyond which a puck centre is a radius past a goal line's face: in the goal, out of every
        post's reach (the model holds it there)."""
        return self.x_limit + 2.0 * self.puck_radius

    def in_goal_mouth(self, y: float) -> bool:
        """True when a puck centre at this y passes through a goal opening."""
        return abs(y) < self.goal_mouth

    def post_position(self, contact: int) -> tuple[float, float]:
        """Where post ``contact`` (``FIRST_POST`` + k) stands [m]: a short rim's end beside its goal opening
        (computed as the compiled prediction computes it, from the centre's limits)."""
        r = self.puck_radius
        return post_position(contact, self.x_limit + r, self.goal_mouth + r)

    def clear_of_rims(self, x: float, y: float, vx: float, vy: float, seconds: float) -> bool:
        """True when a puck centre at (x, y) [m] moving at (vx, vy) [m/s] reaches no rim line flying
        straight for ``seconds`` [s], either way."""
        return abs(x) + abs(vx) * seconds < self.x_limit and abs(y) + abs(vy) * seconds < self.y_limit

    def contains(self, x: float, y: float, margin: float = 0.0) -> bool:
        """True when the puck centre is on the table, up to ``margin`` beyond the rims [m]."""
        return abs(x) <= self.length / 2 + margin and abs(y) <= self.width / 2 + margin


def post_position(contact: int, half_length: float, half_goal: float) -> tuple[float, float]:
    """Post ``contact`` (``FIRST_POST`` + k) at (+-``half_length``, +-``half_goal``) [m]: k 0, 1 on the far
    rim (x > 0), 2, 3 on the near one; even k at y < 0. Scalars only (compiled by the prediction)."""
    k = contact - FIRST_POST
    return (half_length if k < 2 else -half_length), (-half_goal if k % 2 == 0 else half_goal)


def contact_rim(contact: int) -> int:
    """The rim a contact belongs to: a rim's own id, a post's short rim (``WALL_FAR`` or ``WALL_NEAR``)."""
    if contact < FIRST_POST:
        return contact
    return WALL_FAR if contact - FIRST_POST < 2 else WALL_NEAR


def post_contact_time(x: float, y: float, vx: float, vy: float, px: float, py: float, radius: float) -> float:
    """Time [s] until a puck of ``radius`` [m] whose centre flies straight from (x, y) with velocity (vx, vy)
    [m/s] touches the post at (px, py) while moving toward it, with its centre not past the rim's face
    (|x| <= |px|: behind it the goal's sides would act, which are not modelled); for a puck already
    overlapping and approaching it, the (negative) time since its straight path touched; inf for none.
    Scalars only: the compiled prediction compiles it."""
    dx, dy = x - px, y - py
    closing = dx * vx + dy * vy  # < 0 while the centre approaches the post
    if closing >= 0.0:
        return math.inf
    gap = dx * dx + dy * dy - radius * radius
    speed2 = vx * vx + vy * vy
    disc = closing * closing - speed2 * gap
    if disc < 0.0:
        return math.inf
    root = math.sqrt(disc)
    t = gap / (root - closing) if gap > 0.0 else -(closing + root) / speed2  # the smaller root, without cancellation
    if (x + t * vx - px) * px > 0.0:
        return math.inf
    return t

"""Table geometry in the table frame (README "Frames and units").

The puck centre moves inside the rectangle |x| <= L/2 - r, |y| <= W/2 - r. Each rim is a line of that
rectangle described by its inward unit normal ``n`` (pointing from the rim into the table) and the
signed distance ``n . p + offset`` of the puck centre from it (positive inside). The short rims have
the goal opening: a puck whose centre crosses a short rim line with |y| < goal_width/2 - r enters the goal
(no impact), unless its edge meets a post (the rim's end at x = +-L/2, y = +-goal_width/2) before its centre
reaches the rim's face x = +-L/2: a steep puck does, and comes back (:meth:`TableGeometry.enters_goal`).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping

WALL_LEFT, WALL_FAR, WALL_RIGHT, WALL_NEAR = 0, 1, 2, 3  # same values as air_hockey_msgs/WallImpact
WALL_NAMES = ("left", "far", "right", "near")
# Inward normals: left rim y = -W/2, far rim x = +L/2, right rim y = +W/2, near rim x = -L/2.
WALL_NORMALS = ((0.0, 1.0), (-1.0, 0.0), (0.0, -1.0), (1.0, 0.0))
SHORT_WALLS = (WALL_FAR, WALL_NEAR)


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

    def in_goal_mouth(self, y: float) -> bool:
        """True when a puck centre at this y passes through a goal opening."""
        return abs(y) < self.goal_mouth

    def enters_goal(self, x: float, y: float, vx: float, vy: float) -> bool:
        """True when a puck whose centre crosses a short rim line at (x, y) [m] with velocity (vx, vy) [m/s]
        enters the goal: inside the mouth, and its edge does not meet a post on the way from the line to
        the rim's face (the centre's straight path over that last puck radius; beyond the face the goal's
        sides only steer it, its motion toward the goal kept)."""
        r = self.puck_radius  # face and post as the compiled prediction computes them
        return abs(y) < self.goal_mouth and not meets_post(x, y, vx, vy, self.x_limit + r, self.goal_mouth + r, r)

    def contains(self, x: float, y: float, margin: float = 0.0) -> bool:
        """True when the puck centre is on the table, up to ``margin`` beyond the rims [m]."""
        return abs(x) <= self.length / 2 + margin and abs(y) <= self.width / 2 + margin


def meets_post(x: float, y: float, vx: float, vy: float, face: float, post: float, radius: float) -> bool:
    """True when a puck of ``radius`` [m] whose centre goes straight from (x, y) with velocity (vx, vy) to
    the rim face |x| = ``face`` comes within its radius of a post at (+-face, +-post) [m] (table frame).
    Scalars only: the compiled prediction compiles this function itself."""
    if vx == 0.0:
        return False
    end_x = face if vx > 0.0 else -face
    t = (end_x - x) / vx  # [s] to the face
    dx, dy = end_x - x, t * vy
    length2 = dx * dx + dy * dy
    for post_y in (post, -post):
        s = 0.0 if length2 == 0.0 else min(1.0, max(0.0, (dx * dx + (post_y - y) * dy) / length2))
        gx, gy = end_x - (x + s * dx), post_y - (y + s * dy)
        if gx * gx + gy * gy < radius * radius:
            return True
    return False

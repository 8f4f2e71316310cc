"""The puck on a MuJoCo table: a second physics engine as the truth of synthetic sessions (issue #13 item 1).

The tracker's model, the test bed (:mod:`air_hockey_agent.core.puck.real_table`) and the pybullet table's
rim impacts (:mod:`.rim_contact`) are all written here; a filter or an identification that agrees with
them may agree with our own arithmetic. MuJoCo (https://mujoco.org) is an independent engine: its rims
are soft constraints solved with a finite stiffness and damping, so a rim impact lasts several
milliseconds, its restitution depends on where in a time step the contact starts, and its tangential
impulse comes from a soft friction constraint, not from Routh's impact (thesis eq. 3.2-3.3). Nothing
of the tracker's model is used to make the trajectories.

The scene, written from ``config/table.yaml``'s geometry and ``mujoco.*`` in ``config/synthetic.yaml``:

- the puck: a body with two horizontal slide joints and a vertical hinge (no z motion, no contact with
  the surface), damped by ``damping`` [1/s] and ``angular_damping`` [1/s] (joint damping = rate x mass
  or inertia); its collision shape is a sphere of the puck's radius centred on the rims' mid-height,
  so the rims meet its equator, a circle of the puck's radius as a disc's edge would (sphere-box
  contacts are exact in MuJoCo, a cylinder's go through its general convex collider); its inertia
  is the disc's, m r^2 / 2 about the vertical;
- the rims: boxes outside the playing surface, the short ones split around the goal mouth (a puck
  that passes the goal line leaves the table); soft contacts with ``rim_timeconst`` / ``rim_dampratio``
  (MuJoCo's solref), ``rim_solimp`` and sliding friction ``rim_friction``;
- a tilted surface as gravity's component along the table: g sin(tilt) toward ``tilt_heading``.

State and frame as the tracker's: ``(x, y, vx, vy, theta, omega)`` in the table frame [m, m/s, rad,
rad/s] (README "Frames and units").
"""
from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import Any, Mapping

import mujoco
import numpy as np

from air_hockey_agent.core.puck.model import wrap_angle
from air_hockey_agent.core.puck.real_table import held_then_hit
from air_hockey_agent.core.puck.surface_field import GRAVITY, tilt_acceleration
from air_hockey_agent.core.table import TableGeometry

RIM_HALF_THICKNESS = 0.05  # [m] the puck meets the rims' inner faces, and beside a goal mouth their ends (posts)
RIM_HALF_HEIGHT = 0.02     # [m] below the puck's radius, so the sphere touches a rim's face at its equator


@dataclass(frozen=True)
class MujocoTable:
    """The MuJoCo table's physics (``mujoco.*`` in ``config/synthetic.yaml``, where the values come from)."""

    timestep: float              # [s] MuJoCo's integration step
    puck_mass: float             # [kg]
    damping: float               # [1/s] viscous damping of the puck's velocity
    angular_damping: float       # [1/s] viscous damping of its spin
    tilt: float                  # [rad] slope of the surface
    tilt_heading: float          # [rad] direction (table frame) the surface falls toward
    rim_timeconst: float         # [s] MuJoCo solref: time constant of the rim contact
    rim_dampratio: float         # [-] MuJoCo solref: damping ratio of the rim contact
    rim_solimp: tuple            # MuJoCo solimp of the rim contact (dmin, dmax, width [m], midpoint, power)
    rim_friction: float          # [-] sliding friction of the rim contact

    def __post_init__(self) -> None:
        """MuJoCo clamps a solimp out of its ranges without a word: refuse it instead (ValueError)."""
        dmin, dmax, width, midpoint, power = self.rim_solimp
        if not (0.0 < dmin < 1.0 and 0.0 < dmax < 1.0 and width > 0.0 and 0.0 < midpoint < 1.0 and power >= 1.0):
            raise ValueError(f"parameter 'mujoco.rim_solimp' = {list(self.rim_solimp)} is not MuJoCo's solimp "
                             "(dmin and dmax in (0, 1), width > 0 [m], midpoint in (0, 1), power >= 1)")

    @classmethod
    def from_params(cls, params: Mapping[str, Any], prefix: str = "mujoco.") -> "MujocoTable":
        """From parameters named ``<prefix><field>`` (e.g. ``mujoco.damping``)."""
        scalars = {f.name: float(params[prefix + f.name]) for f in fields(cls) if f.name != "rim_solimp"}
        return cls(rim_solimp=tuple(float(v) for v in params[prefix + "rim_solimp"]), **scalars)

    @property
    def tilt_acceleration(self) -> np.ndarray:
        """Acceleration [m/s^2] of the tilted surface in the table's plane (table frame)."""
        return np.array(tilt_acceleration(self.tilt, self.tilt_heading))


def scene_xml(table: TableGeometry, physics: MujocoTable) -> str:
    """The MJCF text of the puck and the rims (see the module's docstring)."""
    m, r = physics.puck_mass, table.puck_radius
    gx, gy = physics.tilt_acceleration
    gz = -GRAVITY * math.cos(physics.tilt)
    solimp = " ".join(f"{v:g}" for v in physics.rim_solimp)
    t, h = RIM_HALF_THICKNESS, RIM_HALF_HEIGHT
    half_long = table.length / 2 + 2 * t  # the long rims close the corners
    side = (table.width / 2 - table.goal_width / 2) / 2  # half length of a short rim's part beside the goal
    rims = [(0.0, sy * (table.width / 2 + t), half_long, t) for sy in (1, -1)]
    rims += [(sx * (table.length / 2 + t), sy * (table.goal_width / 2 + side), t, side)
             for sx in (1, -1) for sy in (1, -1)]
    rim_geoms = "\n".join(f'    <geom class="rim" pos="{x:.6f} {y:.6f} 0" size="{sx:.6f} {sy:.6f} {h}"/>'
                          for x, y, sx, sy in rims)
    inertia = m * r * r
    return f"""<mujoco model="air_hockey_puck">
  <option timestep="{physics.timestep:g}" gravity="{gx:.9g} {gy:.9g} {gz:.9g}" integrator="implicitfast"
          cone="elliptic"/>
  <default>
    <default class="rim">
      <geom type="box" condim="3" priority="1" friction="{physics.rim_friction:g} 0 0"
            solref="{physics.rim_timeconst:g} {physics.rim_dampratio:g}" solimp="{solimp}"/>
    </default>
  </default>
  <worldbody>
{rim_geoms}
    <body name="puck">
      <joint name="puck_x" type="slide" axis="1 0 0" damping="{physics.damping * m:.9g}"/>
      <joint name="puck_y" type="slide" axis="0 1 0" damping="{physics.damping * m:.9g}"/>
      <joint name="puck_yaw" type="hinge" axis="0 0 1" damping="{physics.angular_damping * inertia / 2:.9g}"/>
      <inertial pos="0 0 0" mass="{m:g}" diaginertia="{inertia / 4:.9g} {inertia / 4:.9g} {inertia / 2:.9g}"/>
      <geom name="puck" type="sphere" size="{r:g}" mass="0"/>
    </body>
  </worldbody>
</mujoco>
"""


class MujocoPuck:
    """A puck on the MuJoCo table; :meth:`simulate` integrates one shot."""

    def __init__(self, table: TableGeometry, physics: MujocoTable) -> None:
        self.table, self.physics = table, physics
        self.model = mujoco.MjModel.from_xml_string(scene_xml(table, physics))
        self.data = mujoco.MjData(self.model)

    def set_state(self, state: np.ndarray) -> None:
        """Place the puck at ``state`` (x, y, vx, vy, theta, omega) and clear the contacts' warm start."""
        mujoco.mj_resetData(self.model, self.data)
        self.data.qpos[:] = (state[0], state[1], state[4])
        self.data.qvel[:] = (state[2], state[3], state[5])
        mujoco.mj_forward(self.model, self.data)

    def state(self) -> np.ndarray:
        """The puck's state (x, y, vx, vy, theta, omega), theta wrapped to [-pi, pi)."""
        q, v = self.data.qpos, self.data.qvel
        return np.array([q[0], q[1], v[0], v[1], wrap_angle(float(q[2])), v[2]])

    def simulate(self, state: np.ndarray, duration: float, hit_at: float | None = None,
                 hit_velocity: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """True states at every MuJoCo step for ``duration`` [s] from ``state``; with ``hit_at`` [s] the
        puck rests until then and its velocity becomes ``hit_velocity`` [m/s] (a human hit). Returns times
        (n,), states (n, 6)."""
        dt = self.model.opt.timestep
        n = int(round(duration / dt)) + 1
        hit_step = 0 if hit_at is None else min(int(round(hit_at / dt)), n)
        states = np.empty((n, 6))
        states[:max(hit_step, 1)] = state  # held by the hand until the hit
        if 0 < hit_step < n:
            states[hit_step - 1, 2:4] = hit_velocity
        start = max(hit_step, 1)
        self.set_state(states[start - 1])
        for i in range(start, n):
            mujoco.mj_step(self.model, self.data)
            states[i] = self.state()
        return np.arange(n) * dt, states


def mujoco_shots(physics: MujocoTable, table: TableGeometry, hit_delay: tuple[float, float],
                 rng: np.random.Generator):
    """Shots on the MuJoCo table (``simulate(state, duration) -> (times, states)`` for
    :func:`~air_hockey_agent.core.estimation.synthetic.synthetic_session`): each a human hit of a resting
    puck (:func:`~air_hockey_agent.core.puck.real_table.held_then_hit`), integrated by MuJoCo."""
    puck = MujocoPuck(table, physics)

    def simulate(state: np.ndarray, duration: float) -> tuple[np.ndarray, np.ndarray]:
        rest, delay, velocity = held_then_hit(state, table, hit_delay, rng)
        return puck.simulate(rest, duration, delay, velocity)
    return simulate

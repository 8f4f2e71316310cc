"""The simulated table (ROS-free): pybullet world with the table, the puck and the iiwa arms.

Frames: the world frame is the table frame (README "Frames and units"); the surface is at z = 0.

* Puck: pybullet handles its contacts with the mallets (restitution and lateral friction from
  ``config/sim.yaml``); its rim impacts are rigid-body impacts computed by
  :mod:`air_hockey_agent.sim.rim_contact` after every step (pybullet's rim contact depends on the step
  phase for a spinning puck; see there). The puck-surface contact is disabled: the air film acts as
  thesis eq. 3.1's surface friction and damping, applied to the puck's velocity after every physics
  step, plus the surface's own push where a table has one (a tilt, an uneven air film, random
  accelerations: :mod:`air_hockey_agent.core.puck.surface_field`; none on the thesis's table), and the puck is held
  on the surface (height, roll and pitch reset every step: a planar body, as on the real table).
  A puck that has fully crossed a goal line stops there (it is in the goal).
* Robots: KUKA iiwa 14 with the striker (``models/iiwa14_striker.urdf``), position/velocity control
  of the seven arm joints following :class:`~air_hockey_agent.core.motion.joint_trajectory.JointTrajectory`;
  the striker's passive universal joint is driven to keep the mallet vertical, like the universal-joint
  plugins of the earlier stacks (REFERENCE_FACTS 3.5). The mallet's height comes from the trajectory.
"""
from __future__ import annotations

import contextlib
import math
import os
import sys
from dataclasses import dataclass, replace
from typing import Any, Mapping, Sequence

import numpy as np
import pybullet
from pybullet_utils.bullet_client import BulletClient

from air_hockey_agent.core.frames import quaternion_from_yaw, yaw_from_quaternion
from air_hockey_agent.core.motion.joint_trajectory import JointTrajectory, TrajectoryError, received_at
from air_hockey_agent.core.puck.surface_field import RandomPush, SurfaceField, slide_from_rest
from air_hockey_agent.core.table import TableGeometry
from air_hockey_agent.paths import model_path
from air_hockey_agent.sim.contacts import ContactLog, MalletContact
from air_hockey_agent.sim.params import ROBOTS
from air_hockey_agent.sim.rim_contact import PuckBody, RimContacts, RimLaw

ARM_JOINTS = tuple(f"iiwa_joint_{i}" for i in range(1, 8))
STRIKER_JOINTS = ("striker_joint_1", "striker_joint_2")
FLANGE_LINK, MALLET_LINK, TIP_LINK = "iiwa_flange", "striker_mallet", "striker_tip"
# URDF loading: inertia as written, cylinders as exact implicit shapes (see TableWorld.__init__)
SHAPE_FLAGS = pybullet.URDF_USE_INERTIA_FROM_FILE | pybullet.URDF_USE_IMPLICIT_CYLINDER
# the random push draws from its own stream of the simulation's seed (the mocap stand-in draws from the seed
# itself, nodes/table_sim.py), so switching it on leaves the mocap's noise as it was
RANDOM_PUSH_STREAM = 1


@dataclass(frozen=True)
class SimSettings:
    """Physical and control settings of the world (``config/sim.yaml``, ``config/table.yaml``)."""

    table: TableGeometry
    puck_height: float
    physics_rate: float
    surface_friction: float
    surface_damping: float
    rim_law: RimLaw              # the rims' restitution (falling with the impact speed or not) and friction
    surface: SurfaceField        # the surface's own push (tilt, air film; zero on the thesis's table)
    mallet_restitution: float
    mallet_friction: float
    contact_erp: float
    striker_control_rate: float  # [Hz]
    robot_bases: dict            # name -> (x, y, z, yaw) in the table frame
    home: tuple                  # home joint positions [rad]
    random_acceleration: float = 0.0       # [m/s^2] std per axis of the surface's random push (0: none)
    random_acceleration_time: float = 0.1  # [s] how long one random push holds
    seed: int = 0                          # the random push's seed (a stream of its own)

    @classmethod
    def from_params(cls, params: Mapping[str, Any]) -> "SimSettings":
        return cls(TableGeometry.from_params(params), params["puck.height"], params["physics_rate"],
                   params["surface_friction"], params["surface_damping"],
                   RimLaw(params["rim_restitution"], params["rim_friction"], params["rim_restitution_slope"],
                          params["rim_restitution_min"], params["rim_restitution_knee"],
                          params["rim_tangential_scale"]),
                   SurfaceField.from_params(params),
                   params["mallet_restitution"], params["mallet_friction"],
                   params["contact_erp"], params["striker_control_rate"],
                   {n: tuple(params[f"robot_base.{n}"]) for n in ROBOTS},
                   tuple(params["home_joint_positions"]),
                   params["random_acceleration"], params["random_acceleration_time"], params["seed"])

    def puck_only(self) -> "SimSettings":
        """The same table without robots (benchmarks, synthetic sessions)."""
        return replace(self, robot_bases={})


@contextlib.contextmanager
def _c_stdout_silenced():
    """Silence what pybullet's C code prints to stdout ("argv[0]=", URDF importer warnings), which
    would otherwise end up in front of a tool's JSON output."""
    sys.stdout.flush()
    saved = os.dup(1)
    try:
        with open(os.devnull, "wb") as null:
            os.dup2(null.fileno(), 1)
            yield
    finally:
        os.dup2(saved, 1)
        os.close(saved)


def arm_joint_order(names: Sequence[str]) -> list[int]:
    """Where each of ``ARM_JOINTS`` is in ``names``; :class:`TrajectoryError` unless they are exactly those 7."""
    names = list(names)
    if sorted(names) != sorted(ARM_JOINTS):
        raise TrajectoryError(f"joint_names must be the 7 arm joints {list(ARM_JOINTS)}, got {names}")
    return [names.index(n) for n in ARM_JOINTS]


class _Robot:
    """Joint bookkeeping of one arm in the pybullet world."""

    def __init__(self, client: BulletClient, body: int, home: Sequence[float]) -> None:
        self.body = body
        index = {client.getJointInfo(body, j)[1].decode(): j for j in range(client.getNumJoints(body))}
        links = {client.getJointInfo(body, j)[12].decode(): j for j in range(client.getNumJoints(body))}
        self.arm = [index[n] for n in ARM_JOINTS]
        self.striker = [index[n] for n in STRIKER_JOINTS]
        self.flange, self.mallet, self.tip = links[FLANGE_LINK], links[MALLET_LINK], links[TIP_LINK]
        self.limits = [client.getJointInfo(body, j)[10] for j in self.arm]  # max effort [N m]
        self.striker_limits = [client.getJointInfo(body, j)[10] for j in self.striker]
        self.home = np.asarray(home, float)
        self.trajectory: JointTrajectory | None = None


class TableWorld:
    """pybullet world of the table, the puck and the robots, stepped at ``physics_rate``."""

    def __init__(self, settings: SimSettings, gui: bool = False) -> None:
        self.settings = settings
        self.dt = 1.0 / settings.physics_rate
        self.time, self._steps = 0.0, 0
        self.contact_log = ContactLog()
        self.contacts: list[MalletContact] = []  # ended contacts not yet taken by the caller
        self._striker_every = max(1, round(settings.physics_rate / settings.striker_control_rate))
        self.random_push = RandomPush(settings.random_acceleration, settings.random_acceleration_time,
                                      np.random.default_rng((settings.seed, RANDOM_PUSH_STREAM)))
        with _c_stdout_silenced():
            self.client = BulletClient(connection_mode=pybullet.GUI if gui else pybullet.DIRECT)
            self._load(gui)

    def _load(self, gui: bool) -> None:
        settings = self.settings
        self.cid = self.client._client  # hot paths call pybullet directly (BulletClient wraps every call)
        c = self.client
        c.setGravity(0.0, 0.0, -9.81)
        c.setTimeStep(self.dt)
        c.setPhysicsEngineParameter(restitutionVelocityThreshold=0.0, erp=settings.contact_erp,
                                    contactERP=settings.contact_erp, frictionERP=settings.contact_erp)
        self.table = c.loadURDF(model_path("air_hockey_table.urdf"), useFixedBase=True)
        # the URDF's inertia (a disc, I = m r^2 / 2): by default pybullet derives it from the collision
        # shape's bounding box (2/3 m r^2 for this cylinder), which gives too little spin at rim impacts
        # and the exact (implicit) cylinder: by default pybullet tessellates a URDF cylinder into a prism,
        # whose faceted side turns a mallet contact's normal by up to a few degrees (bench smash saw the
        # puck leave up to 3.7 deg off the mallet's centre line)
        self.puck = c.loadURDF(model_path("puck.urdf"), [0.0, 0.0, settings.puck_height / 2],
                               flags=SHAPE_FLAGS)
        self.robots = {name: self._load_robot(pose) for name, pose in settings.robot_bases.items()}
        self._configure_contacts()
        if gui:
            c.configureDebugVisualizer(pybullet.COV_ENABLE_GUI, 0)
            c.resetDebugVisualizerCamera(cameraDistance=2.6, cameraYaw=0.0, cameraPitch=-89.9,
                                         cameraTargetPosition=[0.0, 0.0, 0.0])
        self.reset_robots()

    # --- set-up -------------------------------------------------------------------------------
    def _load_robot(self, pose: Sequence[float]) -> _Robot:
        x, y, z, yaw = pose
        body = self.client.loadURDF(model_path("iiwa14_striker.urdf"), [x, y, z],
                                    self.client.getQuaternionFromEuler([0.0, 0.0, yaw]), useFixedBase=True,
                                    flags=SHAPE_FLAGS)
        return _Robot(self.client, body, self.settings.home)

    def _configure_contacts(self) -> None:
        c, s = self.client, self.settings
        no_threshold = dict(contactProcessingThreshold=0.0)  # no speculative contacts: they ignore restitution
        c.changeDynamics(self.puck, -1, restitution=1.0, lateralFriction=1.0, rollingFriction=0.0,
                         spinningFriction=0.0, linearDamping=0.0, angularDamping=0.0, **no_threshold)
        for link in range(-1, c.getNumJoints(self.table)):  # the surface (air cushion) and the rims (RimContacts)
            c.setCollisionFilterPair(self.puck, self.table, -1, link, 0)
        mass, _, inertia = c.getDynamicsInfo(self.puck, -1)[:3]
        self.rims = RimContacts(s.table, PuckBody(s.table.puck_radius, mass, inertia[2]), s.rim_law)
        for robot in self.robots.values():
            c.changeDynamics(robot.body, robot.mallet, restitution=s.mallet_restitution,
                             lateralFriction=s.mallet_friction, **no_threshold)
            c.setCollisionFilterPair(robot.body, self.table, robot.mallet, -1, 0)  # mallet glides on the surface

    # --- puck ---------------------------------------------------------------------------------
    def puck_state(self) -> np.ndarray:
        """True puck state (x, y, vx, vy, theta, omega) in the table frame."""
        return np.array(self._puck_state())

    def _puck_state(self) -> tuple[float, ...]:
        (x, y, _), (qx, qy, qz, qw) = pybullet.getBasePositionAndOrientation(self.puck, physicsClientId=self.cid)
        (vx, vy, _), (_, _, wz) = pybullet.getBaseVelocity(self.puck, physicsClientId=self.cid)
        return x, y, vx, vy, yaw_from_quaternion(qx, qy, qz, qw), wz

    def set_puck_state(self, state: Sequence[float]) -> None:
        x, y, vx, vy, theta, omega = (float(v) for v in state)
        pybullet.resetBasePositionAndOrientation(self.puck, [x, y, self.settings.puck_height / 2],
                                                 quaternion_from_yaw(theta), physicsClientId=self.cid)
        pybullet.resetBaseVelocity(self.puck, [vx, vy, 0.0], [0.0, 0.0, omega], physicsClientId=self.cid)

    def move_puck(self, state: Sequence[float]) -> None:
        """Put the puck at ``state`` by hand: like :meth:`set_puck_state`, and open contacts are forgotten."""
        self.contact_log.reset()
        self.set_puck_state(state)

    def take_contacts(self) -> list[MalletContact]:
        """Mallet-puck contacts that ended since the last call."""
        out, self.contacts = self.contacts, []
        return out

    def in_contact(self) -> tuple[str, ...]:
        """The robots whose mallet is in a contact with the puck now: begun and not yet ended (a contact ends,
        and is reported by :meth:`take_contacts`, once the two have been apart for a few steps)."""
        return self.contact_log.open_robots()

    def _track_contacts(self) -> None:
        touching = {name: bool(pybullet.getContactPoints(self.puck, robot.body, -1, robot.mallet,
                                                         physicsClientId=self.cid))
                    for name, robot in self.robots.items()}
        if touching:
            self.contacts += self.contact_log.step(self.time, touching, self._puck_state())

    def _puck_dynamics(self) -> None:
        """After a physics step: rim impacts, eq. 3.1's friction and damping over the step, the planar
        constraint and goal capture."""
        x, y, vx, vy, theta, omega = self._puck_state()
        x, y, vx, vy, omega = self.rims.resolve(x, y, vx, vy, omega)
        s, dt = self.settings, self.dt
        speed = math.hypot(vx, vy)
        new_speed = max((1.0 - dt * s.surface_damping) * speed - dt * s.surface_friction, 0.0)
        scale = new_speed / speed if speed > 0.0 else 0.0
        vx, vy = vx * scale, vy * scale
        if abs(x) > s.table.length / 2 + s.table.puck_radius:  # fully over a goal line: in the goal
            vx, vy, omega = 0.0, 0.0, 0.0
        elif not s.surface.is_zero or s.random_acceleration > 0.0:
            vx, vy = self._pushed_by_surface(x, y, vx, vy, speed)
        self.set_puck_state((x, y, vx, vy, theta, omega))

    def _pushed_by_surface(self, x: float, y: float, vx: float, vy: float, speed: float) -> tuple[float, float]:
        """Velocity [m/s] after the surface's own acceleration (tilt and air film, ``SimSettings.surface``,
        plus the random push held now) over a step, from the velocity after eq. 3.1's terms; ``speed`` [m/s]
        is the speed before them. A puck at rest stays there unless the push beats the surface friction (a
        constant deceleration that holds it like a static friction), as in the test bed
        (core/puck/real_table.py)."""
        ax, ay = self.settings.surface.at(x, y)
        if self.settings.random_acceleration > 0.0:
            rx, ry = self.random_push.at(self.time)
            ax, ay = ax + rx, ay + ry
        if speed > 0.0:
            return vx + self.dt * ax, vy + self.dt * ay
        return slide_from_rest(ax, ay, self.settings.surface_friction, self.dt)

    # --- robots -------------------------------------------------------------------------------
    def joint_state(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """Arm joint positions [rad] and velocities [rad/s] of robot ``name``."""
        robot = self.robots[name]
        return self._joint_states(robot.body, robot.arm)

    def striker_state(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """Universal-joint positions [rad] and velocities [rad/s] of robot ``name``."""
        robot = self.robots[name]
        return self._joint_states(robot.body, robot.striker)

    def _joint_states(self, body: int, joints: list[int]) -> tuple[np.ndarray, np.ndarray]:
        states = self.client.getJointStates(body, joints)
        return np.array([s[0] for s in states]), np.array([s[1] for s in states])

    def follow(self, name: str, trajectory: JointTrajectory) -> None:
        """Execute ``trajectory`` on robot ``name`` (its joint names must be the arm's seven joints)."""
        order = arm_joint_order(trajectory.joint_names)
        trajectory.positions, trajectory.velocities = trajectory.positions[:, order], trajectory.velocities[:, order]
        trajectory.joint_names = ARM_JOINTS
        self.robots[name].trajectory = trajectory

    def receive(self, name: str, joint_names: Sequence[str], start: float, times: Sequence[float],
                positions: Sequence[Sequence[float]], velocities: Sequence[Sequence[float]] | None) -> None:
        """Execute on robot ``name`` a trajectory (points at ``start + times`` [s], in ``joint_names``
        order) received now, as ros2_control's controller does (:func:`received_at`: from the current
        state to the first point still ahead). Raises :class:`TrajectoryError` for a malformed one."""
        q, dq = np.empty(len(joint_names)), np.empty(len(joint_names))  # current state in the message's order
        order = arm_joint_order(joint_names)
        q[order], dq[order] = self.joint_state(name)
        self.follow(name, received_at(joint_names, start, times, positions, velocities, self.time, q, dq))

    def reset_robots(self) -> None:
        """Put every robot at its home configuration, at rest, holding it."""
        for robot in self.robots.values():
            for j, q in zip(robot.arm, robot.home):
                self.client.resetJointState(robot.body, j, q, 0.0)
            robot.trajectory = None
            self._command(robot, robot.home, np.zeros(len(robot.arm)))
            self._keep_mallet_vertical(robot)

    def set_joint_positions(self, name: str, q: Sequence[float]) -> None:
        """Put robot ``name`` at rest at joint positions ``q`` [rad] (arm joints), holding them."""
        robot = self.robots[name]
        q = np.asarray(q, float)
        for j, value in zip(robot.arm, q):
            self.client.resetJointState(robot.body, j, float(value), 0.0)
        robot.trajectory = None
        self._command(robot, q, np.zeros(len(robot.arm)))
        self._keep_mallet_vertical(robot)

    def _command(self, robot: _Robot, q: np.ndarray, dq: np.ndarray) -> None:
        pybullet.setJointMotorControlArray(robot.body, robot.arm, pybullet.POSITION_CONTROL,
                                           targetPositions=q.tolist(), targetVelocities=dq.tolist(),
                                           forces=robot.limits, physicsClientId=self.cid)

    def _keep_mallet_vertical(self, robot: _Robot) -> None:
        """Universal-joint angles that point the mallet axis straight down (world -z)."""
        _, orn = pybullet.getLinkState(robot.body, robot.flange, physicsClientId=self.cid)[4:6]
        rot = pybullet.getMatrixFromQuaternion(orn)  # row-major; its third row is the world z axis in the flange frame
        down = (-rot[6], -rot[7], -rot[8])  # wanted mallet axis (world -z) in the flange frame
        q1 = math.atan2(down[0], down[2])
        q2 = -math.asin(max(-1.0, min(1.0, down[1])))
        pybullet.setJointMotorControlArray(robot.body, robot.striker, pybullet.POSITION_CONTROL,
                                           targetPositions=[q1, q2], forces=robot.striker_limits,
                                           physicsClientId=self.cid)

    def _control(self) -> None:
        striker_due = self._steps % self._striker_every == 0
        for robot in self.robots.values():
            if robot.trajectory is not None:
                q, dq = robot.trajectory.sample(self.time)
                self._command(robot, q, dq)
                if self.time - robot.trajectory.start > robot.trajectory.duration:
                    robot.trajectory = None  # done: the last command holds the final point
            if striker_due:
                self._keep_mallet_vertical(robot)

    # --- time ---------------------------------------------------------------------------------
    def step(self, steps: int = 1) -> None:
        """Advance the world by ``steps`` physics steps."""
        for _ in range(steps):
            self._control()
            pybullet.stepSimulation(physicsClientId=self.cid)
            self._steps += 1
            self.time = self._steps * self.dt
            self._track_contacts()
            self._puck_dynamics()

    def mallet_position(self, name: str) -> np.ndarray:
        """Centre of the mallet's bottom face (the striker tip) in the table frame [m]."""
        robot = self.robots[name]
        return np.array(self.client.getLinkState(robot.body, robot.tip)[4])

    def close(self) -> None:
        self.client.disconnect()


def simulate_shot(world: TableWorld, state: Sequence[float], duration: float) -> tuple[np.ndarray, np.ndarray]:
    """True puck states at every physics step of ``duration`` [s] from ``state``: times (n,), states (n, 6).

    The signature of :func:`air_hockey_agent.core.estimation.synthetic.simulate_truth` without the model, so the
    table simulation can stand in for the model as the truth of a synthetic session.
    """
    world.set_puck_state(state)
    n = int(round(duration / world.dt)) + 1
    states = np.empty((n, 6))
    states[0] = world.puck_state()
    for i in range(1, n):
        world.step()
        states[i] = world.puck_state()
    return np.arange(n) * world.dt, states

"""Forward kinematics of an iiwa 14 with the striker (``models/iiwa14_striker.urdf``), with pinocchio.

Frames: joint positions in [rad]; the robot base frame is the URDF's root; a base pose
(x, y, z [m], yaw [rad]) places it in the table frame (``robot_base.<robot>`` in ``config/table.yaml``).
The mallet's reference point is the ``striker_tip`` frame: the centre of the mallet's bottom face.
"""
from __future__ import annotations

from typing import Mapping, Sequence

import numpy as np
import pinocchio as pin

from air_hockey_agent.core.frames import table_to_mocap


def in_order(names: Sequence[str], values: Sequence[float], wanted: Sequence[str]) -> np.ndarray | None:
    """``values`` given for ``names`` (e.g. a JointState's), rearranged into the order of ``wanted``;
    None when one of ``wanted`` is missing or has no value."""
    by_name: Mapping[str, float] = dict(zip(names, values))
    try:
        return np.array([by_name[n] for n in wanted], float)
    except KeyError:
        return None


class ArmKinematics:
    """Forward kinematics of one arm model; joints in the model's order (7 arm joints, then the striker's 2)."""

    def __init__(self, urdf_path: str, tip_frame: str = "striker_tip") -> None:
        self.model = pin.buildModelFromUrdf(urdf_path)
        self.data = self.model.createData()
        self.joint_names = tuple(self.model.names[i] for i in range(1, self.model.njoints))
        if not self.model.existFrame(tip_frame):
            raise ValueError(f"{urdf_path}: no frame '{tip_frame}'")
        self.tip = self.model.getFrameId(tip_frame)

    def positions_from_names(self, names: Sequence[str], values: Sequence[float]) -> np.ndarray | None:
        """Joint vector in model order from a (names, positions) pair, e.g. a JointState; None when a
        model joint is missing."""
        return in_order(names, values, self.joint_names)

    def tip_position(self, q: np.ndarray) -> np.ndarray:
        """Mallet tip position in the robot base frame [m]."""
        pin.framesForwardKinematics(self.model, self.data, q)
        return self.data.oMf[self.tip].translation.copy()

    def tip_in_table(self, q: np.ndarray, base_pose: Sequence[float]) -> tuple[float, float]:
        """Mallet tip (x, y) in the table frame [m]; ``base_pose`` as for :func:`base_to_table`."""
        tip = base_to_table(self.tip_position(q), base_pose)
        return float(tip[0]), float(tip[1])


def base_to_table(point: Sequence[float], base_pose: Sequence[float]) -> np.ndarray:
    """A point in a robot base frame -> table frame; ``base_pose`` = (x, y, z, yaw) of the base in the table."""
    # the planar child-to-parent transform of core.frames (written for the table in the mocap frame)
    x, y, _ = table_to_mocap(point[0], point[1], 0.0, base_pose)
    return np.array([x, y, base_pose[2] + point[2]])


class MalletKinematics:
    """The mallet of one arm as the motion layer sees it: 7 arm joints, the striker held vertical.

    The simulation (and the real striker's universal joint) keeps the mallet axis vertical, so the
    mallet's bottom centre is the universal joint's centre less ``tip_length`` straight down. Positions
    and the 3x7 translational Jacobian are in the robot's own table frame (x toward the opponent,
    README "Frames and units"), given the base pose ``base`` = (x, y, z [m], yaw [rad]) in that frame;
    both robots share this code path.
    """

    def __init__(self, urdf_path: str, base: Sequence[float], joint_frame: str = "striker_link_1",
                 tip_frame: str = "striker_tip") -> None:
        full = pin.buildModelFromUrdf(urdf_path)
        striker = [full.getJointId(n) for n in full.names if n.startswith("striker_joint")]
        self.model = pin.buildReducedModel(full, striker, pin.neutral(full))
        self.data = self.model.createData()
        self.frame = self.model.getFrameId(joint_frame)
        self._placements = self.data.oMf  # pinocchio's frame placements in self.data (updated in place)
        full_data = full.createData()
        pin.framesForwardKinematics(full, full_data, pin.neutral(full))
        offset = full_data.oMf[full.getFrameId(tip_frame)].translation - \
            full_data.oMf[full.getFrameId(joint_frame)].translation
        self.tip_length = float(np.linalg.norm(offset))  # [m] universal joint centre -> mallet bottom
        self.q_lower = self.model.lowerPositionLimit.copy()
        self.q_upper = self.model.upperPositionLimit.copy()
        self.joint_names = tuple(self.model.names[i] for i in range(1, self.model.njoints))
        x, y, z, yaw = (float(v) for v in base)
        c, s = np.cos(yaw), np.sin(yaw)
        self._rotation = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        self._turned = not np.array_equal(self._rotation, np.eye(3))  # False: skip the product (hot path)
        self._offset = np.array([x, y, z - self.tip_length])
        self.base_xy = (x, y)

    def position(self, q: np.ndarray) -> np.ndarray:
        """Mallet bottom centre [m] in the robot's own table frame."""
        pin.forwardKinematics(self.model, self.data, q)
        pin.updateFramePlacement(self.model, self.data, self.frame)
        return self._rotation @ self.data.oMf[self.frame].translation + self._offset

    def position_and_jacobian(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Mallet position [m] and its 3x7 Jacobian d(position)/dq [m/rad], both in the own table frame."""
        jac = pin.computeFrameJacobian(self.model, self.data, q, self.frame, pin.LOCAL_WORLD_ALIGNED)[:3]
        if not self._turned:
            return self._placements[self.frame].translation + self._offset, jac
        p = self._rotation @ self._placements[self.frame].translation + self._offset
        return p, self._rotation @ jac

    def planar_motion(self, q: np.ndarray, dq: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Mallet position (x, y) [m] and velocity (vx, vy) [m/s] in the own table frame at joint positions
        ``q`` [rad] and velocities ``dq`` [rad/s]."""
        p, jac = self.position_and_jacobian(q)
        return p[:2].copy(), (jac @ dq)[:2]


class TableMallets:
    """The robots' mallets as the tracker sees them: each one's centre (x, y) [m] and velocity [m/s] in the
    table frame from its joint states (:class:`MalletKinematics` at ``bases``: robot -> base pose x, y, z [m],
    yaw [rad] in the table frame, ``robot_base`` of config/table.yaml)."""

    def __init__(self, urdf_path: str, bases: Mapping[str, Sequence[float]]) -> None:
        self.kinematics = {robot: MalletKinematics(urdf_path, base) for robot, base in bases.items()}

    def motion(self, robot: str, names: Sequence[str], positions: Sequence[float],
               velocities: Sequence[float]) -> tuple[np.ndarray, np.ndarray | None] | None:
        """``robot``'s mallet (position, velocity) from a joint state (names, positions, velocities): the
        velocity None when the state has none for an arm joint; None when it lacks an arm joint's position."""
        kin = self.kinematics[robot]
        q = in_order(names, positions, kin.joint_names)
        if q is None:
            return None
        dq = in_order(names, velocities, kin.joint_names)
        return (kin.position(q)[:2], None) if dq is None else kin.planar_motion(q, dq)

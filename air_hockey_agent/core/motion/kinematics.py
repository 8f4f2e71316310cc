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
        by_name: Mapping[str, float] = dict(zip(names, values))
        try:
            return np.array([by_name[n] for n in self.joint_names], float)
        except KeyError:
            return None

    def tip_position(self, q: np.ndarray) -> np.ndarray:
        """Mallet tip position in the robot base frame [m]."""
        pin.framesForwardKinematics(self.model, self.data, q)
        return self.data.oMf[self.tip].translation.copy()


def base_to_table(point: Sequence[float], base_pose: Sequence[float]) -> np.ndarray:
    """A point in a robot base frame -> table frame; ``base_pose`` = (x, y, z, yaw) of the base in the table."""
    # the planar child-to-parent transform of core.frames (written for the table in the mocap frame)
    x, y, _ = table_to_mocap(point[0], point[1], 0.0, base_pose)
    return np.array([x, y, base_pose[2] + point[2]])

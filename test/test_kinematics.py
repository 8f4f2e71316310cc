"""core.motion.kinematics (pinocchio) against the pybullet world: mallet tips of both robots in the table frame."""
import numpy as np

from air_hockey_agent.core.motion.kinematics import ArmKinematics, base_to_table
from air_hockey_agent.paths import model_path
from air_hockey_agent.sim.params import ROBOTS, load_sim_params
from air_hockey_agent.sim.world import SimSettings, TableWorld


def test_tip_in_the_table_frame_matches_the_simulated_mallet_for_both_robots():
    params = load_sim_params()
    world = TableWorld(SimSettings.from_params(params))
    kin = ArmKinematics(model_path("iiwa14_striker.urdf"))
    rng = np.random.default_rng(0)
    try:
        for _ in range(5):
            for robot in ROBOTS:
                body = world.robots[robot].body
                joints = {world.client.getJointInfo(body, j)[1].decode(): j
                          for j in range(world.client.getNumJoints(body))}
                q = rng.uniform(kin.model.lowerPositionLimit, kin.model.upperPositionLimit) * 0.5
                for name, value in zip(kin.joint_names, q):
                    world.client.resetJointState(body, joints[name], value)
                tip = base_to_table(kin.tip_position(q), params[f"robot_base.{robot}"])
                np.testing.assert_allclose(tip, world.mallet_position(robot), atol=1e-6)
                # the referee's and the visualizer's planar mallet position
                np.testing.assert_allclose(kin.tip_in_table(q, params[f"robot_base.{robot}"]),
                                           world.mallet_position(robot)[:2], atol=1e-6)
    finally:
        world.close()


def test_joint_vector_from_names_is_in_model_order_and_none_when_a_joint_is_missing():
    kin = ArmKinematics(model_path("iiwa14_striker.urdf"))
    names = list(reversed(kin.joint_names))
    q = kin.positions_from_names(names, list(range(len(names))))
    assert list(q) == list(reversed(range(len(names))))
    assert kin.positions_from_names(names[:-1], list(range(8))) is None

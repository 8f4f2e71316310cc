"""URDF models: pybullet and pinocchio agree on the iiwa's kinematics; the table matches config/table.yaml."""
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from air_hockey_agent.paths import model_path
from air_hockey_agent.tracker_params import load_tracker_params


@pytest.fixture(scope="module")
def bullet():
    import pybullet
    from pybullet_utils.bullet_client import BulletClient
    client = BulletClient(connection_mode=pybullet.DIRECT)
    yield client
    client.disconnect()


def test_iiwa_forward_kinematics_agree_between_pybullet_and_pinocchio(bullet):
    import pinocchio as pin
    model = pin.buildModelFromUrdf(model_path("iiwa14_striker.urdf"))
    data = model.createData()
    body = bullet.loadURDF(model_path("iiwa14_striker.urdf"), useFixedBase=True)
    joints = {bullet.getJointInfo(body, j)[1].decode(): j for j in range(bullet.getNumJoints(body))}
    links = {bullet.getJointInfo(body, j)[12].decode(): j for j in range(bullet.getNumJoints(body))}
    movable = [model.names[i] for i in range(1, model.njoints)]
    assert movable[:7] == [f"iiwa_joint_{i}" for i in range(1, 8)] and len(movable) == 9
    rng = np.random.default_rng(0)
    lower, upper = model.lowerPositionLimit, model.upperPositionLimit
    for _ in range(20):
        q = rng.uniform(lower, upper)
        for name, value in zip(movable, q):
            bullet.resetJointState(body, joints[name], value)
        pin.framesForwardKinematics(model, data, q)
        for frame in ("iiwa_link_4", "iiwa_flange", "striker_link_1", "striker_tip"):
            expected = data.oMf[model.getFrameId(frame)].translation
            actual = np.array(bullet.getLinkState(body, links[frame], computeForwardKinematics=True)[4])
            assert np.allclose(actual, expected, atol=1e-6), frame


def test_iiwa_limits_are_those_of_the_iiwa_14():
    import pinocchio as pin
    model = pin.buildModelFromUrdf(model_path("iiwa14_striker.urdf"))
    np.testing.assert_allclose(model.upperPositionLimit[:7], [2.9671, 2.0944, 2.9671, 2.0944, 2.9671, 2.0944, 3.0543])
    np.testing.assert_allclose(model.velocityLimit[:7], [1.4835, 1.4835, 1.7453, 1.3090, 2.2689, 2.3562, 2.3562])


def test_table_rims_bound_the_configured_playing_surface():
    params = load_tracker_params()
    length, width, goal = params["table.length"], params["table.width"], params["table.goal_width"]
    root = ET.parse(model_path("air_hockey_table.urdf")).getroot()
    inner = {"x": [], "y_goal_edges": [], "y": []}
    for link in root.iter("link"):
        name = link.get("name")
        if not name.startswith("rim_"):
            continue
        box = link.find("collision")
        cx, cy, _ = map(float, box.find("origin").get("xyz").split())
        sx, sy, _ = map(float, box.find("geometry/box").get("size").split())
        if name in ("rim_left", "rim_right"):
            inner["y"].append(abs(cy) - sy / 2)
        else:
            inner["x"].append(abs(cx) - sx / 2)
            inner["y_goal_edges"].append(abs(cy) - sy / 2)
    assert np.allclose(inner["y"], width / 2) and len(inner["y"]) == 2
    assert np.allclose(inner["x"], length / 2) and len(inner["x"]) == 4
    assert np.allclose(inner["y_goal_edges"], goal / 2)

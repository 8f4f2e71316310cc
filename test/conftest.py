"""Shared fixtures: private ROS domain and ROS_HOME for every test run, rclpy contexts, launchers."""
from __future__ import annotations

import atexit
import os
import shutil
import sys
import tempfile
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
HELPERS = Path(__file__).resolve().parent / "helpers"

# One private domain per test session (1..101 only; 0 is everyone's default). Set before rclpy loads.
# Under pytest-xdist the workers inherit the controller's choice and each takes its own next to it.
_SESSION_TMP = Path(tempfile.mkdtemp(prefix="air_hockey_tests_"))
atexit.register(shutil.rmtree, _SESSION_TMP, ignore_errors=True)
os.environ.setdefault("AIR_HOCKEY_TEST_DOMAIN", str(10 + os.getpid() % 90))
_WORKER = os.environ.get("PYTEST_XDIST_WORKER", "")  # "gw0", "gw1", ... or "" without xdist
_OFFSET = int(_WORKER[2:]) + 1 if _WORKER.startswith("gw") and _WORKER[2:].isdigit() else 0
os.environ["ROS_DOMAIN_ID"] = str(10 + (int(os.environ["AIR_HOCKEY_TEST_DOMAIN"]) - 10 + _OFFSET) % 90)
os.environ["ROS_HOME"] = str(_SESSION_TMP / "ros_home")
os.environ["ROS_LOG_DIR"] = str(_SESSION_TMP / "ros_home" / "log")


# Tests that start ROS nodes (or join a ROS graph) are marked ``ros``: `make test` runs the others on two
# processes first, then these alone, one after another (README "Tests"): some check that no node process
# of theirs is left running (pgrep), which another test's node would fail, and node graphs under a
# second process's load missed their timings (a simulated shot, a message count).
ROS_FIXTURES = {"ros_env", "rclpy_node", "launcher", "domain_id"}


@pytest.hookimpl(tryfirst=True)  # before -m selects by marks
def pytest_collection_modifyitems(config, items):
    for item in items:
        if item.get_closest_marker("integration") or ROS_FIXTURES & set(getattr(item, "fixturenames", ())):
            item.add_marker(pytest.mark.ros)


@pytest.fixture(scope="session")
def domain_id() -> int:
    return int(os.environ["ROS_DOMAIN_ID"])


@pytest.fixture
def ros_env(domain_id, tmp_path):
    """Environment for node subprocesses: our Fast DDS profile, the private domain, a temp ROS_HOME."""
    from air_hockey_agent.tools.ros_env import ros_environment
    return ros_environment(domain_id=domain_id, ros_home=tmp_path / "ros_home")


@pytest.fixture
def rclpy_node(ros_env):
    """An rclpy node in this test process (own context), destroyed afterwards."""
    import rclpy
    os.environ["FASTRTPS_DEFAULT_PROFILES_FILE"] = ros_env["FASTRTPS_DEFAULT_PROFILES_FILE"]
    context = rclpy.Context()
    rclpy.init(context=context, domain_id=int(ros_env["ROS_DOMAIN_ID"]))
    node = rclpy.create_node("pytest_probe", context=context)
    try:
        yield node
    finally:
        node.destroy_node()
        rclpy.try_shutdown(context=context)


@pytest.fixture
def launcher(ros_env):
    """A process launcher whose processes are always stopped at the end of the test."""
    from air_hockey_agent.tools.launch import Launcher
    with Launcher(ros_env, echo=sys.stderr) as launch:
        yield launch

"""ament_python package air_hockey_agent (colcon build, or pip install in the project venv)."""
from glob import glob

from setuptools import find_packages, setup

PACKAGE = "air_hockey_agent"

# One console script per node, named as the node (`ros2 run air_hockey_agent <node>`).
NODES = {
    "puck_tracker": "air_hockey_agent.nodes.puck_tracker:main",
    "tactics": "air_hockey_agent.nodes.tactics:main",
    "trajectory_generator": "air_hockey_agent.nodes.trajectory_generator:main",
    "referee": "air_hockey_agent.nodes.referee:main",
    "table_sim": "air_hockey_agent.nodes.table_sim:main",
    "bag_player": "air_hockey_agent.nodes.bag_player:main",
    "strategy_test": "air_hockey_agent.nodes.strategy_test:main",
    "prediction_optimizer": "air_hockey_agent.nodes.prediction_optimizer:main",
    "visualizer": "air_hockey_agent.nodes.visualizer:main",
}

setup(
    name=PACKAGE,
    version="0.1.0",
    packages=find_packages(exclude=["test", "test.*"]),
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{PACKAGE}"]),
        (f"share/{PACKAGE}", ["package.xml"]),
        (f"share/{PACKAGE}/config", glob("config/*.yaml") + glob("config/*.xml")),
        (f"share/{PACKAGE}/models", glob("models/*.urdf")),
        (f"share/{PACKAGE}/launch", glob("launch/*.launch.py")),
    ],
    install_requires=["setuptools"],
    extras_require={"test": ["pytest"]},
    zip_safe=True,
    maintainer="air_hockey_agent maintainers",
    maintainer_email="maintainers@air-hockey-agent.org",
    description="Robot air hockey baseline agent (ROS 2 Jazzy, Python).",
    license="MIT",
    entry_points={
        "console_scripts": [f"{name}={target}" for name, target in NODES.items()]
        + ["air-hockey=air_hockey_agent.tools.cli:main"],
    },
)

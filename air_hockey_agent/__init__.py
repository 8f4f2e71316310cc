"""air_hockey_agent: a ROS 2 (Python) baseline agent for robot air hockey.

ROS-free code lives in :mod:`air_hockey_agent.core` (math, models, filters, decisions) and
:mod:`air_hockey_agent.sim`; :mod:`air_hockey_agent.nodes` holds thin rclpy nodes and
:mod:`air_hockey_agent.tools` the ``air-hockey`` command line.
"""

__version__ = "0.1.0"

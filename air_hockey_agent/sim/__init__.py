"""pybullet table simulation (ROS-free)."""

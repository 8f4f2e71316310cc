"""The strategy test (thesis sec. 4.6, 5.4): trial initial states and the success criteria (ROS-free)."""

"""ROS-free core: table geometry, puck model, EKF, prediction, preprocessing, sysid, tactics, referee rules."""

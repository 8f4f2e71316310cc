"""Thin rclpy nodes: translate messages and parameters to core calls, one module per node."""

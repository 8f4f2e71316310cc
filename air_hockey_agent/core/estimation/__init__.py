"""Puck state estimation: the EKF, its evaluation on recordings, synthetic lab-like sessions."""

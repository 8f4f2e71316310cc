"""Joint trajectories as the simulated controller executes them (core/motion/joint_trajectory)."""
import numpy as np
import pytest

from air_hockey_agent.core.motion.joint_trajectory import JointTrajectory, TrajectoryError, received_at

NAMES = ("a", "b")
TIMES = [0.03, 0.05, 0.07]
Q = [[0.10, 0.0], [0.20, 0.1], [0.30, 0.2]]
DQ = [[5.0, 5.0], [5.0, 5.0], [0.0, 0.0]]
CURRENT_Q, CURRENT_DQ = [0.0, -0.1], [4.0, 4.0]


def _message_segment(t):
    """Cubic Hermite between the message's own points at absolute time t (message stamped at 1.0 s)."""
    full = JointTrajectory.from_points(NAMES, 1.0, TIMES, Q, DQ, CURRENT_Q, CURRENT_DQ)
    return full.sample(t)


@pytest.mark.parametrize("now", [0.99, 1.0, 1.012, 1.029])
def test_execution_starts_from_the_current_state_when_received(now):
    """ros2_control's rule: the current state at the moment of receipt (stamped earlier or later) is the
    implicit first point; the message's points keep their absolute times."""
    traj = received_at(NAMES, 1.0, TIMES, Q, DQ, now, CURRENT_Q, CURRENT_DQ)
    q, dq = traj.sample(now + 1e-9)
    assert np.allclose(q, CURRENT_Q, atol=1e-6) and np.allclose(dq, CURRENT_DQ, atol=1e-2)
    for t, q_point in zip(TIMES, Q):
        assert np.allclose(traj.sample(1.0 + t)[0], q_point)
    if now > 1.0:  # the former rule put the current state at the stamp instead
        old = JointTrajectory.from_points(NAMES, 1.0, TIMES, Q, DQ, CURRENT_Q, CURRENT_DQ)
        assert not np.allclose(old.sample(now)[0], CURRENT_Q, atol=1e-6)


def test_a_stamp_in_the_future_moves_on_at_once_instead_of_holding():
    traj = received_at(NAMES, 1.0, TIMES, Q, DQ, 0.95, CURRENT_Q, CURRENT_DQ)
    q, dq = traj.sample(0.96)
    assert np.all(np.abs(dq) > 1.0) and not np.allclose(q, CURRENT_Q)


def test_passed_points_are_skipped_onto_the_segment_in_progress():
    for now in (1.04, 1.06):
        traj = received_at(NAMES, 1.0, TIMES, Q, DQ, now, CURRENT_Q, CURRENT_DQ)
        for t in (now, now + 0.005, 1.07):
            assert np.allclose(traj.sample(t)[0], _message_segment(t)[0])


def test_a_trajectory_entirely_in_the_past_holds_its_last_point():
    traj = received_at(NAMES, 1.0, TIMES, Q, DQ, 1.2, CURRENT_Q, CURRENT_DQ)
    for t in (1.2, 1.3):
        q, dq = traj.sample(t)
        assert np.allclose(q, Q[-1]) and np.allclose(dq, 0.0)


def test_a_malformed_message_is_refused():
    with pytest.raises(TrajectoryError):
        received_at(NAMES, 1.0, [0.03, 0.02], [[0, 0], [1, 1]], None, 1.0, CURRENT_Q, CURRENT_DQ)

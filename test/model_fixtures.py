"""Shared model objects for the core tests (values of config/table.yaml and thesis table 5.3)."""
import numpy as np

from air_hockey_agent.core.puck.model import PuckModel, PuckParams
from air_hockey_agent.core.table import TableGeometry

TABLE = TableGeometry(length=1.956, width=1.042, goal_width=0.25, puck_radius=0.03165)
PARAMS = PuckParams(friction_surface=0.05, damping=0.5, restitution=0.9, friction_rim=0.1)
DT = 1.0 / 120.0
Q = np.diag([1e-10, 1e-10, 2e-7, 2e-7, 1e-6, 1e-6])


def model(**overrides) -> PuckModel:
    return PuckModel(TABLE, PARAMS.with_values(**overrides))


def finite_difference_jacobian(m: PuckModel, state: np.ndarray, dt: float, h: float = 1e-7) -> np.ndarray:
    """Central differences of one model step (angle differences wrapped)."""
    jac = np.zeros((6, 6))
    for i in range(6):
        d = np.zeros(6)
        d[i] = h
        diff = m.step(state + d, dt, False).state - m.step(state - d, dt, False).state
        diff[4] = (diff[4] + np.pi) % (2 * np.pi) - np.pi
        jac[:, i] = diff / (2 * h)
    return jac

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


def session_on_testbed(ekf, shots: int, seed: int, testbed: dict | None = None, **mocap):
    """A session on the test bed with config/synthetic.yaml's shots, effects and mocap (``testbed``: its
    ``testbed.*`` effects, ``mocap``: fields of MocapImperfections, set otherwise), as synth-bag --source
    testbed writes it."""
    from air_hockey_agent.core.puck.real_table import HandCarry, TableEffects, testbed_shots

    def shots_of(cfg, rng):
        cfg = {**cfg, **{f"testbed.{name}": value for name, value in (testbed or {}).items()}}
        return testbed_shots(TableEffects.from_params(cfg), ekf.model.table, cfg["testbed.hit_delay"], cfg["fine_dt"],
                             rng, HandCarry.from_params(cfg), np.random.default_rng([seed, 2]))
    return _session(ekf, shots, seed, shots_of, mocap)


def session_on_mujoco(ekf, shots: int, seed: int):
    """A session on the MuJoCo table with config/synthetic.yaml's shots, physics and mocap, as synth-bag
    --source mujoco writes it."""
    from air_hockey_agent.sim.mujoco_table import MujocoTable, mujoco_shots
    return _session(ekf, shots, seed, lambda cfg, rng: mujoco_shots(
        MujocoTable.from_params(cfg), ekf.model.table, cfg["testbed.hit_delay"], rng))


def synthetic_config() -> dict:
    """config/synthetic.yaml's session parameters, as synth-bag reads them."""
    from air_hockey_agent.params import load_node_params
    from air_hockey_agent.tools.synth_bag import SESSION_PARAMS
    return load_node_params(["synthetic.yaml"], "/synth_bag", SESSION_PARAMS, [])


def _session(ekf, shots: int, seed: int, source, mocap: dict | None = None):
    from air_hockey_agent.core.estimation.synthetic import MocapImperfections, ShotRanges, synthetic_session
    cfg = {**synthetic_config(), **{f"mocap.{name}": value for name, value in (mocap or {}).items()}}
    ranges = ShotRanges(tuple(cfg["speed"]), tuple(cfg["spin"]), cfg["shot_duration"], cfg["pause"])
    simulate = source(cfg, np.random.default_rng([seed, 1]))
    return synthetic_session(ekf.model, ranges, shots, cfg["rate"], MocapImperfections.from_params(cfg),
                             np.random.default_rng(seed), cfg["fine_dt"], simulate)

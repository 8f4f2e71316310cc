"""HEBO (installed --no-deps, see README) runs in the same venv as pin/numpy 2 and the ROS wheels."""
import numpy as np
import pytest


@pytest.mark.slow
def test_hebo_minimises_a_quadratic_on_numpy2_with_pinocchio_loaded():
    import pinocchio  # noqa: F401  (must coexist with HEBO in one process)
    import rclpy  # noqa: F401
    from hebo.design_space.design_space import DesignSpace
    from hebo.optimizers.hebo import HEBO

    import torch

    assert int(np.__version__.split(".")[0]) >= 2
    np.random.seed(0)  # HEBO draws from numpy's and torch's global generators; its GP fit is still
    torch.manual_seed(0)  # not bit-reproducible (seen after 20 samples: 1e-5 to 5e-3, once 0.021 in CI)
    space = DesignSpace().parse([{"name": "a", "type": "num", "lb": -1.0, "ub": 1.0},
                                 {"name": "b", "type": "num", "lb": -1.0, "ub": 1.0}])
    opt = HEBO(space, rand_sample=4, scramble_seed=0)
    for _ in range(15):
        suggestion = opt.suggest(n_suggestions=2)
        values = ((suggestion["a"] - 0.3) ** 2 + (suggestion["b"] + 0.2) ** 2).to_numpy().reshape(-1, 1)
        opt.observe(suggestion, values)
    # after 30 samples HEBO reached 4e-8 to 1.5e-4 over seeds 0-9 (measured 2026-11-23, this loop per seed);
    # 30 uniform random samples get below 0.005 with probability ~11 %
    assert opt.best_y < 0.005

"""System identification: losses, HEBO + polish on a small synthetic problem, the CLI end to end."""
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from air_hockey_agent.core.estimation.ekf import PuckEKF
from air_hockey_agent.core.estimation.evaluation import EvaluationTotals, evaluate_stream
from air_hockey_agent.core.identification.preprocess import to_model_grid
from air_hockey_agent.core.estimation.synthetic import MocapImperfections, ShotRanges, synthetic_session
from air_hockey_agent.core.identification.sysid import identify, loss_report
from air_hockey_agent.tracker_params import load_tracker_params, trajectory_loss_params, without_learning

TRUE = {"friction_surface": 0.1, "damping": 0.35, "restitution": 0.85, "friction_rim": 0.15}
EXE = Path(sys.executable).parent / "air-hockey"


@pytest.fixture(scope="module")
def tracker():
    return trajectory_loss_params(load_tracker_params())  # as sysid runs its objective: the law itself is identified


@pytest.fixture(scope="module")
def trajectories(tracker):
    model = PuckEKF.from_params({**tracker, **TRUE}).model
    shots = ShotRanges(speed=(2.0, 4.0), spin=(-10.0, 10.0), duration=3.0, pause=3.0)
    frames = synthetic_session(model, shots, 4, 120.0, MocapImperfections(), np.random.default_rng(1), 0.002)
    out, start = [], 0
    for i in range(1, len(frames) + 1):  # one grid trajectory per shot (pauses of 3 s separate them)
        if i == len(frames) or frames[i].stamp - frames[i - 1].stamp > 1.0:
            chunk = frames[start:i]
            out.append(to_model_grid([f.stamp for f in chunk], [f.measurement for f in chunk], 1 / 120))
            start = i
    return out


def test_the_trajectory_losses_run_without_the_hand_regime(trajectories):
    """Preprocessing ends a trajectory where a hand took the puck, so a hand regime there could only answer
    the model's misfit: on these shots (damping 0.35, restitution 0.85) the configured physics misfits, and
    a filter with the regime starts it and hides part of the misfit (a lower loss for the wrong
    parameters). The loss sysid minimises (and eval-prediction's thesis-style columns and plot's curves
    report) runs without it: wrong parameters pay their whole misfit, the true ones lose nothing."""
    configured = load_tracker_params()
    with_hand, losses = without_learning(configured), trajectory_loss_params(configured)

    def regimes(params):
        ekf = PuckEKF.from_params(params)
        for traj in trajectories:
            evaluate_stream(ekf, traj.frames(), EvaluationTotals((1.0,)))
        return ekf.stats.hand_regimes
    assert regimes(with_hand) >= 2 and regimes(losses) == 0
    assert loss_report(losses, trajectories, 1.0).loss > loss_report(with_hand, trajectories, 1.0).loss
    right = [loss_report({**params, **TRUE}, trajectories, 1.0).loss for params in (losses, with_hand)]
    assert right[0] == right[1]


def test_true_parameters_have_the_lowest_loss(tracker, trajectories):
    true = loss_report({**tracker, **TRUE}, trajectories, 1.0)
    default = loss_report(tracker, trajectories, 1.0)
    off = loss_report({**tracker, **TRUE, "restitution": 0.8}, trajectories, 1.0)
    assert true.loss < 0.2 * default.loss and true.loss < off.loss
    assert true.min <= true.median <= max(true.loss * 3, true.median)
    ll_true = loss_report({**tracker, **TRUE}, trajectories, 1.0, loss="loglik")
    ll_off = loss_report({**tracker, **TRUE, "restitution": 0.8}, trajectories, 1.0, loss="loglik")
    assert ll_true.objective < ll_off.objective


def test_identify_moves_toward_the_true_parameters(tracker, trajectories):
    bounds = {"friction_surface": (0.0, 0.5), "damping": (0.2, 0.8), "restitution": (0.5, 1.0),
              "friction_rim": (0.0, 0.6)}

    def objective(batch):
        return [loss_report({**tracker, **c}, trajectories, 1.0, stride=3).objective for c in batch]

    seen = []
    # HEBO's GP fit is not bit-reproducible: over 4 runs this budget ended at 0.07-0.25 of the start
    # (4 x 3 + 30 ended at 0.19-0.44, too close to the bound below)
    result = identify(objective, bounds, {k: tracker[k] for k in bounds}, iterations=6, batch=3, seed=0,
                      random_samples=3, polish_evaluations=40, progress=lambda d, t, b: seen.append(d))
    assert result.evaluations == len(result.history) > 1 + 6 * 3  # start, HEBO batches, polish
    assert seen[-1] == len(result.history) - 1
    assert result.best_objective < 0.5 * result.initial_objective
    assert all(bounds[k][0] <= v <= bounds[k][1] for k, v in result.best.items())


@pytest.mark.slow
def test_cli_writes_params_that_eval_prediction_accepts(tmp_path):
    true_file = tmp_path / "true.yaml"
    true_file.write_text("/**/puck_tracker:\n  ros__parameters:\n"
                         + "".join(f"    {k}: {v}\n" for k, v in TRUE.items()))
    bags = tmp_path / "bags"
    bags.mkdir()
    made = subprocess.run([str(EXE), "synth-bag", str(bags / "a"), "--shots", "4", "--params-file", str(true_file)],
                          capture_output=True, text=True, timeout=120)
    assert made.returncode == 0, made.stderr
    (bags / "junk").mkdir()
    (bags / "junk" / "metadata.yaml").write_text("not: a bag\n")
    out = tmp_path / "identified.yaml"
    run = subprocess.run([str(EXE), "sysid", str(bags), "--method", "hebo", "--iterations", "3", "--batch", "2", "--out", str(out),
                          "--json"], capture_output=True, text=True, timeout=600)
    assert run.returncode == 2  # the junk bag is reported ...
    assert "junk: cannot read" in run.stderr
    assert run.stdout, run.stderr[-3000:]
    report = json.loads(run.stdout)  # ... and the good one still used
    assert report["after"]["train"]["loss_m"] < report["before"]["train"]["loss_m"]
    objective = report["objective"]  # what was minimised, reported as such (issue #13)
    assert objective["set"] == "train" and objective["stride"] >= 1
    assert objective["identified"] <= objective["initial"] and isinstance(report["on_bounds"], list)
    assert report["bags"] == 1 and report["bad_bags"] == 1
    assert "ros__parameters" in out.read_text()
    check = subprocess.run([str(EXE), "eval-prediction", str(bags / "a"), "--params-file", str(out), "--json"],
                           capture_output=True, text=True, timeout=120)
    assert check.returncode == 0, check.stderr


def cli(*args, timeout=300):
    return subprocess.run([str(EXE), *map(str, args)], capture_output=True, text=True, timeout=timeout)


def test_noise_estimate_cli(tmp_path):
    bag = tmp_path / "a"
    assert cli("synth-bag", bag, "--shots", 3).returncode == 0
    out = tmp_path / "noise.yaml"
    run = cli("noise-estimate", tmp_path, "--iterations", 2, "--fix", "Q", "--out", out, "--json")
    assert run.returncode == 0, run.stderr
    report = json.loads(run.stdout)
    assert len(report["history"]) == 2 and report["fixed"] == ["Q"]
    assert set(report["prediction_error"]) == {"horizon", "current", "estimated_R", "estimated_Q", "estimated_both"}
    assert all(v > 0 for v in report["measurement_noise"])
    check = cli("eval-prediction", bag, "--params-file", out, "--json")
    assert check.returncode == 0, check.stderr
    by_speed = cli("noise-estimate", tmp_path, "--iterations", 1, "--fix", "Q", "--by-speed", "--out", out, "--json")
    assert by_speed.returncode == 0, by_speed.stderr
    assert json.loads(by_speed.stdout)["measurement_noise_per_speed"] >= 0.0
    assert "measurement_noise_per_speed:" in out.read_text()
    assert cli("eval-prediction", bag, "--params-file", out).returncode == 0
    both = cli("noise-estimate", tmp_path, "--fix", "R", "--by-speed")
    assert both.returncode == 2 and "--by-speed estimates R" in both.stderr and not both.stdout


def test_plot_cli_writes_three_pngs(tmp_path):
    bag = tmp_path / "a"
    assert cli("synth-bag", bag, "--shots", 2).returncode == 0
    run = cli("plot", bag, "--out", tmp_path / "plots", "--horizon", 0.5)
    assert run.returncode == 0, run.stderr
    for name in ("velocity.png", "prediction.png", "error_vs_horizon.png"):
        data = (tmp_path / "plots" / name).read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 10_000
    assert not [p for p in (tmp_path / "plots").iterdir() if p.name.startswith(".")]


def test_errors_through_steps_match_the_offline_loss(tracker, trajectories):
    """The service path of prediction_optimizer (a step function) gives the offline loss exactly."""
    from air_hockey_agent.core.estimation.evaluation import valid_poses
    from air_hockey_agent.core.identification.sysid import errors_through_steps
    ekf = PuckEKF.from_params(tracker)

    def step(t, z, h):
        flags = ekf.process(t, z)
        return flags, tuple(ekf.predict(h).state[:2]) if ekf.initialised else (0.0, 0.0)

    errors = []
    for traj in trajectories:
        ekf.reset()
        errors.extend(errors_through_steps(traj, 1.0, step, valid_poses(list(traj.frames()), ekf)))
    offline = loss_report(tracker, trajectories, 1.0)
    assert len(errors) == offline.comparisons and np.mean(errors) == pytest.approx(offline.loss, rel=1e-9)


def test_messy_bag_is_repaired_with_a_warning_and_used(tmp_path):
    """Out-of-order and repeated stamps and NaN poses: one warning line naming the bag, bag still used."""
    from air_hockey_agent.bags.reader import read_poses
    from air_hockey_agent.bags.trajectories import load_trajectories
    from air_hockey_agent.bags.types import typestore
    from air_hockey_agent.bags.writer import write_bag
    from air_hockey_agent.sysid_params import load_sysid_params
    from air_hockey_agent.tracker_params import load_tracker_params

    clean = tmp_path / "clean"
    assert cli("synth-bag", clean, "--shots", 2).returncode == 0
    records = read_poses(clean, "/optitrack/puck")
    types = typestore().types
    msgs = []
    for k, r in enumerate(records):
        stamp_ns = int(round(r.stamp * 1e9)) if k != 50 else int(round(records[40].stamp * 1e9))  # back in time
        x = float("nan") if k in (70, 71) else r.position[0]
        msg = types["geometry_msgs/msg/PoseStamped"](
            header=types["std_msgs/msg/Header"](stamp=types["builtin_interfaces/msg/Time"](
                sec=stamp_ns // 10**9, nanosec=stamp_ns % 10**9), frame_id="optitrack"),
            pose=types["geometry_msgs/msg/Pose"](
                position=types["geometry_msgs/msg/Point"](x=x, y=r.position[1], z=r.position[2]),
                orientation=types["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=r.orientation[2],
                                                                  w=r.orientation[3])))
        msgs.append(("/optitrack/puck", k, msg))
    write_bag(tmp_path / "messy", {"/optitrack/puck": "geometry_msgs/msg/PoseStamped"}, msgs)
    loaded = load_trajectories([tmp_path / "messy"], "/optitrack/puck", load_tracker_params(), load_sysid_params())
    assert loaded.bags == 1 and loaded.trajectories and not loaded.errors
    assert len(loaded.warnings) == 1 and str(tmp_path / "messy") in loaded.warnings[0]
    assert "1 stamps out of order" in loaded.warnings[0] and "2 poses with NaN" in loaded.warnings[0]


def test_cross_validation_table(tmp_path):
    assert cli("synth-bag", tmp_path / "a", "--shots", 4).returncode == 0
    fast = tmp_path / "fast.yaml"
    fast.write_text("/**:\n  ros__parameters:\n    polish_evaluations: 0\n    random_samples: 1\n")
    run = cli("sysid", tmp_path / "a", "--method", "hebo", "--iterations", 1, "--batch", 1, "--cross-validate", "--params-file", fast,
              "--json", timeout=600)
    assert run.returncode == 0, run.stderr
    report = json.loads(run.stdout)
    assert set(report["learned"]) == {"0.5", "1.0", "1.5"}
    assert set(report["cross_validation"]) == {"0.5", "1.0", "1.5"}
    assert all(set(row) == {"0.5", "1.0", "1.5"} for row in report["cross_validation"].values())


def test_results_on_a_search_bound_are_named():
    from air_hockey_agent.core.identification.sysid import on_bounds
    box = {"damping": (0.2, 0.8), "restitution": (0.5, 1.0), "friction_rim": (0.0, 0.6)}
    values = {"damping": 0.2055, "restitution": 0.9999, "friction_rim": 0.3}
    assert on_bounds(values, box, 0.01) == ["damping 0.2055 at its lower bound 0.2",
                                            "restitution 0.9999 at its upper bound 1"]
    assert on_bounds(values, box, 0.0) == []


def test_loglik_warns_unless_the_filter_is_calibrated(tracker, trajectories):
    from air_hockey_agent.core.identification.sysid import nis_median
    from air_hockey_agent.tools.sysid import _calibration_warning
    nis = nis_median(tracker, trajectories)
    assert nis is not None and nis > 0.0
    assert _calibration_warning("position", tracker, {"calibrated_nis": [nis + 1, nis + 2]}, trajectories) == ""
    assert _calibration_warning("loglik", tracker, {"calibrated_nis": [nis - 0.1, nis + 0.1]}, trajectories) == ""
    warning = _calibration_warning("loglik", tracker, {"calibrated_nis": [nis + 1, nis + 2]}, trajectories)
    assert f"median NIS on the training set is {nis:.2f}" in warning


@pytest.mark.slow
def test_identify_chooses_the_parameters_and_the_yaml_holds_only_those(tmp_path):
    """`sysid --identify` on a test-bed bag (rims that lose more at speed): only the named parameters are
    searched, reported and written; an unknown name is a one-line usage error."""
    bag = tmp_path / "tb"
    made = cli("synth-bag", bag, "--source", "testbed", "--shots", "4", "--seed", "2")
    assert made.returncode == 0, made.stderr
    out = tmp_path / "identified.yaml"
    run = cli("sysid", bag, "--method", "hebo", "--identify", "damping", "restitution_slope", "--iterations", "2", "--batch", "2",
               "--polish", "6", "--out", out, "--json", timeout=600)
    assert run.returncode == 0, run.stderr[-3000:]
    report = json.loads(run.stdout)
    assert report["evaluations"] <= 1 + 2 * 2 + 6 + 3  # --polish 6 instead of config's 60 (the simplex may end a step late)
    assert set(report["identified"]) == set(report["initial"]) == {"damping", "restitution_slope"}
    assert 0.0 <= report["identified"]["restitution_slope"] <= 0.4  # config/sysid.yaml bounds
    written = [line.split(":")[0].strip() for line in out.read_text().splitlines() if line.startswith("    ")]
    assert written == ["damping", "restitution_slope"]
    bad = cli("sysid", bag, "--identify", "gravity")
    assert bad.returncode == 2 and "invalid choice: 'gravity'" in bad.stderr

"""The MuJoCo table (sim/mujoco_table.py): its scene checked against closed forms and a conservation law,
then the tracker measured on trajectories MuJoCo made (no code of ours integrates them)."""
import json
import math
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from air_hockey_agent.core.estimation.ekf import PuckEKF
from air_hockey_agent.core.estimation.evaluation import EvaluationTotals, evaluate_stream
from air_hockey_agent.core.puck.impact import speed_restitution
from air_hockey_agent.sim.mujoco_table import MujocoPuck, MujocoTable
from air_hockey_agent.tracker_params import load_tracker_params
from model_fixtures import TABLE, session_on_mujoco, synthetic_config

CONFIGURED = MujocoTable.from_params(synthetic_config())
FLAT = replace(CONFIGURED, tilt=0.0)
R = TABLE.puck_radius


def test_free_flight_decays_as_the_closed_form():
    """Away from the rims the puck's velocity and spin decay as exp(-d t) and the position follows
    x0 + v0 (1 - exp(-d t)) / d (MuJoCo's implicit damping at 0.2 ms steps: 1e-4 relative, 0.1 mm after 1 s)."""
    puck = MujocoPuck(TABLE, FLAT)
    d, da = FLAT.damping, FLAT.angular_damping
    times, states = puck.simulate(np.array([-0.5, -0.2, 0.6, 0.25, 0.3, 8.0]), 1.0)
    t = times[-1]
    decay = math.exp(-d * t)
    assert states[-1, 2:4] == pytest.approx([0.6 * decay, 0.25 * decay], rel=1e-4)
    assert states[-1, 0:2] == pytest.approx([-0.5 + 0.6 * (1 - decay) / d, -0.2 + 0.25 * (1 - decay) / d], abs=1e-4)
    assert states[-1, 5] == pytest.approx(8.0 * math.exp(-da * t), rel=1e-4)


def test_a_tilted_surface_accelerates_a_resting_puck_downhill():
    """g sin(tilt) toward the heading, against the damping: v(t) = a (1 - exp(-d t)) / d."""
    table = replace(CONFIGURED, tilt=0.004, tilt_heading=2.0)
    times, states = MujocoPuck(TABLE, table).simulate(np.zeros(6), 0.5)
    a = 9.81 * math.sin(0.004)
    v = a * (1 - math.exp(-table.damping * times[-1])) / table.damping
    assert states[-1, 2:4] == pytest.approx([v * math.cos(2.0), v * math.sin(2.0)], rel=1e-3)


def rim_impact_on_mujoco(vb, vn, omega):
    """(incoming, outgoing) (vb, vn, omega) of one impact on the +y rim without damping, in the rim's frame
    (core/puck/impact.py: b = -x, n = -y), the outgoing velocity once the contact has let go."""
    puck = MujocoPuck(TABLE, replace(FLAT, damping=0.0, angular_damping=0.0))
    times, states = puck.simulate(np.array([0.0, TABLE.y_limit - 0.005, -vb, -vn, 0.0, omega]), 0.4)
    after = states[np.flatnonzero((states[:, 3] < 0) & (states[:, 1] < TABLE.y_limit - 0.002))[0]]
    return (vb, vn, omega), (-after[2], -after[3], after[5])


def test_a_rim_impact_keeps_the_angular_momentum_about_the_contact_and_is_softer_than_routh():
    """The rim's impulse acts at the contact point, so the puck's angular momentum about it is kept:
    the spin changes by 2 / r times the tangential velocity's change (a disc's inertia). The normal speed
    comes back at 0.70-0.80 (solref's damping ratio 0.1: exp(-pi 0.1 / sqrt(0.99)) = 0.73 for a linear
    contact), the tangential impulse is far less than Routh's sticking one (a third of the slip)."""
    rng = np.random.default_rng(3)
    for _ in range(12):
        before, after = rim_impact_on_mujoco(rng.uniform(-1.5, 1.5), -rng.uniform(0.3, 3.0), rng.uniform(-15, 15))
        dvb, domega = after[0] - before[0], after[2] - before[2]
        assert domega * R / 2 == pytest.approx(dvb, abs=0.03 * abs(dvb) + 1e-3)
        assert 0.70 < -after[1] / before[1] < 0.80
        slip = before[0] + R * before[2]
        assert 0.3 < dvb / (-slip / 3) < 0.6


def test_a_puck_through_the_goal_mouth_leaves_the_table():
    times, states = MujocoPuck(TABLE, FLAT).simulate(np.array([0.5, 0.0, 2.0, 0.0, 0.0, 0.0]), 0.6)
    assert states[-1, 0] > TABLE.length / 2 + 0.2 and abs(states[-1, 1]) < 1e-9


@pytest.fixture(scope="module")
def mujoco_session():
    """Ten shots on the MuJoCo table through the tracker with the repository's defaults (it learns online)."""
    params = load_tracker_params()
    ekf = PuckEKF.from_params(params)
    totals = EvaluationTotals((0.5, 1.0), rest_speed=params["regime_rest_speed"])
    evaluate_stream(ekf, [(f.stamp, f.measurement) for f in session_on_mujoco(ekf, 10, 5)], totals)
    return ekf.learning.report(), totals.summary(), ekf.model.params


def test_the_tracker_learns_the_mujoco_tables_flight(mujoco_session):
    """Damping and tilt learned online from MuJoCo's free flight: within 10 % of its 0.13 1/s (and no
    surface friction beyond 2 std: its film is viscous) and within 3 standard deviations of its g sin(0.001)
    along +x, the spin's decay within 10 % of its hinge's 0.4 1/s
    (config/synthetic.yaml's mujoco.*)."""
    flight = mujoco_session[0]["table_acceleration"]
    assert flight["damping"] == pytest.approx(CONFIGURED.damping, rel=0.1)
    assert flight["friction_surface"] < 2 * flight["friction_surface_std"]  # a viscous film alone: no constant part
    assert mujoco_session[0]["spin_damping"]["value"] == pytest.approx(CONFIGURED.angular_damping, rel=0.1)
    for axis in range(2):
        assert abs(flight["value"][axis] - CONFIGURED.tilt_acceleration[axis]) < 3 * flight["std"][axis]


def meeting_delay_on_mujoco(vn: float) -> tuple[float, float]:
    """Where the straight paths before and after one head-on impact on the +y rim meet, beyond the rim line,
    over the normal speed ``vn`` [m/s] (the model's impact_delay for this rim, from the engine's own noiseless
    states at every step), and how long the contact lasted [s]."""
    puck = MujocoPuck(TABLE, replace(FLAT, damping=0.0, angular_damping=0.0))
    times, states = puck.simulate(np.array([0.0, TABLE.y_limit - 0.02, 0.4, vn, 0.0, 0.0]), 0.02 / vn + 0.03)
    y, clear = states[:, 1], states[:, 1] < TABLE.y_limit - 0.001
    (a1, b1), (a2, b2) = (np.polyfit(times[clear & (states[:, 3] * sign > 0)], y[clear & (states[:, 3] * sign > 0)], 1)
                          for sign in (1.0, -1.0))
    meet = a1 * (b2 - b1) / (a1 - a2) + b1
    return (meet - TABLE.y_limit) / vn, float(np.sum(y > TABLE.y_limit) * (times[1] - times[0]))


def test_the_tracker_learns_the_mujoco_rims_delay(mujoco_session):
    """Where the watched impacts' paths meet: impact_delay learned online within 20 % of where MuJoCo's own
    noiseless paths meet (after 38 impacts the configured rigid rim, worth 5, still pulls it about 12 %)."""
    delay = mujoco_session[0]["impact_delay"]
    engine = np.mean([meeting_delay_on_mujoco(vn)[0] for vn in (0.5, 1.0, 2.0)])
    assert delay["impacts"] >= 30 and delay["value"] == pytest.approx(engine, rel=0.2)
    assert mujoco_session[2].impact_delay == delay["value"]  # the model predicts with it


def test_a_soft_rims_paths_meet_beyond_it_by_half_the_contact():
    """MuJoCo's rims are soft constraints: the puck goes on into the rim for a contact of 2.2-2.4 ms, so the
    paths before and after meet beyond the rim line by about the normal speed times half the contact (a linear
    spring's exactly half), at every speed: what the model's impact_delay is."""
    for vn in (0.3, 1.0, 3.0):
        delay, contact = meeting_delay_on_mujoco(vn)
        assert 0.4 * contact < delay < 0.5 * contact and 0.002 <= contact <= 0.0025


@pytest.fixture(scope="module")
def mujoco_rims():
    """MuJoCo's own rims, measured: (median fraction of Routh's sticking impulse, median restitution) of
    ten impacts at 0.3-3 m/s normal speed."""
    rng = np.random.default_rng(7)
    impacts = [rim_impact_on_mujoco(rng.uniform(-1.5, 1.5), -rng.uniform(0.3, 3.0), rng.uniform(-15, 15))
               for _ in range(10)]
    return (float(np.median([(a[0] - b[0]) / (-(b[0] + R * b[2]) / 3) for b, a in impacts])),
            float(np.median([-a[1] / b[1] for b, a in impacts])))


def restitution_at(p: dict, speed: float) -> float:
    return speed_restitution(p["restitution"], p["restitution_slope"], -speed, p["restitution_min"],
                             p["restitution_knee"])[0]


def test_the_tracker_learns_the_mujoco_rims_in_the_stick_fraction_form(mujoco_session, mujoco_rims):
    """MuJoCo's rims push along themselves in proportion to the slip, far below Coulomb's bound: the
    stick-fraction form is chosen, its fraction within 15 % of the one measured from MuJoCo's own
    impacts, and the learned restitution at 1 m/s within 10 % of MuJoCo's."""
    law = mujoco_session[0]["rim_law"]
    assert law["tangential_form"] == "stick fraction"
    assert law["stick_fraction"] == pytest.approx(mujoco_rims[0], rel=0.15)
    assert restitution_at(law["params"], 1.0) == pytest.approx(mujoco_rims[1], rel=0.1)


def test_split_sysid_finds_the_mujoco_tables_physics(tmp_path, mujoco_rims):
    """Issue #13 item 5's recovery test on another engine's bag, as a user runs it: damping and the tilt's
    acceleration within 10 % of MuJoCo's, restitution at 0.5, 1 and 2 m/s and the sticking fraction
    (1 + beta) within 10 % of MuJoCo's own impacts, the spin's decay (spin_damping) within 10 % of its
    hinge's; the report says so."""
    exe = Path(sys.executable).parent / "air-hockey"
    made = subprocess.run([exe, "synth-bag", tmp_path / "mj", "--source", "mujoco", "--shots", "12", "--seed", "2"],
                          capture_output=True, text=True, timeout=300)
    assert made.returncode == 0, made.stderr
    run = subprocess.run([exe, "sysid", tmp_path / "mj", "--json"], capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr[-2000:]
    report = json.loads(run.stdout)
    found = report["identified"]
    spin = report["objective"]["flight"]["spin_decay"]
    assert found["spin_damping"] == spin["rate_per_s"] == pytest.approx(CONFIGURED.angular_damping, rel=0.1)
    text = subprocess.run([exe, "sysid", tmp_path / "mj"], capture_output=True, text=True, timeout=300)
    assert "the spin decays in free flight at" in text.stdout and "spin_damping identified" in text.stdout
    assert found["damping"] == pytest.approx(CONFIGURED.damping, rel=0.1)
    assert found["table_acceleration"][0] == pytest.approx(CONFIGURED.tilt_acceleration[0], rel=0.1)
    assert abs(found["table_acceleration"][1]) < 0.1 * CONFIGURED.tilt_acceleration[0]
    for speed in (0.5, 1.0, 2.0):
        assert restitution_at(found, speed) == pytest.approx(mujoco_rims[1], rel=0.1)
    assert 1.0 + found["tangential_restitution"] == pytest.approx(mujoco_rims[0], rel=0.1)
    assert found["impact_delay"] > 0.0005  # a soft rim's (the next test: its value)


def test_split_sysid_finds_where_the_mujoco_rims_paths_meet(tmp_path):
    """impact_delay from a 40-shot bag's noisy mocap poses (112 impacts) within 10 % of where MuJoCo's own
    noiseless paths before and after an impact meet, and the rim lines where the model has them."""
    exe = Path(sys.executable).parent / "air-hockey"
    made = subprocess.run([exe, "synth-bag", tmp_path / "mj", "--source", "mujoco", "--shots", "40", "--seed", "2"],
                          capture_output=True, text=True, timeout=300)
    assert made.returncode == 0, made.stderr
    run = subprocess.run([exe, "sysid", tmp_path / "mj", "--identify", "impact_delay", "--json"], capture_output=True,
                         text=True, timeout=300)
    assert run.returncode == 0, run.stderr[-2000:]
    report = json.loads(run.stdout)
    engine = np.mean([meeting_delay_on_mujoco(vn)[0] for vn in (0.5, 1.0, 2.0)])
    assert report["identified"]["impact_delay"] == pytest.approx(engine, rel=0.1)
    assert max(map(abs, report["objective"]["impacts"]["delay"]["offsets_m"].values())) < 5e-4


def test_predictions_on_the_mujoco_table(mujoco_session):
    """Measured on trajectories no model of ours made: free flight within a few millimetres at 0.5 s, the
    filter's flight and impact innovations near consistent (NIS median of a consistent 3-dof filter: 2.37)."""
    summary = mujoco_session[1]
    assert summary["by_path"]["0.5"]["no_impact"]["median_m"] < 0.003
    assert summary["by_path"]["1.0"]["one_impact"]["median_m"] < 0.03
    assert 1.5 < summary["nis_by_regime"]["flight"]["median"] < 4.0


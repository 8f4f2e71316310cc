"""Table files (air-hockey game / strategy-test --table, sim/table_file.py): what they may set, the one-line
errors, and where their values go in process (the node graph's side: test_launch_files.py, test_node_cli.py)."""
from pathlib import Path

import numpy as np
import pytest

from air_hockey_agent.paths import config_file
from air_hockey_agent.sim.table_file import table_problem

LAB = config_file("lab_table.yaml")


def write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "table.yaml"
    path.write_text(text)
    return path


def test_the_lab_table_file_loads_and_says_what_the_recordings_say():
    """config/lab_table.yaml (issue #13): free flight at 0.6-1 m/s decelerates by about 0.10 m/s^2, about
    0.03 m/s^2 pushes a puck across its track, a resting puck rests anywhere (the friction beats the push
    everywhere), and the rims take the tracker's restitution law (config/tracker.yaml)."""
    from air_hockey_agent.core.puck.surface_field import SurfaceField
    from air_hockey_agent.sim.params import load_sim_params
    from air_hockey_agent.tracker_params import load_tracker_params
    assert table_problem(LAB) == ""
    sim, tracker = load_sim_params([LAB]), load_tracker_params()
    for speed in (0.6, 0.8, 1.0):
        deceleration = sim["surface_damping"] * speed + sim["surface_friction"]
        assert deceleration == pytest.approx(0.10, abs=0.02), speed
    field = SurfaceField.from_params(sim)
    pushes = [float(np.hypot(*field.at(x, y))) for x in np.linspace(-1, 1, 41) for y in np.linspace(-0.5, 0.5, 21)]
    assert 0.02 < np.median(pushes) and max(pushes) == pytest.approx(0.03, abs=0.005)
    assert max(pushes) <= field.max_push <= sim["surface_friction"]
    for sim_name, tracker_name in (("rim_restitution", "restitution"), ("rim_restitution_knee", "restitution_knee"),
                                   ("rim_restitution_slope", "restitution_slope"),
                                   ("rim_restitution_min", "restitution_min"), ("rim_friction", "friction_rim")):
        assert sim[sim_name] == tracker[tracker_name], sim_name


def test_a_slide_is_decided_early_only_where_the_friction_holds_the_puck_against_the_surfaces_push(tmp_path):
    """TrialSettings.damping bounds a slide by speed / damping: true where the surface friction beats
    the tilt and air film everywhere and nothing pushes at random, not where the puck can be pushed on
    (a weaker friction, or random pushes: the lab's table)."""
    from air_hockey_agent.strategy_params import trial_settings
    def damping(friction: float, extra: str = "") -> float:
        path = write(tmp_path, "/**/table_sim:\n  ros__parameters:\n    surface_damping: 0.3\n"
                               f"    surface_friction: {friction}\n    surface_tilt: 0.002\n{extra}")
        return trial_settings(table_file=str(path)).damping
    assert damping(0.03) == 0.3  # g sin(0.002) = 0.0196 m/s^2
    assert damping(0.01) == 0.0 and damping(0.03, "    random_acceleration: 0.001\n") == 0.0
    assert trial_settings(table_file=str(LAB)).damping == 0.0


@pytest.mark.parametrize("text, message", [
    ("/**/puck_tracker:\n  ros__parameters:\n    damping: 0.2\n", "no '/**/table_sim' section"),
    ("/**/table_sim:\n  ros__parameters:\n    surface_dampng: 0.2\n", "did you mean 'surface_damping'"),
    ("/**/table_sim:\n  ros__parameters:\n    surface_damping: -1.0\n", "'surface_damping' = -1.0 is outside"),
    ("/iiwa_front/puck_tracker:\n  ros__parameters:\n    damping: 0.2\n", "takes sections for any namespace"),
    ("/**/tactics:\n  ros__parameters:\n    aim_noise: 0.1\n",
     "sets only table_sim, puck_tracker and strategy_test parameters"),
    ("/**/table_sim:\n  ros__parameters:\n    surface_damping: 0.2\n/**/puck_tracker:\n  ros__parameters:\n"
     "    dampin: 0.2\n", "did you mean 'damping'"),
    ("/**/table_sim: [\n", "not valid YAML"),
])
def test_a_bad_table_file_is_one_line_naming_the_file_and_what_is_wrong(tmp_path, text, message):
    path = write(tmp_path, text)
    problem = table_problem(path)
    assert message in problem and str(path) in problem and problem.startswith("--table") and "\n" not in problem
    assert table_problem(tmp_path / "none.yaml") == f"--table {tmp_path / 'none.yaml'}: no such file"


def test_in_process_the_table_file_sets_the_simulated_table_and_what_the_agent_is_told(tmp_path):
    """The simulation reads the file's table_sim section; the tracker and the tactics config/tracker.yaml (a
    real table's defaults, its learning on) and the file's puck_tracker section, not tracker_sim_table.yaml;
    the strategy test its strategy_test section and the simulated table's damping."""
    from air_hockey_agent.sim.game_loop import GameConfig
    from air_hockey_agent.strategy_params import trial_settings
    from air_hockey_agent.tracker_params import load_tracker_params
    path = write(tmp_path, "/**/table_sim:\n  ros__parameters:\n    surface_damping: 0.3\n"
                           "    rim_restitution_slope: 0.1\n/**/puck_tracker:\n  ros__parameters:\n    damping: 0.31\n"
                           "/**/strategy_test:\n  ros__parameters:\n    timeout: 25.0\n")
    known, table = GameConfig.load(0), GameConfig.load(0, table=str(path))
    assert (table.sim["surface_damping"], table.sim["rim_restitution_slope"]) == (0.3, 0.1)
    assert table.sim["rim_restitution"] == known.sim["rim_restitution"]
    assert table.tracker == {**load_tracker_params(), "damping": 0.31}
    assert table.tracker["rim_adaptation.enabled"] and not known.tracker["rim_adaptation.enabled"]
    assert table.agent["puck_params_file"] == str(path) != known.agent["puck_params_file"]
    settings, default = trial_settings(table_file=str(path)), trial_settings()
    assert (settings.timeout, settings.damping) == (25.0, 0.3)
    assert (default.timeout, default.damping) == (10.0, known.sim["surface_damping"])


def test_the_strategy_tests_node_graph_reads_a_table_file_only_when_given():
    """worker_processes: with a table file table_sim and strategy_test read it and strategy_test is told its
    path; without one no such argument (rcl refuses an empty '-p table_file:=': every trial's node failed)."""
    from air_hockey_agent.tools.strategy_test import worker_processes
    plain = {spec.label: list(spec.command) for spec in worker_processes([("cut", 0)], 0)}
    assert not any("table_file" in arg or arg == "--params-file" for arg in plain["strategy_test"] + plain["table_sim"])
    table = {spec.label: list(spec.command) for spec in worker_processes([("cut", 0)], 0, table_file=str(LAB))}
    for label in ("table_sim", "strategy_test"):
        assert table[label][table[label].index("--params-file") + 1] == str(LAB)
    assert f"table_file:={LAB}" in table["strategy_test"]
    assert f"puck_params_file:={LAB}" in table["tactics"]


def test_the_strategy_plots_say_the_table_and_the_defence(tmp_path, monkeypatch):
    """strategy-test --plot with --table (and --defended): each figure's title names the set-up; the thesis's
    set-up has no title."""
    from air_hockey_agent.tools import strategy_plots
    titles = []
    save = strategy_plots.save_figure

    def keep_title(fig, path, **kwargs):
        titles.append(fig.axes[0].get_title())
        return save(fig, path, **kwargs)
    monkeypatch.setattr(strategy_plots, "save_figure", keep_title)
    summary = {"cut": {"success_rate": 0.4, "partial_rate": 0.9, "trials": 1}}
    results = [{"strategy": "cut", "offset": None}]
    strategy_plots.write_plots(summary, results, tmp_path / "plain")
    strategy_plots.write_plots(summary, results, tmp_path / "lab", table="config/lab_table.yaml")
    strategy_plots.write_plots(summary, results, tmp_path / "both", defended=True, table="config/lab_table.yaml")
    assert titles[:2] == ["", ""]
    assert all(t == "on the simulated table of config/lab_table.yaml (--table)" for t in titles[2:4])
    assert all("--defended" in t and t.endswith("config/lab_table.yaml (--table)") for t in titles[4:])
    assert (tmp_path / "lab" / "strategy_success.png").is_file() and (tmp_path / "lab" / "smash_spread.png").is_file()

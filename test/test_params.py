"""Parameter files and declarations: defaults load, overrides apply, bad values are refused clearly."""
from pathlib import Path

import pytest
import yaml

from air_hockey_agent.params import (ParameterFileError, ParameterValueError, ParamSpec, load_defaults,
                                     load_parameter_file)
from air_hockey_agent.paths import config_dir

SPECS = (ParamSpec("rate", float, "[Hz] rate", 1.0, 1000.0), ParamSpec("name", str, "a name"))


def write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "p.yaml"
    path.write_text(text)
    return path


def test_wildcard_then_exact_node_section_wins(tmp_path):
    path = write(tmp_path, "/**:\n  ros__parameters:\n    rate: 10.0\n    name: all\n"
                           "/**/tracker:\n  ros__parameters:\n    rate: 120.0\n")
    assert load_parameter_file(path, "/iiwa_front/tracker") == {"rate": 120.0, "name": "all"}
    assert load_parameter_file(path, "/referee") == {"rate": 10.0, "name": "all"}


def test_nested_parameters_are_flattened_with_dots(tmp_path):
    path = write(tmp_path, "/**:\n  ros__parameters:\n    table:\n      length: 1.956\n")
    assert load_parameter_file(path, "/x") == {"table.length": 1.956}


def test_later_files_override_earlier(tmp_path):
    a, b = tmp_path / "a.yaml", tmp_path / "b.yaml"
    a.write_text("/**:\n  ros__parameters:\n    rate: 10.0\n    name: a\n")
    b.write_text("/**:\n  ros__parameters:\n    rate: 20\n")
    assert load_defaults([a, b], "/n", SPECS) == {"rate": 20.0, "name": "a"}


def test_out_of_range_value_is_refused_with_name_and_range():
    with pytest.raises(ParameterValueError, match=r"'rate' = 0.5 is outside \[1.0, 1000.0\]"):
        SPECS[0].check(0.5)


def test_wrong_type_is_refused():
    with pytest.raises(ParameterValueError, match="'name' must be of type str"):
        SPECS[1].check(3)
    with pytest.raises(ParameterValueError, match="must be finite"):
        SPECS[0].check(float("nan"))
    with pytest.raises(ParameterValueError, match=r"'xy' must be a list of numbers, got list \['x', 0\]"):
        ParamSpec("xy", list, "a pair", length=2).check(["x", 0])


def test_numbers_without_a_decimal_point_are_numbers_as_in_ros2(tmp_path):
    """PyYAML (YAML 1.1) reads 1e-3 as a string; ROS 2's parameter parser as a double, and so do we: a
    copied ROS 2 parameter file with ``1e-3`` was refused as "must be of type float, got str '1e-3'"."""
    path = write(tmp_path, "/**:\n  ros__parameters:\n    rate: 1e2\n    low: -2.5E-3\n    big: 1e400\n"
                           "    name: e5\n    word: 1e\n    whole: 12\n")
    values = load_parameter_file(path, "/node")
    assert values["rate"] == 100.0 and values["low"] == -0.0025 and values["big"] == float("inf")
    assert values["name"] == "e5" and values["word"] == "1e" and values["whole"] == 12
    assert SPECS[0].check(values["rate"]) == 100.0
    with pytest.raises(ParameterValueError, match="must be finite"):
        SPECS[0].check(values["big"])
    assert yaml.safe_load("1e-3") == "1e-3"  # what PyYAML alone gives


def test_missing_default_names_parameter_and_file(tmp_path):
    path = write(tmp_path, "/**:\n  ros__parameters:\n    rate: 10.0\n")
    with pytest.raises(ParameterFileError, match=r"no default for parameter 'name'.*p\.yaml"):
        load_defaults([path], "/n", SPECS)


def test_malformed_file_is_a_one_line_error_naming_the_file(tmp_path):
    path = write(tmp_path, "/**: [unclosed\n")
    with pytest.raises(ParameterFileError, match=r"p\.yaml: not valid YAML"):
        load_parameter_file(path, "/n")
    with pytest.raises(ParameterFileError, match=r"missing\.yaml: cannot read"):
        load_parameter_file(tmp_path / "missing.yaml", "/n")


@pytest.mark.parametrize("path", sorted(config_dir().glob("*.yaml")), ids=lambda p: p.name)
def test_every_config_file_is_a_ros_parameter_file(path):
    document = yaml.safe_load(path.read_text())
    assert isinstance(document, dict) and document
    for key, block in document.items():
        assert key.startswith("/"), f"{path.name}: section '{key}' should be a /** or fully qualified pattern"
        assert "ros__parameters" in block, f"{path.name}: section '{key}' lacks ros__parameters"


def test_yaml_float_reads_back_as_the_same_float():
    import yaml

    from air_hockey_agent.params import yaml_float
    for value in (1e-6, 2.28e-4, 0.5, 3.0, -1e-10, 123456789.0, 0.0):
        text = yaml_float(value)
        assert isinstance(yaml.safe_load(text), float) and float(yaml.safe_load(text)) == pytest.approx(value, rel=1e-8)


def test_every_shipped_parameter_file_passes_the_misspelling_check():
    """Each section of config/*.yaml names a node or tool of the package and each key is declared by
    the node it is for (by some node in a '/**' section): a user may pass any of them as --params-file."""
    from air_hockey_agent.param_registry import node_parameters
    from air_hockey_agent.params import check_parameter_file
    from air_hockey_agent.paths import config_file
    nodes = node_parameters()
    files = sorted(config_file("tracker.yaml").parent.glob("*.yaml"))
    assert len(files) >= 10
    for path in files:
        check_parameter_file(path, "puck_tracker", nodes["puck_tracker"], nodes)


def test_the_sim_table_tracker_file_has_the_simulated_tables_physics():
    """config/tracker_sim_table.yaml (the tracker and tactics on the simulated table) carries
    config/sim.yaml's air film and rim values; the tracker's defaults are a real table's."""
    from air_hockey_agent.sim.params import load_sim_params
    from air_hockey_agent.paths import config_file
    from air_hockey_agent.tracker_params import SIM_TABLE_FILE, load_tracker_params
    sim, tracker = load_sim_params(), load_tracker_params([config_file(SIM_TABLE_FILE)])
    for tracker_name, sim_name in (("friction_surface", "surface_friction"), ("damping", "surface_damping"),
                                   ("restitution", "rim_restitution"), ("friction_rim", "rim_friction"),
                                   ("restitution_slope", "rim_restitution_slope")):
        assert tracker[tracker_name] == sim[sim_name], tracker_name
    assert tracker["restitution_slope"] == 0.0  # so the knee and restitution_min, a real table's, do not act
    assert load_tracker_params()["damping"] != sim["surface_damping"]


def test_a_misspelled_key_in_the_config_directory_is_an_error_naming_the_file(tmp_path, monkeypatch):
    """The defaults are checked as a --params-file is: an edited config/ (here AIR_HOCKEY_CONFIG_DIR's copy)
    with a misspelled key is refused with the file, section and key, not read without it."""
    import shutil
    from air_hockey_agent.tracker_params import load_tracker_params
    copy = tmp_path / "config"
    shutil.copytree(config_dir(), copy)
    monkeypatch.setenv("AIR_HOCKEY_CONFIG_DIR", str(copy))
    assert load_tracker_params()["hand.stop_fraction"] == 0.25
    text = (copy / "tracker.yaml").read_text()
    (copy / "tracker.yaml").write_text(text.replace("      stop_fraction: 0.25", "      stop_fracton: 0.25"))
    with pytest.raises(ParameterFileError, match=r"config/tracker\.yaml: section '/\*\*/puck_tracker': "
                                                 r"'hand\.stop_fracton' is not a parameter of node 'puck_tracker'"):
        load_tracker_params()


@pytest.mark.parametrize("text, readers, read", [
    ("/**/puck_tracker:\n  ros__parameters:\n    damping: 0.2\n", ("puck_tracker",), True),
    ("/**:\n  ros__parameters:\n    damping: 0.2\n", ("puck_tracker",), True),     # a key the reader declares
    ("/**:\n  ros__parameters:\n    robot: iiwa_back\n", ("puck_tracker",), False),  # only others' keys
    ("/**/puck_tracker:\n  ros__parameters: {}\n", ("puck_tracker",), False),       # a section that sets nothing
    ("/**/table_sim:\n  ros__parameters:\n    surface_damping: 0.2\n", ("puck_tracker", "sysid"), False),
    ("/**/table_sim:\n  ros__parameters:\n    surface_damping: 0.2\n", ("puck_tracker", "table_sim"), True),
    ("", ("puck_tracker",), False),
])
def test_a_file_that_sets_nothing_a_command_reads_is_refused_naming_it(tmp_path, text, readers, read):
    from air_hockey_agent.params import check_files_read
    good, path = tmp_path / "good.yaml", tmp_path / "p.yaml"
    good.write_text("/**/puck_tracker:\n  ros__parameters:\n    damping: 0.2\n/**/table_sim:\n  ros__parameters:\n"
                    "    surface_damping: 0.2\n")
    path.write_text(text)
    if read:
        check_files_read([good, path], readers)
        return
    with pytest.raises(ParameterFileError, match=r"p\.yaml: --params-file sets no parameter of"):
        check_files_read([good, path], readers)

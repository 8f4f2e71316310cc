"""`air-hockey synth-bag` and `air-hockey eval-prediction` as a user runs them (console script)."""
import json
import subprocess
import sys
from pathlib import Path

import pytest

from helpers.ros1_bags import poses_to_tf_bag

EXE = Path(sys.executable).parent / "air-hockey"


def cli(*args, timeout=120):
    return subprocess.run([str(EXE), *map(str, args)], capture_output=True, text=True, timeout=timeout)


@pytest.fixture(scope="module")
def bags(tmp_path_factory):
    root = tmp_path_factory.mktemp("bags")
    for name, storage, seed in (("a", "mcap", 1), ("b", "sqlite3", 2)):
        out = cli("synth-bag", root / name, "--shots", 3, "--storage", storage, "--seed", seed)
        assert out.returncode == 0, out.stderr
        assert "3 shots" in out.stdout
    return root


@pytest.fixture(scope="module")
def report_a(bags):
    """`eval-prediction a --json`, run once for the tests that compare another reading of the same poses
    (or a derived bag) with it."""
    out = cli("eval-prediction", bags / "a", "--json")
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout)


def strict_json(text):
    """JSON as RFC 8259 has it: Python's json module would also read NaN and Infinity, which are not JSON."""
    def refuse(word):
        raise ValueError(f"{word} is not JSON")
    return json.loads(text, parse_constant=refuse)


def test_json_report_is_exactly_one_object_with_the_documented_keys(bags):
    out = cli("eval-prediction", bags / "a", bags / "b", "--json")
    assert out.returncode == 0, out.stderr
    report = strict_json(out.stdout)  # the whole of stdout is one JSON document
    assert set(report) == {"horizons", "bags", "frames", "lost_frames", "outliers_rejected", "off_table_poses", "rejected_fraction",
                           "reinit_per_s", "nis", "nis_by_regime", "by_path", "rim_law", "table_acceleration",
                           "spin_damping", "impact_delay", "marker_offset", "marker_noise", "process_noise",
                           "thesis_style", "hand"}
    law = report["rim_law"]  # the bags' shots are flown with the configured physics: learning it keeps it
    assert set(law) == {"impacts", "restitution_scale", "fall_scale", "knee", "fall_width", "tangential_scale",
                        "stick_fraction", "friction_rim", "tangential_form", "params"}
    assert law["tangential_form"] == "scaled"
    assert law["impacts"] >= 3 and abs(law["restitution_scale"] - 1.0) < 0.02
    assert abs(law["fall_scale"] - 1.0) < 0.1 and abs(law["tangential_scale"] - 1.0) < 0.1
    assert law["params"]["restitution_knee"] == law["knee"]
    flight = report["table_acceleration"]
    assert set(flight) == {"windows", "value", "std", "damping", "damping_std", "friction_surface",
                           "friction_surface_std"} and flight["windows"] >= 10
    assert max(map(abs, flight["value"])) < 0.01 and abs(flight["damping"] - 0.125) < 0.02
    assert flight["friction_surface"] < 0.02 and flight["friction_surface_std"] > 0.0
    spin = report["spin_damping"]  # the shots' spin is constant, as the configured model's
    assert set(spin) == {"windows", "value", "std"} and spin["windows"] >= 10 and spin["value"] < 3 * spin["std"]
    delay = report["impact_delay"]  # the model's rims are rigid: their paths meet on the line
    assert set(delay) == {"impacts", "value", "rim_offsets", "rims_off"} and 0 < delay["impacts"] <= law["impacts"]
    assert delay["value"] < 2e-4 and delay["rims_off"] == []  # and on the model's lines
    assert sum(o["impacts"] for o in delay["rim_offsets"].values()) == delay["impacts"]
    offset = report["marker_offset"]  # the bags' pivot is the disc's centre
    assert set(offset) == {"windows", "value", "std"} and max(map(abs, offset["value"])) < 3e-4
    process = report["process_noise"]  # the model's own flight: nothing is missing, the scale does not grow
    assert set(process) == {"flight", "rest", "impact"} and process["flight"]["blocks"] >= 3
    flight = process["flight"]
    assert flight["scale"] <= 1.0 and flight["acceleration_std_m_s2"] == pytest.approx(0.03 * flight["scale"] ** 0.5)
    assert set(process["impact"]) == {"blocks", "scale", "impact_noise", "impact_contact_time_s"}
    assert set(report["nis"]) == {"median", "mean"}
    assert set(report["by_path"]) == set(report["horizons"])
    for key, paths in report["by_path"].items():
        assert list(paths) == ["rest", "no_impact", "one_impact", "impacts", "goal"]
        assert sum(v["n"] for v in paths.values()) == report["horizons"][key]["n"]
    assert set(report["nis_by_regime"]) == {"rest", "flight", "impact"}
    assert all(set(v) == {"median", "mean", "n"} for v in report["nis_by_regime"].values())
    assert 0.0 <= report["rejected_fraction"] < 0.1 and report["reinit_per_s"] >= 0.0
    assert set(report["horizons"]) == {"0.5", "1.0", "1.5"}
    assert set(report["horizons"]["1.0"]) == {"mean_m", "median_m", "p95_m", "n"}
    assert report["bags"] == 2 and report["frames"] > 1000
    assert report["horizons"]["0.5"]["median_m"] <= 3e-3 and report["horizons"]["1.0"]["median_m"] <= 8e-3


def test_a_figure_that_is_not_a_number_is_null_in_json(tmp_path):
    """One shot: a rim met once has an offset whose standard deviation is infinite; --json wrote it as
    `Infinity`, which JSON parsers other than Python's refuse."""
    assert cli("synth-bag", tmp_path / "one", "--shots", 1, "--seed", 1).returncode == 0
    out = cli("eval-prediction", tmp_path / "one", "--json")
    assert out.returncode == 0, out.stderr
    offsets = strict_json(out.stdout)["impact_delay"]["rim_offsets"]
    assert any(rim["impacts"] == 1 and rim["std_m"] is None for rim in offsets.values()), offsets


def test_json_text_writes_every_non_finite_float_as_null():
    from air_hockey_agent.tools.json_output import json_text
    value = {"a": float("nan"), "b": [1.5, float("inf"), (-float("inf"), 2)], "c": {"d": None, "e": "NaN"}, "f": 3}
    assert json.loads(json_text(value)) == {"a": None, "b": [1.5, None, [None, 2]], "c": {"d": None, "e": "NaN"},
                                            "f": 3}
    assert value["a"] != value["a"] and value["b"][1] == float("inf")  # the input is left as it was


def test_thesis_style_columns_are_sysids_over_the_same_trajectories(bags, report_a):
    """eval-prediction's trajectory-level columns (thesis tables 5.2-5.4) are the ones sysid reports: with
    the default parameters at 1.0 s, sysid's "before" loss pooled over its training and validation
    trajectories (weighted by comparisons) and the lower of their minima are eval-prediction's."""
    thesis = report_a["thesis_style"]
    assert thesis["trajectories"] >= 3 and set(thesis) == {"trajectories", "0.5", "1.0", "1.5"}
    ident = cli("sysid", bags / "a", "--json", timeout=300)
    assert ident.returncode == 0, ident.stderr
    before = json.loads(ident.stdout)["before"]
    train, validation = before["train"], before["validation"]
    n = train["n"] + validation["n"]
    assert thesis["1.0"]["n"] == n
    assert thesis["1.0"]["loss_m"] == pytest.approx((train["loss_m"] * train["n"] + validation["loss_m"] * validation["n"]) / n, rel=1e-9)
    assert thesis["1.0"]["min_m"] == pytest.approx(min(train["min_m"], validation["min_m"]), rel=1e-9)
    assert thesis["0.5"]["loss_m"] < thesis["1.0"]["loss_m"] < thesis["1.5"]["loss_m"]


def test_bad_bags_give_one_line_errors_and_exit_2_while_good_bags_count(bags, tmp_path):
    (tmp_path / "empty_dir").mkdir()
    (tmp_path / "notes.txt").write_text("not a bag\n")
    out = cli("eval-prediction", bags / "a", tmp_path / "missing", tmp_path / "empty_dir", tmp_path / "notes.txt",
              bags / "b", "--topic", "/optitrack/puck", "--json")
    assert out.returncode == 2
    errors = out.stderr.strip().splitlines()
    assert len(errors) == 3 and "missing: does not exist" in errors[0] and "empty_dir: no bags" in errors[1]
    assert "notes.txt: not a bag (neither a rosbag2 bag" in errors[2]
    assert json.loads(out.stdout)["bags"] == 2


def test_a_directory_of_bags_is_its_bags_in_path_order(bags):
    """As sysid, noise-estimate and plot read them: the bags below a directory, sorted by path (one session,
    so the order matters to what is learned online)."""
    listed, searched = (cli("eval-prediction", *paths, "--json") for paths in ((bags / "a", bags / "b"), (bags,)))
    assert listed.returncode == searched.returncode == 0, searched.stderr
    assert json.loads(searched.stdout) == json.loads(listed.stdout) and json.loads(searched.stdout)["bags"] == 2


def test_a_ros1_copy_of_a_bag_gives_the_same_figures(bags, report_a, tmp_path):
    """The lab recorded with ROS 1: the same session converted by rosbags' own converter (Noetic types, a header
    with seq, ROS 1 serialisation) is evaluated exactly like the rosbag2 original."""
    converted = subprocess.run([str(EXE.parent / "rosbags-convert"), "--src", str(bags / "a"), "--dst",
                                str(tmp_path / "a.bag"), "--dst-typestore", "ros1_noetic",
                                "--include-topic", "/optitrack/puck"], capture_output=True, text=True, timeout=120)
    assert converted.returncode == 0, converted.stderr
    ros1 = cli("eval-prediction", tmp_path / "a.bag", "--json")
    assert ros1.returncode == 0, ros1.stderr
    assert json.loads(ros1.stdout) == report_a
    assert json.loads(ros1.stdout)["frames"] > 500


def test_the_puck_on_tf_gives_the_same_figures(bags, report_a, tmp_path):
    """The ROS 1 lab's tracker read the puck from /tf (child frame "Puck"): the same poses as transforms,
    beside another body's, are evaluated exactly like the PoseStamped original."""
    assert poses_to_tf_bag(bags / "a", tmp_path / "tf.bag") > 500
    tf = cli("eval-prediction", tmp_path / "tf.bag", "--topic", "/tf", "--json")
    assert tf.returncode == 0, tf.stderr
    assert json.loads(tf.stdout) == report_a
    wrong = cli("eval-prediction", tmp_path / "tf.bag", "--topic", "/tf", "--frame", "puck")
    assert wrong.returncode == 2 and len(wrong.stderr.strip().splitlines()) == 1
    assert "no transform to frame puck on /tf (child frames: Puck, Table; choose one with --frame)" in wrong.stderr


def test_the_table_pose_can_come_from_the_bags_own_transform(bags, report_a, tmp_path):
    """The ROS 1 lab's TF tree holds world -> Table (static): --table-frame Table takes the table pose from
    it. The same session carried into a world where the table stands elsewhere and turned 0.3 rad gives
    the original's figures; without --table-frame the poses lie off the table and a warning says so."""
    lab = ((1.694, 0.813, 0.1, 0.3), "Table")  # REFERENCE_FACTS: the lab's static world -> Table, turned
    assert poses_to_tf_bag(bags / "a", tmp_path / "lab.bag", moved=lab, table_in_source=(1.504, 0.0, 0.0, 0.0)) > 500
    original = report_a
    moved = cli("eval-prediction", tmp_path / "lab.bag", "--topic", "/tf", "--table-frame", "Table", "--json")
    assert moved.returncode == 0, moved.stderr
    report = json.loads(moved.stdout)
    assert report["frames"] == original["frames"] and report["outliers_rejected"] == original["outliers_rejected"]
    for h, figures in original["horizons"].items():
        assert report["horizons"][h]["n"] == figures["n"]
        assert report["horizons"][h]["median_m"] == pytest.approx(figures["median_m"], rel=1e-6, abs=1e-9)
    plain = cli("eval-prediction", tmp_path / "lab.bag", "--topic", "/tf")
    assert "lie off the table" in plain.stderr
    wrong = cli("eval-prediction", tmp_path / "lab.bag", "--topic", "/tf", "--table-frame", "TableHome")
    assert wrong.returncode == 2 and len(wrong.stderr.strip().splitlines()) == 1
    assert "no transform to frame TableHome on /tf_static or /tf (child frames: Puck, Table)" in wrong.stderr


def test_wrong_topic_type_is_reported(bags):
    out = cli("eval-prediction", bags / "a", "--topic", "/puck/true_state")
    assert out.returncode == 2
    assert "/puck/true_state has type air_hockey_msgs/msg/PuckState" in out.stderr


def test_no_usable_bag_prints_its_errors_and_no_report(bags):
    """As sysid and noise-estimate: with no bag read there is no report (an all-empty table said nothing)."""
    for extra in ([], ["--json"]):
        out = cli("eval-prediction", bags / "a", bags / "b", "--topic", "/nothing", *extra)
        assert out.returncode == 2 and out.stdout == ""
        assert [line.endswith("no topic /nothing (topics: /optitrack/puck, /puck/true_state)")
                for line in out.stderr.strip().splitlines()] == [True, True], out.stderr


def test_a_plot_directory_made_for_nothing_is_removed(bags, tmp_path):
    """--plot makes its directory before any bag is read (to fail fast); with no bag read (or an interrupt)
    the empty directory it made goes again, while one that was there stays."""
    made, there = tmp_path / "new" / "plots", tmp_path / "there"
    there.mkdir()
    for plots in (made, there):
        out = cli("eval-prediction", bags / "a", "--topic", "/nothing", "--plot", plots)
        assert out.returncode == 2 and out.stdout == ""
    assert not made.parent.exists() and there.is_dir()


def test_params_file_changes_the_model_and_the_error(bags, tmp_path):
    wrong = tmp_path / "wrong.yaml"
    wrong.write_text("/**/puck_tracker:\n  ros__parameters:\n    restitution: 0.6\n")
    right = json.loads(cli("eval-prediction", bags / "a", "--horizons", "1.0", "--json").stdout)
    worse = json.loads(cli("eval-prediction", bags / "a", "--horizons", "1.0", "--json",
                           "--params-file", wrong).stdout)
    assert set(right["horizons"]) == {"1.0"}
    assert worse["horizons"]["1.0"]["median_m"] > 3 * right["horizons"]["1.0"]["median_m"]


def test_bad_params_file_is_a_one_line_error(bags, tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("/**/puck_tracker:\n  ros__parameters:\n    restitution: 1.5\n")
    out = cli("eval-prediction", bags / "a", "--params-file", bad)
    assert out.returncode == 2 and len(out.stderr.strip().splitlines()) == 1
    assert "restitution" in out.stderr


def test_the_reference_filter_on_the_same_bags_gives_its_figures_and_the_ratio(bags, tmp_path):
    """--reference: the challenge-style filter on the same bags and definition (the same valid poses: its
    comparisons differ only by the frames before the tracker's first state); the tracker's median as a ratio
    to its; its own figures change with config/reference_filter.yaml's values given by --params-file."""
    out = cli("eval-prediction", bags / "a", "--reference", "--json")
    assert out.returncode == 0, out.stderr
    report = json.loads(out.stdout)
    reference = report["reference"]
    assert set(reference) == {"filter", "horizons", "rejected_fraction", "reinit_per_s", "nis", "median_ratio"}
    assert reference["rejected_fraction"] == 0.0 and set(reference["nis"]) == {"median", "mean"}
    for key, ours in report["horizons"].items():
        theirs = reference["horizons"][key]
        assert 0 <= theirs["n"] - ours["n"] <= 20
        assert reference["median_ratio"][key] == pytest.approx(ours["median_m"] / theirs["median_m"])
        assert reference["median_ratio"][key] < 1.0  # its damping, rims and spin are not the bags' table's
    tuned = tmp_path / "reference.yaml"
    tuned.write_text("/**/reference_filter:\n  ros__parameters:\n    damping: [0.125, 0.125]\n    rim:\n"
                     "      restitution: 0.96\n")
    closer = json.loads(cli("eval-prediction", bags / "a", "--reference", "--json", "--params-file", tuned).stdout)
    assert closer["horizons"] == report["horizons"]  # the tracker ignores the reference's section
    assert closer["reference"]["horizons"]["1.0"]["median_m"] < 0.8 * reference["horizons"]["1.0"]["median_m"]
    text = cli("eval-prediction", bags / "a", "--reference")
    assert text.returncode == 0 and "tracker / reference median" in text.stdout
    bad = tmp_path / "bad_reference.yaml"
    bad.write_text("/**/reference_filter:\n  ros__parameters:\n    damping: [0.1]\n")
    out = cli("eval-prediction", bags / "a", "--reference", "--params-file", bad)
    assert out.returncode == 2 and out.stderr.strip().splitlines() == [
        f"air-hockey eval-prediction: error: reference filter: {bad}: /reference_filter: parameter 'damping' needs 2 "
        "values, got 1"]  # the file and node that set it (3cd6392)


def test_per_bag_rows_add_up_to_the_session(bags, tmp_path):
    """--per-bag: a row per bag in session order whose frames and comparisons add up to the report's;
    --plot draws them (PNGs written, a file in the way a one-line error)."""
    out = cli("eval-prediction", bags / "a", bags / "b", "--per-bag", "--json")
    assert out.returncode == 0, out.stderr
    report = json.loads(out.stdout)
    rows = report["per_bag"]
    assert [Path(row["bag"]).name for row in rows] == ["a", "b"]
    assert set(rows[0]) == {"bag", "frames", "horizons", "rejected_fraction", "reinit_per_s", "nis_median"}
    assert sum(row["frames"] for row in rows) == report["frames"]
    for key, total in report["horizons"].items():
        assert sum(row["horizons"][key]["n"] for row in rows) == total["n"]
        low, high = sorted(row["horizons"][key]["median_m"] for row in rows)
        assert low <= total["median_m"] <= high
    plots = tmp_path / "plots"
    text = cli("eval-prediction", bags / "a", bags / "b", "--per-bag", "--reference", "--plot", plots)
    assert text.returncode == 0 and "per bag, in session order" in text.stdout
    assert "reference median [mm]" in text.stdout and text.stdout.rstrip().endswith(str(bags / "b"))
    for name in ("eval_per_bag.png", "eval_horizons.png"):
        assert (plots / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and f"wrote {plots / name}" in text.stderr
    in_the_way = tmp_path / "a_file"
    in_the_way.write_text("")
    out = cli("eval-prediction", bags / "a", "--plot", in_the_way)
    assert out.returncode == 2 and out.stderr.strip().splitlines() == [
        f"air-hockey eval-prediction: error: --plot {in_the_way}: cannot create the directory (File exists)"]


def test_human_readable_table(bags):
    out = cli("eval-prediction", bags / "a")
    assert out.returncode == 0
    assert "median [mm]" in out.stdout and "outliers rejected" in out.stdout
    assert "by the predicted path" in out.stdout and "one rim impact" in out.stdout


def test_synth_bag_refuses_to_overwrite(bags):
    out = cli("synth-bag", bags / "a", "--shots", 1)
    assert out.returncode == 2 and "exists already" in out.stderr


def test_synth_bag_from_the_table_simulation(tmp_path):
    out = cli("synth-bag", tmp_path / "sim", "--shots", 2, "--source", "sim")
    assert out.returncode == 0, out.stderr
    assert "truth from the sim" in out.stdout
    report = cli("eval-prediction", tmp_path / "sim", "--json")
    assert report.returncode == 0 and json.loads(report.stdout)["frames"] > 500


def test_synth_bag_from_the_mujoco_table(tmp_path):
    """The MuJoCo table as a user writes its bag; a bad mujoco.* parameter is one line naming it."""
    out = cli("synth-bag", tmp_path / "mj", "--shots", 2, "--source", "mujoco", "--seed", 3)
    assert out.returncode == 0, out.stderr
    assert "truth from the mujoco" in out.stdout
    report = cli("eval-prediction", tmp_path / "mj", "--json")
    assert report.returncode == 0 and json.loads(report.stdout)["frames"] > 300  # a shot that scores ends
    bad = tmp_path / "bad.yaml"
    bad.write_text("/**/synth_bag:\n  ros__parameters:\n    mujoco:\n      rim_solimp: [0.9, 0.95]\n")
    out = cli("synth-bag", tmp_path / "mj2", "--source", "mujoco", "--params-file", bad)
    assert out.returncode == 2 and len(out.stderr.strip().splitlines()) == 1
    assert "mujoco.rim_solimp" in out.stderr and not (tmp_path / "mj2").exists()
    bad.write_text("/**/synth_bag:\n  ros__parameters:\n    mujoco:\n      rim_solimp: [2.0, 0.95, 0.001, 0.5, 2]\n")
    out = cli("synth-bag", tmp_path / "mj2", "--source", "mujoco", "--params-file", bad)  # MuJoCo would clamp it
    assert out.returncode == 2 and len(out.stderr.strip().splitlines()) == 1
    assert "dmin and dmax in (0, 1)" in out.stderr and not (tmp_path / "mj2").exists()


def test_a_pose_with_an_empty_header_stamp_is_left_out_with_a_warning(bags, report_a, tmp_path):
    """One message with a zero stamp among the session's: left in, it stretched the recording's span (the
    re-initialisations per second fell from 0.10 to 0.008 on an eight-shot bag) and, in sysid's and the
    thesis-style columns' preprocessing, asked for a grid from 0 s on. Now left out, with a warning, and
    the figures are the clean bag's but for that frame; sysid reads the bag as well."""
    from rosbags.highlevel import AnyReader

    from air_hockey_agent.bags.types import typestore
    from air_hockey_agent.bags.writer import BagWriter
    odd = tmp_path / "odd"
    with AnyReader([bags / "a"], default_typestore=typestore()) as reader, \
            BagWriter(odd, {"/optitrack/puck": "geometry_msgs/msg/PoseStamped"}) as writer:
        puck = [c for c in reader.connections if c.topic == "/optitrack/puck"]
        for k, (c, log_ns, raw) in enumerate(reader.messages(connections=puck)):
            msg = reader.deserialize(raw, c.msgtype)
            if k == 300:
                msg.header.stamp.sec, msg.header.stamp.nanosec = 0, 0
            writer.write("/optitrack/puck", log_ns, msg)
    out = cli("eval-prediction", odd, "--json")
    assert out.returncode == 0, out.stderr
    assert "1 pose(s) whose header stamp lies more than max_prediction_gap 2 s" in out.stderr
    clean, got = report_a, json.loads(out.stdout)
    assert got["frames"] == clean["frames"] - 1
    assert got["reinit_per_s"] == pytest.approx(clean["reinit_per_s"], rel=0.01)
    assert cli("sysid", odd, "--json", timeout=300).returncode == 0


def test_stamp_glitches_are_isolated_stamps_far_from_both_neighbours():
    from air_hockey_agent.bags.trajectories import stamp_glitches
    steady = [100.0 + k / 120 for k in range(10)]
    assert stamp_glitches(steady, 2.0) == []
    assert stamp_glitches(steady[:4] + [0.0] + steady[5:], 2.0) == [4]
    assert stamp_glitches(steady[:4] + [float("nan")] + steady[5:], 2.0) == [4]
    # a lone frame between two gaps, and time running back (a replay loop), are the stream's own times
    assert stamp_glitches([1.0, 1.01, 5.0, 9.0, 9.01], 2.0) == []
    assert stamp_glitches([1.0, 1.01, 1.02, 0.5, 0.51, 0.52], 2.0) == []

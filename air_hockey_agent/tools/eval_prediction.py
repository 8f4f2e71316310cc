"""``air-hockey eval-prediction BAG...``: prediction accuracy of the puck tracker on recorded bags.

Each bag (rosbag2, sqlite3 or MCAP, or a ROS 1 .bag; read with rosbags, no ROS needed) is replayed through the tracker's
own filter code offline (:mod:`air_hockey_agent.core.estimation.evaluation`, thesis sec. 4.3): from every
frame at which the filter has a state the position is predicted ``h`` seconds ahead and compared with the
valid pose at ``t + h``, fused by the filter or not (marker glitches excepted), so rejecting frames does
not make a filter look better. Reported per horizon: mean, median and 95th percentile of the error [m]
over all comparisons and their number; frames, lost frames, rejected outliers, poses off the table (JSON
"off_table_poses": beyond ``outside_table_margin``, dropped before the gate: a puck carried off or in a
goal, not a measurement the gate rejected), the rejected fraction of the poses on the table,
re-initialisations per second and the normalised innovation squared (NIS), also by regime (rest, flight,
impact). Where the error comes from: the median and mean per horizon by the predicted path
(JSON "by_path"): started at rest (a later motion is a hit no model foresees), ended in a goal (the model
holds a puck a radius past the goal line's face; a real one may meet a post or the goal's sides), or
through no, one, or two and more rim impacts.

The bags are one session on one table, in the order given (a directory's bags in path order), as for a
tracker node that keeps running: what the tracker learns online of the table (``rim_adaptation``,
``acceleration_adaptation`` in ``config/tracker.yaml``) carries from one bag to the next, and every
prediction uses what was learned up to its frame. Reported: JSON "rim_law" (the impacts learned from, the
scales of the configured rim law and the rim parameters they give), "table_acceleration" (free-flight
windows, value and std [m/s^2]), "spin_damping", "impact_delay", "marker_offset" (the mocap pivot's
offset from the disc's centre: windows, value and std [m]), "marker_noise" (``noise_adaptation``: windows
collected and used, the position noise's std at rest [m] and per m/s [s], the angle's [rad]) and
"process_noise" (``process_noise_adaptation``: blocks of free-flight frames learned from, the scale of the
configured velocity terms and the acceleration std they stand for [m/s^2]); a ``--params-file`` with
``enabled: false`` under both table learnings evaluates the configured physics alone.

And the thesis's own columns (tables 5.2-5.4; JSON "thesis_style"), computed as ``air-hockey sysid``
reports them, of the configured physics (nothing learned): the bags preprocessed into cut trajectories (thesis sec. 4.5.1,
``config/sysid.yaml``), per horizon the loss (mean error over all their comparisons) and the min and
median over trajectories of each trajectory's mean error. A bag that cannot be used gives a one-line
error on stderr and exit code 2; the other bags are still evaluated (and nothing is printed on stdout when
none could be).

With ``--reference``, the reference filter (``config/reference_filter.yaml``: a linear Kalman filter built as
the Air Hockey Challenge baseline's tracker is described in REFERENCE_FACTS sec. 1, with its identified
constants; :mod:`air_hockey_agent.core.estimation.reference_filter`) is evaluated on the same bags, on the
same definition and against the same valid poses, and each horizon's median error is also given as the
tracker's ratio to the reference's (JSON "reference", its "median_ratio"; issue #13's target: at most 0.7).
With ``--per-bag``, each bag's own figures follow in session order (JSON "per_bag": bag, frames, median and
n per horizon, rejected fraction, re-initialisations per second, NIS median, and with ``--reference`` the
reference's medians): which bags are hard, and how the session's first bags fare while the table is learned.
``--plot DIR`` draws them: each bag's medians in session order and the errors against the horizon, with the
reference's when it ran (:mod:`.eval_plots`).
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from air_hockey_agent.bags.reader import BagError
from air_hockey_agent.core.estimation.ekf import PuckEKF
from air_hockey_agent.core.estimation.evaluation import EvaluationTotals, evaluate_stream
from air_hockey_agent.core.estimation.reference_filter import ReferenceFilter
from air_hockey_agent.core.estimation.table_learning import rims_off_text
from air_hockey_agent.bags.trajectories import bag_measurements, find_bags
from air_hockey_agent.core.identification.preprocess import preprocess, push_limits
from air_hockey_agent.params import ParameterFileError, ParameterValueError, check_files_read
from air_hockey_agent.reference_params import load_reference_params
from air_hockey_agent.sysid_params import load_sysid_params
from air_hockey_agent.tools.json_output import json_text
from air_hockey_agent.tracker_params import trajectory_loss_params, load_tracker_params
from air_hockey_agent.tools.argtypes import number
from air_hockey_agent.tools.eval_report import format_table
from air_hockey_agent.tools.progress import Progress
from air_hockey_agent.tools.recordings import add_pose_topic_arguments

PROG = "air-hockey eval-prediction"


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser("eval-prediction", help="prediction error of the puck tracker on bags",
                                   description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("bags", nargs="+", type=Path, metavar="BAG",
                        help="rosbag2 bags (directory, or its .mcap/.db3 file) or ROS 1 .bag files, or directories "
                             "of bags (searched, in path order)")
    add_pose_topic_arguments(parser)
    parser.add_argument("--horizons", type=number(0.0, low_open=True), nargs="+", default=[0.5, 1.0, 1.5], metavar="SECONDS",
                        help="prediction horizons [s] (default 0.5 1.0 1.5)")
    parser.add_argument("--params-file", type=Path, action="append", default=[],
                        help="tracker parameter YAML (as for puck_tracker --params-file; a "
                             "/**/reference_filter section for --reference); may be repeated")
    parser.add_argument("--reference", action="store_true",
                        help="also evaluate the reference filter (config/reference_filter.yaml: the challenge "
                             "baseline's tracker as REFERENCE_FACTS describes it) and give the medians' ratio")
    parser.add_argument("--per-bag", action="store_true",
                        help="also each bag's figures, in session order (median per horizon, rejected, "
                             "re-initialisations per second, NIS median)")
    parser.add_argument("--plot", type=Path, default=None, metavar="DIR",
                        help="write eval_per_bag.png and eval_horizons.png into DIR (created)")
    parser.add_argument("--json", action="store_true", help="print exactly one JSON object")
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    made = [] if args.plot is None else [d for d in (args.plot, *args.plot.parents) if not d.exists()]
    try:
        return _run(args)
    finally:
        for directory in made:  # made for --plot: no bag read, or interrupted, leaves no empty directory behind
            if not directory.is_dir() or any(directory.iterdir()):
                break
            directory.rmdir()


def _run(args: argparse.Namespace) -> int:
    loaded = _load_parameters(args)
    if loaded is None:
        return 2
    params, preprocessing, reference = loaded
    ekf = PuckEKF.from_params(params)
    totals = EvaluationTotals(tuple(args.horizons), rest_speed=params["regime_rest_speed"])
    reference_totals = EvaluationTotals(tuple(args.horizons))
    cut: list = []  # the bags' trajectories cut as sysid cuts them (thesis sec. 4.5.1)
    per_bag: list = []  # each bag's own figures (its rows of --per-bag)
    bags, missing = find_bags(args.bags)  # a directory is searched for bags, as sysid and plot do
    for message in missing:
        print(f"{PROG}: error: {message}", file=sys.stderr)
    failed = len(missing)
    progress = Progress("eval-prediction", quiet=True)  # with --json: a bar on a terminal only
    limits = push_limits(ekf.model.table, preprocessing["push_rim_margin"])  # where preprocessing judges pushes
    for done, bag in enumerate(bags, 1):
        try:
            records, measurements, warning, _ = bag_measurements(bag, args.topic, args.frame, args.table_frame, params)
        except BagError as exc:
            print(f"{PROG}: error: {exc}", file=sys.stderr)
            failed += 1
            continue
        if warning:
            print(f"{PROG}: warning: {bag}: {warning}", file=sys.stderr)
        frames = [(r.stamp, m) for r, m in zip(records, measurements)]
        per_bag.append(_evaluate_bag(bag, frames, ekf, totals, reference, reference_totals))
        cut += preprocess([r.stamp for r in records], measurements, ekf.settings.dt, preprocessing,
                          params["glitch_speed"], limits).trajectories  # as sysid cuts them, from the poses read once
        if not args.json:
            print(f"{bag}: {len(frames)} frames", file=sys.stderr)
        else:
            progress(done, len(bags), bag.name)
    if not totals.recordings:  # each bag's one-line error said why; an all-empty report would say nothing
        return 2
    summary = _summary(ekf, totals, params, cut, args.horizons)
    if reference is not None:
        summary["reference"] = reference_report(reference_totals.summary(), summary["horizons"])
    if args.per_bag:
        summary["per_bag"] = per_bag
    if args.plot is not None:
        from air_hockey_agent.tools.eval_plots import write_eval_plots
        for path in write_eval_plots(args.plot, summary, per_bag):
            print(f"wrote {path}", file=sys.stderr)
    print(json_text(summary) if args.json else format_table(summary))
    return 2 if failed else 0


def _evaluate_bag(bag: Path, frames: list, ekf: PuckEKF, totals: EvaluationTotals, reference,
                  reference_totals: EvaluationTotals) -> dict:
    """Evaluate one bag's frames (the tracker, and the reference filter unless None) into the session's
    totals; returns the bag's own figures: its --per-bag row."""
    own = totals.empty_like()
    evaluate_stream(ekf, frames, own)
    totals.absorb(own)
    row = _bag_row(str(bag), own.summary())
    if reference is not None:
        theirs = reference_totals.empty_like()
        evaluate_stream(reference, frames, theirs)
        reference_totals.absorb(theirs)
        row["reference_horizons"] = _medians(theirs.summary())
    return row


def _bag_row(bag: str, summary: dict) -> dict:
    """A bag's row of --per-bag: frames, median and n per horizon, rejected fraction, re-initialisations
    per second and NIS median."""
    return {"bag": bag, "frames": summary["frames"], "horizons": _medians(summary),
            "rejected_fraction": summary["rejected_fraction"], "reinit_per_s": summary["reinit_per_s"],
            "nis_median": summary["nis"]["median"]}


def _medians(summary: dict) -> dict:
    """Median [m] and n per horizon of an evaluation summary."""
    return {key: {"median_m": h["median_m"], "n": h["n"]} for key, h in summary["horizons"].items()}


def _load_parameters(args: argparse.Namespace) -> tuple | None:
    """(tracker parameters, preprocessing parameters, the reference filter or None), or None after a
    one-line error."""
    if any(h <= 0.0 for h in args.horizons):
        print(f"{PROG}: error: --horizons must be positive, got {args.horizons}", file=sys.stderr)
        return None
    if args.plot is not None:
        try:
            args.plot.mkdir(parents=True, exist_ok=True)
        except OSError as exc:  # a file in the way, or no permission: before any bag is read
            print(f"{PROG}: error: --plot {args.plot}: cannot create the directory ({exc.strerror})",
                  file=sys.stderr)
            return None
    try:
        params = load_tracker_params(args.params_file)
        preprocessing = load_sysid_params(args.params_file)
        reference_section = ("reference_filter",) if args.reference else ()
        check_files_read(args.params_file, ("puck_tracker", "sysid", *reference_section))
    except (ParameterFileError, ParameterValueError) as exc:
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return None
    try:
        reference = (ReferenceFilter.from_params(load_reference_params(args.params_file), params)
                     if args.reference else None)
    except (ParameterFileError, ParameterValueError) as exc:  # say whose: the tracker has a damping too
        print(f"{PROG}: error: reference filter: {exc}", file=sys.stderr)
        return None
    return params, preprocessing, reference


def _summary(ekf: PuckEKF, totals: EvaluationTotals, params: dict, cut: list, horizons) -> dict:
    """The report: the totals' figures, what was learned online (warning of rims off their lines) and the
    thesis-style columns over the ``cut`` trajectories."""
    summary = totals.summary()
    summary.update(ekf.learning_report())
    delay = summary.get("impact_delay")
    if delay is not None and delay["rims_off"]:
        print(f"{PROG}: warning: {rims_off_text(delay['rim_offsets'], delay['rims_off'])}", file=sys.stderr)
    summary["thesis_style"] = thesis_style(params, cut, horizons)
    return summary


def thesis_style(params: dict, trajectories: list, horizons) -> dict:
    """The thesis's trajectory-level columns per horizon, as sysid reports them (the configured physics,
    nothing learned online, no hand regime: :func:`trajectory_loss_params`): ``{"trajectories": n,
    "<h>": {"loss_m", "min_m", "median_m", "n"}}`` over cut ``trajectories`` (None without any)."""
    from air_hockey_agent.core.identification.sysid import position_loss_reports
    reports = position_loss_reports(trajectory_loss_params(params), trajectories, horizons)
    out: dict = {"trajectories": len(trajectories)}
    for key, r in reports.items():
        out[key] = ({"loss_m": r.loss, "min_m": r.min, "median_m": r.median, "n": r.comparisons} if r.comparisons
                    else {"loss_m": None, "min_m": None, "median_m": None, "n": 0})
    return out


def reference_report(reference: dict, ours: dict) -> dict:
    """The reference filter's figures (per horizon, rejected fraction, re-initialisations per second, NIS)
    and per horizon the ratio of the tracker's median error to the reference's (None where either has none)."""
    ratio = {key: (ours[key]["median_m"] / r["median_m"] if ours[key]["n"] and r["n"] and r["median_m"] > 0.0
                   else None) for key, r in reference["horizons"].items()}
    return {"filter": "config/reference_filter.yaml (the challenge baseline's tracker, REFERENCE_FACTS 1)",
            "horizons": reference["horizons"], "rejected_fraction": reference["rejected_fraction"],
            "reinit_per_s": reference["reinit_per_s"], "nis": reference["nis"], "median_ratio": ratio}

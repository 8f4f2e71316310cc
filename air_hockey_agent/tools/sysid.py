"""``air-hockey sysid BAG_DIR...``: identify the puck model's physical parameters from recordings.

Bags (or directories holding bags) are preprocessed into trajectories (thesis sec. 4.5.1) and split into
training and validation sets by trajectory (``--split``), or, with ``--validate BAG...``, all of them
train and the trajectories of the bags given to ``--validate`` validate (issue #13's protocol: identified
on 100 of the lab's bags, validated on the other 28). Printed: the prediction loss at ``--horizon`` before
and after on both sets (thesis table 5.2/5.3 columns: loss, min, median) and the objective that was
minimised. ``--out`` writes the identified parameters as a parameter YAML that ``puck_tracker --ros-args
--params-file`` and ``air-hockey eval-prediction --params-file`` accept; the split identification's also
sets the online learning's priors from its own weight (the rim law worth the impacts it was fitted to, the
flight's parameters with their standard errors): the configured priors are a stranger's table's.

``--method split`` (the default, issue #13) fits each part of the model where it alone acts, without
the filter and in about a second: damping, surface friction and the table acceleration by least
squares on local fits of the free flight, then the restitution law and the rim's tangential law on the
velocities before and after each rim impact (core/identification/split.py); its objectives are the
fits' own. Where the paths before and after the impacts meet gives a compliant rim's delay and where
the rims are (``table_geometry``): rims found millimetres from the model's move ``mocap_table_pose`` and
``table.length`` / ``table.width`` (written with ``--out``), and the fits run again on the moved rims.

``--method hebo`` is the thesis's identification (sec. 3.3, 4.3): HEBO minimises the prediction loss
at ``--horizon`` on the training set over the table 4.1 bounds (``config/sysid.yaml``), starting from
the tracker's current parameters and finishing with a local polish; with ``--cross-validate`` it is
repeated at 0.5, 1.0 and 1.5 s and each result validated at every horizon (table 5.4).
"""
from __future__ import annotations

import argparse
import contextlib
import math
import multiprocessing
import os
import sys
import time
from datetime import datetime, timezone
from pathlib import Path

from air_hockey_agent.bags.trajectories import LoadedTrajectories, split_train_validation
from air_hockey_agent.core.identification.local_fit import beyond_noise
from air_hockey_agent.core.identification.rim_lines import recentred
from air_hockey_agent.core.identification.split import SPLIT_IDENTIFIABLE, identify_split, learning_priors
from air_hockey_agent.core.identification.sysid import (IDENTIFIABLE, LOSSES, PHYSICAL, combine, identify,
                                                      loss_report, nis_median, on_bounds, partial_loss, polish)
from air_hockey_agent.core.table import WALL_NAMES
from air_hockey_agent.sysid_params import bounds
from air_hockey_agent.tools.json_output import json_text
from air_hockey_agent.tracker_params import TRACKER_PARAMS, trajectory_loss_params
from air_hockey_agent.tools.progress import Progress
from air_hockey_agent.tools.recordings import (ToolError, add_recording_arguments, load_recordings, read_trajectories,
                                              nothing_read, report_error)
from air_hockey_agent.tools.sysid_report import (format_report, geometry_warnings, objective_text, rims_off,
                                                 write_params_yaml)
from air_hockey_agent.tools.argtypes import count, number, seed

PROG = "air-hockey sysid"
HORIZONS = (0.5, 1.0, 1.5)
METHODS = ("hebo", "split")
DEFAULT_SPLIT = 0.9  # [-] training share of the trajectories without --validate (thesis sec. 4.5: 94 / 10)
HEBO_DEFAULTS = {"loss": "position", "iterations": 50, "batch": 5}  # the thesis's runs (sec. 4.3: 50 iterations of 5 suggestions)


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser("sysid", help="identify the puck model's physical parameters (split fits; HEBO)",
                                   description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_recording_arguments(parser)
    parser.add_argument("--method", choices=METHODS, default="split",
                        help="split: least squares on free flight and on rim impacts, no filter, seconds "
                             "(default); hebo: the thesis's search on the filter's prediction loss (minutes)")
    parser.add_argument("--loss", choices=LOSSES, help="--method hebo: its objective (thesis sec. 4.3.1; default "
                        "position)")
    parser.add_argument("--horizon", type=float, choices=HORIZONS, default=1.0, help="prediction horizon [s]")
    parser.add_argument("--iterations", type=count(1), help=f"--method hebo: iterations (default {HEBO_DEFAULTS['iterations']})")
    parser.add_argument("--batch", type=count(1), help=f"--method hebo: suggestions per iteration (default {HEBO_DEFAULTS['batch']})")
    parser.add_argument("--split", type=number(0.0, 1.0, low_open=True, high_open=True),
                        help=f"training fraction of the trajectories (default {DEFAULT_SPLIT})")
    parser.add_argument("--validate", nargs="+", type=Path, metavar="BAG_DIR",
                        help="bags (or directories of bags) whose trajectories are the validation set; every "
                             "trajectory of the BAG_DIRs then trains (instead of --split)")
    parser.add_argument("--seed", type=seed, default=0, help="seed of the split and of HEBO")
    parser.add_argument("--cross-validate", action="store_true", help="learn at each horizon, validate at each")
    parser.add_argument("--identify", nargs="+", choices=SPLIT_IDENTIFIABLE, metavar="NAME",
                        help="parameters to identify (default: hebo the thesis's four, split all thirteen; "
                             "table_acceleration, spin_damping, impact_delay, table_geometry (where the rims "
                             "are: mocap_table_pose's x, y, table.length, table.width) and marker_offset (the mocap "
                             "pivot off the disc's centre) only with --method split; "
                             "also restitution_slope, the rims' loss with impact speed); choices: "
                             + ", ".join(SPLIT_IDENTIFIABLE))
    parser.add_argument("--polish", type=count(0), metavar="EVALUATIONS",
                        help="then a Nelder-Mead polish of the scalar parameters on the prediction loss at "
                             "--horizon, this many evaluations (default: split 0, none; hebo "
                             "polish_evaluations in config/sysid.yaml)")
    parser.add_argument("--plot", type=Path, metavar="DIR",
                        help="--method split: write split_flight.png, split_impacts.png and split_tangential.png "
                             "(the fits) to DIR")
    parser.add_argument("--out", type=Path, help="write the identified parameters to this parameter YAML (split: "
                        "with the online learning's priors from the identification's own weight)")
    parser.add_argument("--json", action="store_true", help="print exactly one JSON object")
    parser.set_defaults(run=run)


# --- parallel objective (processes forked once, trajectories inherited) ---------------------------
_WORK: dict = {}


def _partial(job: tuple) -> object:
    """One candidate on one share of the training trajectories (runs in a worker process)."""
    candidate, horizon, share, shares = job
    w = _WORK
    return partial_loss({**w["tracker"], **candidate}, w["trajectories"][share::shares], horizon, w["loss"],
                        w["stride"])


@contextlib.contextmanager
def _worker_pool(settings: dict):
    """(pool or None, workers): ``workers`` forked processes (they inherit _WORK), closed afterwards."""
    workers = min(settings["workers"], os.cpu_count() or 1)
    pool = multiprocessing.get_context("fork").Pool(workers) if workers > 1 else None
    try:
        yield pool, workers
    finally:
        if pool is not None:
            pool.close()
            pool.join()


class _Objective:
    """Evaluates a batch of candidates; each candidate's trajectories are split over the workers, so
    every process is busy whatever the batch size (the polish evaluates one candidate at a time)."""

    def __init__(self, pool, workers: int, horizon: float, loss: str) -> None:
        self.pool, self.workers, self.horizon, self.loss = pool, workers, horizon, loss

    def __call__(self, candidates: list[dict]) -> list[float]:
        jobs = [(c, self.horizon, share, self.workers) for c in candidates for share in range(self.workers)]
        parts = self.pool.map(_partial, jobs) if self.pool else [_partial(j) for j in jobs]
        return [combine(parts[i * self.workers:(i + 1) * self.workers], self.loss).objective
                for i in range(len(candidates))]


# split's fits the polish leaves alone: the table acceleration (two axes, fitted from every window), the
# spin's decay (the position loss hardly depends on it) and the marker offset (two axes, from the windows)
UNPOLISHED = ("table_acceleration", "spin_damping", "marker_offset")


def _chosen_names(args: argparse.Namespace) -> tuple[list[str], str]:
    """Parameters to identify (as given, without repeats) and a one-line error ('' when fine)."""
    if args.identify is None:
        return list(PHYSICAL if args.method == "hebo" else SPLIT_IDENTIFIABLE), ""
    names = list(dict.fromkeys(args.identify))
    split_only = [n for n in names if n not in IDENTIFIABLE]
    if args.method == "hebo" and split_only:
        return names, f"--identify {split_only[0]}: only --method split identifies it"
    return names, ""


def run(args: argparse.Namespace) -> int:
    problem = _argument_problem(args)
    if problem:
        return report_error(PROG, problem)
    try:
        recordings = load_recordings(PROG, args, minimum=1 if args.validate else 2)
        held_out = _validation_recordings(args, recordings) if args.validate else None
    except ToolError as exc:
        return report_error(PROG, exc)
    tracker, settings, loaded = recordings.tracker, recordings.settings, recordings.loaded
    others = () if held_out is None else (held_out,)  # the validation bags, read apart from the training ones
    tracker = trajectory_loss_params(tracker)  # the law itself is identified: learning it online would rescale each candidate
    train, validation = _train_and_validation(args, loaded, held_out)
    if not args.json:
        print(f"{len(loaded.trajectories)} trajectories from {loaded.bags} bag(s) ({loaded.frozen} frozen frames "
              f"interpolated, {loaded.pushes} ended where a hand or mallet took the puck): {len(train)} for "
              f"training, {len(validation)} for validation"
              + (f" (from the {held_out.bags} bag(s) of --validate)" if held_out is not None else ""), flush=True)
        if args.method == "hebo":
            print("starting HEBO (loading torch takes several seconds) ...", flush=True)
    if args.method == "split":
        try:
            result = _identify_split(args, tracker, settings, train, validation,
                                     loaded.common_table_pose(*others))
        except ValueError as exc:
            return report_error(PROG, f"--method split: {exc} (in {len(train)} training trajectories)")
    else:
        calibration = _calibration_warning(args.loss, tracker, settings, train)
        if calibration:
            print(f"{PROG}: warning: {calibration}", file=sys.stderr)
        result = _identify_all(args, tracker, settings, train, validation)
    bad_bags = sum(len(part.errors) for part in (loaded, *others))
    result.update({"train_trajectories": len(train), "validation_trajectories": len(validation),
                   "bags": loaded.bags, "bad_bags": bad_bags,
                   "validation_bags": held_out.bags if held_out is not None else None})
    if args.out is not None:
        write_params_yaml(args.out, {**result["identified"], **result.get("table_geometry", {}).get("parameters", {})},
                          result["summary_line"], result.get("learning_priors", {}))
    result.pop("summary_line")
    _print_warnings(result, settings)
    print(json_text(result) if args.json else format_report(result, args.out))
    return 2 if bad_bags else 0


def _argument_problem(args: argparse.Namespace) -> str:
    """The first problem with the arguments as a one-line message ('' when none); fills in the HEBO
    defaults and the chosen names (``args.identify``)."""
    names, problem = _chosen_names(args)
    hebo_only = [f"--{n}" for n in HEBO_DEFAULTS if getattr(args, n) is not None]
    if not problem and args.method == "split" and hebo_only:
        problem = f"{hebo_only[0]}: only with --method hebo (the default method, split, fits without a search)"
    if not problem and args.validate and args.split is not None:
        problem = "--split: not with --validate (the bags given to --validate are the validation set)"
    if not problem and args.method == "split" and args.cross_validate:
        problem = "--cross-validate: only with --method hebo (split does not learn at a horizon)"
    for name, value in HEBO_DEFAULTS.items():
        if getattr(args, name) is None:
            setattr(args, name, value)
    if not problem and args.plot is not None and args.method != "split":
        problem = "--plot: only with --method split (`air-hockey plot` shows HEBO's predictions)"
    if not problem and args.plot is not None and args.plot.exists() and not args.plot.is_dir():
        problem = f"--plot {args.plot} is a file; it names the directory the PNGs are written to"
    if not problem and args.polish and all(n in UNPOLISHED for n in names):
        problem = (f"--polish: nothing to polish (--identify {' '.join(names)}: "
                   f"{'it stays' if len(names) == 1 else 'they stay'} as fitted)")
    args.identify = names
    if not problem and args.out is not None and args.out.is_dir():
        problem = f"--out {args.out} is a directory"
    if not problem and args.out is not None and args.out.exists():
        problem = f"--out {args.out}: exists already, not overwriting"
    return problem


def _train_and_validation(args: argparse.Namespace, loaded: LoadedTrajectories,
                          held_out: LoadedTrajectories | None) -> tuple[list, list]:
    """The training and validation trajectories: ``loaded``'s split by ``--split`` (shuffled by ``--seed``),
    or all of ``loaded``'s and the ``--validate`` bags' ``held_out``."""
    if held_out is not None:
        return list(loaded.trajectories), list(held_out.trajectories)
    train_idx, val_idx = split_train_validation(len(loaded.trajectories), args.split or DEFAULT_SPLIT, args.seed)
    return [loaded.trajectories[i] for i in train_idx], [loaded.trajectories[i] for i in val_idx]


def _print_warnings(result: dict, settings: dict) -> None:
    """The identification's warnings on stderr: values on a search bound, rims off their lines, the table's
    geometry."""
    for phrase in result["on_bounds"]:
        print(f"{PROG}: warning: {phrase}: the search ended on the edge of its box (config/sysid.yaml bounds): "
              f"the effect may be absent, or the model or the box may not fit these recordings", file=sys.stderr)
    identify = "" if "table_geometry" in result else ", or identify them (--identify table_geometry)"
    for phrase in rims_off(result, settings["split.rim_offset_warning"], settings["split.significance"]):
        print(f"{PROG}: warning: {phrase}: check table.length / table.width (config/table.yaml) and "
              f"mocap_table_pose{identify}", file=sys.stderr)
    for phrase in geometry_warnings(result.get("table_geometry"), settings):
        print(f"{PROG}: warning: {phrase}", file=sys.stderr)


def _validation_recordings(args: argparse.Namespace, recordings) -> LoadedTrajectories:
    """The trajectories of the ``--validate`` bags, read and cut as the training bags (their bad bags printed
    as one-line errors); raises ToolError when none is usable or a bag also trains."""
    settings = recordings.settings
    held_out = read_trajectories(PROG, args, args.validate, recordings.tracker, settings, label="--validate: ")
    both = sorted(_bags_of(held_out) & _bags_of(recordings.loaded))
    if both:
        raise ToolError(f"--validate {both[0]}: also a training bag (BAG_DIR); a bag validates or trains, not both")
    if not held_out.trajectories:
        nothing_read(held_out)
        raise ToolError(f"--validate: no usable trajectory in {held_out.bags} bag(s){held_out.why_none(settings)}")
    return held_out


def _bags_of(loaded: LoadedTrajectories) -> set[str]:
    """The resolved paths of the bags ``loaded``'s trajectories came from."""
    return {str(Path(bag).resolve()) for bag in loaded.sources}


def _calibration_warning(loss: str, tracker: dict, settings: dict, train: list) -> str:
    """Why the log-likelihood loss should not be trusted here ('' when it may, or for the position loss)."""
    if loss != "loglik":
        return ""
    nis = nis_median(tracker, train)
    low, high = settings["calibrated_nis"]
    if nis is not None and low <= nis <= high:
        return ""
    shown = "unknown (no gated frame)" if nis is None else f"{nis:.2f}"
    return (f"--loss loglik assumes a calibrated filter, but its median NIS on the training set is {shown} "
            f"(calibrated: {low:g}-{high:g}, config/sysid.yaml; consistent 2.37): a miscalibrated filter's "
            f"likelihood rewards parameters for the covariance they give, not the prediction; --loss position "
            f"does not depend on it")


def _identify_split(args, tracker: dict, settings: dict, train: list, validation: list,
                    table_pose: tuple | None) -> dict:
    """--method split: the fits, then the same before/after reports as HEBO's (after a move of the rims,
    table_geometry, on the trajectories measured from the moved table frame). ``table_pose``: the one table
    pose every bag's poses were read through (mocap_table_pose, or the bags' common transform to
    --table-frame), which a moved table centre or yaw corrects; None: only the table's size can move."""
    names = args.identify
    start = time.monotonic()
    box = bounds(settings, names)
    posed = table_pose is not None
    base = {**tracker, "mocap_table_pose": list(table_pose)} if posed else tracker
    split = identify_split(train, base, settings, names, box, move_centre=posed)
    chosen = dict(split.identified)
    geometry = split.geometry or {}
    moved = {**tracker, **geometry}
    lines = split.rim_lines
    centre, yaw = (lines.centre(), lines.yaw()) if lines is not None else ((0.0, 0.0), 0.0)
    train_after, validation_after = ([recentred(t, centre, yaw) for t in trajs] for trajs in (train, validation))
    plots = []
    if args.plot is not None:
        from air_hockey_agent.tools.split_plots import write_split_plots
        plots = [str(p) for p in write_split_plots(args.plot, split)]
    polished = _polish_split(args, moved, settings, train_after, chosen) if args.polish else None
    objective = _split_objective(split, settings, names)
    std = dict(split.std)
    if polished is not None:
        objective["polish"] = polished
        chosen.update(polished["values"])
        for name in polished["values"]:  # the fits' errors are not the polished values'
            std.pop(name, None)
    absent = _absent(split, chosen, box, settings["split.significance"])
    edges = on_bounds(_flat(chosen), _flat_bounds({n: b for n, b in box.items() if n in chosen}),
                      settings["bound_margin"])
    result = {"method": "split", "horizon": args.horizon, "significance": settings["split.significance"],
              "initial": {n: tracker[n] for n in names if n in tracker},
              "identified": chosen, "std": std, "plots": plots, "seconds": round(time.monotonic() - start, 1),
              "objective": objective, "before": {}, "after": {},
              "on_bounds": [phrase for phrase in edges if phrase.split()[0] not in absent]}
    if split.rim_lines is not None:
        result["table_geometry"] = _geometry_report(split, base, posed)
        result["table_geometry"]["read_without_table_frame"] = bool(args.table_frame) and "mocap_table_pose" in geometry
    kept = [n for n in chosen if polished is None or n not in polished["values"]]
    result["learning_priors"] = learning_priors(split, kept, std, {s.name: (s.low, s.high) for s in TRACKER_PARAMS})
    result["before"] = _loss_reports(tracker, train, validation, args.horizon)
    result["after"] = _loss_reports({**moved, **chosen}, train_after, validation_after, args.horizon)
    result["seconds_with_reports"] = round(time.monotonic() - start, 1)
    result["summary_line"] = (f"identified by `air-hockey sysid --method split` ({len(train)} training "
                              f"trajectories) on {datetime.now(timezone.utc).strftime('%Y-%m-%d %H:%M UTC')}")
    return result


def _split_objective(split, settings: dict, names) -> dict:
    """What the split fits minimised, on the training set, for the report's ``objective``: the flight law's
    windows (and the field check's and the spin decay's), the impacts' (and the rim delay's)."""
    objective = {"set": "train"}
    if split.flight is not None:
        f = split.flight
        objective["flight"] = {"windows": f.windows, "dropped": f.dropped, "weighted_squared_residual": f.objective,
                               "rms_acceleration_m_s2": f.rms_acceleration}
        if split.field is not None:
            c = split.field
            objective["flight"]["field"] = {"cells": c.cells, "largest_m_s2": c.largest, "f_statistic": c.f_statistic,
                                            "p_value": c.p_value,
                                            "varies": c.p_value < settings["split.field_significance"]}
        if split.spin is not None:
            s = split.spin
            objective["flight"]["spin_decay"] = {"rate_per_s": s.rate, "std_per_s": s.std, "windows": s.windows,
                                                 "dropped": s.dropped, "rms_spin_rad_s": s.rms_spin}
    if split.impacts is not None:
        i = split.impacts
        objective["impacts"] = {"impacts": i.impacts, "dropped": i.dropped, "rms_normal_speed_m_s": i.rms_normal,
                                "rms_tangential_m_s": i.rms_tangential}
        if split.delay is not None:
            d = split.delay
            objective["impacts"]["delay"] = {"fitted_s": d.fitted, "std_s": d.std, "impacts": d.impacts,
                                             "value_s": d.value, "identified": "impact_delay" in names,
                                             "offsets_m": {WALL_NAMES[w]: o for w, (o, _) in d.offsets.items()},
                                             "offset_std_m": {WALL_NAMES[w]: s for w, (_, s) in d.offsets.items()}}
    return objective


def _absent(split, chosen: dict, box: dict, significance: float) -> set[str]:
    """Rates whose lower bound is 0 and whose fit lies within ``significance`` standard errors of it: an
    effect that is not there (the spin's decay, a compliant rim's delay; their own report lines say so),
    not a search that ended on the edge of its box."""
    fits = {"spin_damping": (split.spin.rate, split.spin.std) if split.spin is not None else None,
            "impact_delay": (split.delay.fitted, split.delay.std) if split.delay is not None else None}
    return {name for name, fit in fits.items()
            if fit is not None and name in chosen and box[name][0] == 0.0
            and not beyond_noise(fit[0], fit[1], significance)}


def _polish_split(args, tracker: dict, settings: dict, train: list, split_values: dict) -> dict:
    """Nelder-Mead on the training set's position loss at --horizon from the split result, over its
    parameters but ``UNPOLISHED`` (they stay as fitted)."""
    names = [n for n in split_values if n not in UNPOLISHED]
    box = bounds(settings, names)
    start = {n: float(min(max(split_values[n], box[n][0]), box[n][1])) for n in names}
    _WORK.update(tracker={**tracker, **split_values}, trajectories=train, loss="position", stride=settings["stride"])
    bar = Progress(f"sysid split polish @ {args.horizon} s", args.json)
    with _worker_pool(settings) as (pool, workers):
        objective = _Objective(pool, workers, args.horizon, "position")
        first = objective([start])[0]
        history = [(start, first)]
        best, value = polish(objective, box, start, first, args.polish, history,
                             lambda done, total, best: bar(done, total, f"evaluations, best {best * 1e3:.2f} mm"),
                             args.polish)
    return {"evaluations": len(history), "horizon": args.horizon, "stride": settings["stride"],
            "initial_m": first, "final_m": value, "values": best}


def _loss_reports(tracker: dict, train: list, validation: list, horizon: float) -> dict:
    """The loss reports (thesis table 5.2/5.3 columns) of ``tracker``'s parameters on both sets, every frame."""
    return {name: loss_report(tracker, trajs, horizon).as_dict() for name, trajs in (("train", train),
                                                                                     ("validation", validation))}


def _before_after(tracker: dict, identified: dict, train: list, validation: list, horizon: float) -> tuple:
    """The loss reports of the tracker's and the identified parameters on the same trajectories."""
    return (_loss_reports(tracker, train, validation, horizon),
            _loss_reports({**tracker, **identified}, train, validation, horizon))


def _geometry_report(split, tracker: dict, posed: bool) -> dict:
    """table_geometry's part of the result: the rims' centre and size changes found (first pass, against the
    configured rims), which were moved, and the tracker parameters that move them."""
    lines = split.rim_lines
    first = split.first_delay
    metres = [n for n in lines.values if n != "yaw"]
    known = {n: None if math.isnan(v) else v for n, v in lines.values.items()}  # null in JSON: a rim not met
    errors = {n: None if math.isnan(v) else v for n, v in lines.std.items()}
    return {"values_m": {n: known[n] for n in metres}, "std_m": {n: errors[n] for n in metres},
            "yaw_rad": known["yaw"], "yaw_std_rad": errors["yaw"], "taken": lines.taken,
            "beyond": lines.beyond,
            "centre_movable": posed, "parameters": dict(split.geometry or {}),
            "initial": {n: tracker[n] for n in ("mocap_table_pose", "table.length", "table.width")},
            "first_offsets_m": {WALL_NAMES[w]: o for w, (o, _) in first.offsets.items()},
            "first_offset_std_m": {WALL_NAMES[w]: e for w, (_, e) in first.offsets.items()}}


def _flat(values: dict) -> dict:
    """Scalars per name, the table acceleration's axes as table_acceleration_x / _y."""
    out = {}
    for name, value in values.items():
        if isinstance(value, list):
            out.update({f"{name}_{axis}": v for axis, v in zip("xy", value)})
        else:
            out[name] = value
    return out


def _flat_bounds(box: dict) -> dict:
    vectors = ("table_acceleration", "marker_offset")  # bounds per axis
    return {(f"{n}_{axis}" if n in vectors else n): b for n, b in box.items()
            for axis in ("xy" if n in vectors else "x")}


def _hebo_polish(args, settings: dict) -> int:
    """Evaluations of HEBO's closing polish: --polish, else polish_evaluations (config/sysid.yaml)."""
    return settings["polish_evaluations"] if args.polish is None else args.polish


def _identify_all(args, tracker: dict, settings: dict, train: list, validation: list) -> dict:
    names = args.identify
    _WORK.update(tracker=tracker, trajectories=train, loss=args.loss, stride=settings["stride"])
    learn_at = HORIZONS if args.cross_validate else (args.horizon,)
    start = time.monotonic()
    with _worker_pool(settings) as (pool, workers):
        runs = {}
        for h in learn_at:
            bar = Progress(f"sysid {args.loss} @ {h} s", args.json)

            def progress(done: int, total: int, best: float, bar: Progress = bar) -> None:
                bar(done, total, f"evaluations, best {objective_text(args.loss, best)}")
            ident = identify(_Objective(pool, workers, h, args.loss), bounds(settings, names),
                             {n: tracker[n] for n in names}, args.iterations, args.batch, args.seed,
                             settings["random_samples"], _hebo_polish(args, settings), progress)
            runs[h] = ident
    chosen = runs[args.horizon]
    initial = {n: tracker[n] for n in names}
    result = {"loss": args.loss, "horizon": args.horizon, "initial": initial, "identified": chosen.best,
              "evaluations": sum(r.evaluations for r in runs.values()), "seconds": round(time.monotonic() - start, 1),
              # exactly what was minimised, next to the reports below (every frame, both sets)
              "objective": {"loss": args.loss, "horizon": args.horizon, "stride": settings["stride"],
                            "set": "train", "initial": chosen.initial_objective, "identified": chosen.best_objective},
              "on_bounds": on_bounds(chosen.best, bounds(settings, names), settings["bound_margin"]),
              "before": {}, "after": {}}
    result["before"], result["after"] = _before_after(tracker, chosen.best, train, validation, args.horizon)
    if args.cross_validate:
        result["learned"] = {str(h): r.best for h, r in runs.items()}
        result["cross_validation"] = {
            str(v): {str(h): loss_report({**tracker, **r.best}, validation, v).as_dict() for h, r in runs.items()}
            for v in HORIZONS}
    result["summary_line"] = (f"identified by `air-hockey sysid --method hebo` ({args.loss} loss, horizon {args.horizon} s, "
                              f"{len(train)} training trajectories) on "
                              f"{datetime.now(timezone.utc).strftime('%Y-%m-%d %H:%M UTC')}")
    return result

"""``air-hockey noise-estimate BAG_DIR...``: measurement noise R and process noise Q from recordings.

Eq. 3.12 and 3.13 of the thesis, diagonal, iterated ``--iterations`` times with the filter's own
estimates standing in for the true states (sec. 4.4). ``--fix R`` or ``--fix Q`` keeps that matrix at
its current value (``config/tracker.yaml`` or ``--params-file``) and estimates only the other. The
prediction error at ``--horizon`` is reported for the current noise, for estimated R only, estimated
Q only and both (the thesis kept Q after this comparison, sec. 5.3). ``--out`` writes R and Q as a
tracker parameter YAML. A mocap pivot off the disc's centre is not noise: the measured positions are taken
back to the centre by the tracker's ``marker_offset`` (as configured, e.g. by ``sysid --method split``'s YAML,
or as the filter learns it online), as the filter itself takes them. The filter's own learning of the
position noise (``noise_adaptation``) is off here: the noise is this tool's to estimate (the tracker takes
the R written by ``--out`` as the prior of that learning).

``--by-regime`` (issue #13: noise by regime) estimates R as above (or keeps it with ``--fix R``) and
then calibrates the process noise by regime instead of eq. 3.13: Q in flight, Q at rest
(``process_noise_rest``) and the rim impacts' ``impact_noise``, each scaled until its regime's NIS median
is a consistent filter's (2.37); check them on a recording it did not see with ``eval-prediction``
(NIS by regime).

Iterating both matrices together can run away: a larger Q lets the filter follow the measurements,
which shrinks the posterior residuals and so the next R, and so on (seen on synthetic data: R falls by
orders of magnitude in 5 iterations). With ``--fix Q`` the R estimate settles near the true noise
(synthetic data with 1e-8 m^2: 0.8-1.5e-8 after 5 iterations).
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from air_hockey_agent.core.identification.noise import calibrate_by_regime, fixed_noise, iterate
from air_hockey_agent.core.identification.sysid import loss_report
from air_hockey_agent.params import yaml_value
from air_hockey_agent.tools.files import write_text_atomic
from air_hockey_agent.tools.json_output import json_text
from air_hockey_agent.tools.recordings import ToolError, add_recording_arguments, load_recordings, report_error
from air_hockey_agent.tools.argtypes import count, number

PROG = "air-hockey noise-estimate"


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser("noise-estimate", help="estimate R and Q from recordings (eq. 3.12, 3.13)",
                                   description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_recording_arguments(parser)
    parser.add_argument("--iterations", type=count(1), default=5, help="iterations (thesis: 5)")
    parser.add_argument("--fix", choices=("R", "Q"), action="append", default=[],
                        help="keep this matrix fixed (may be given once)")
    parser.add_argument("--horizon", type=number(0.0, low_open=True), default=1.0, help="horizon of the reported prediction error [s]")
    parser.add_argument("--by-speed", action="store_true",
                        help="estimate the position noise at rest and its growth with speed "
                             "(measurement_noise_per_speed) instead of one value for all speeds")
    parser.add_argument("--by-regime", action="store_true",
                        help="calibrate Q in flight, Q at rest (process_noise_rest) and impact_noise by each "
                             "regime's NIS instead of eq. 3.13's Q")
    parser.add_argument("--out", type=Path, help="write measurement_noise and process_noise to this YAML")
    parser.add_argument("--json", action="store_true", help="print exactly one JSON object")
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    if len(set(args.fix)) > 1:
        print(f"{PROG}: error: --fix may be given once (R or Q)", file=sys.stderr)
        return 2
    try:
        recordings = load_recordings(PROG, args)
    except ToolError as exc:
        return report_error(PROG, exc)
    tracker, loaded = fixed_noise(recordings.tracker), recordings.loaded  # the noise is this tool's to estimate
    if args.by_speed and "R" in args.fix:
        print(f"{PROG}: error: --by-speed estimates R; it cannot be combined with --fix R", file=sys.stderr)
        return 2
    if args.by_regime and "Q" in args.fix:
        print(f"{PROG}: error: --by-regime calibrates Q; it cannot be combined with --fix Q", file=sys.stderr)
        return 2
    fix = args.fix + (["Q"] if args.by_regime else [])  # by regime, Q comes from the NIS calibration below
    history = iterate(tracker, loaded.trajectories, args.iterations, fix, args.by_speed)
    final = history[-1]
    r = tracker["measurement_noise"] if "R" in args.fix else final.r.tolist()
    r_params = {"measurement_noise": r}
    if final.r_per_speed is not None:
        r_params["measurement_noise_per_speed"] = final.r_per_speed
    calibration = None
    if args.by_regime:
        calibration = calibrate_by_regime({**tracker, **r_params}, loaded.trajectories)
        q_params = dict(calibration.values)
    else:
        q_params = {"process_noise": tracker["process_noise"] if "Q" in args.fix else final.q.tolist()}
    q = q_params["process_noise"]
    variants = {"current": {}, "estimated_R": r_params, "estimated_Q": q_params,
                "estimated_both": {**r_params, **q_params}}
    errors = {name: loss_report({**tracker, **v}, loaded.trajectories, args.horizon).as_dict()
              for name, v in variants.items()}
    result = {"trajectories": len(loaded.trajectories), "iterations": args.iterations, "fixed": args.fix,
              "measurement_noise": r, "process_noise": q, "measurement_noise_per_speed": final.r_per_speed,
              "by_regime": None if calibration is None else {
                  "process_noise_rest": calibration.values["process_noise_rest"],
                  "impact_noise": calibration.values["impact_noise"], "nis_median": calibration.nis_median,
                  "frames": calibration.frames, "filter_passes": calibration.passes,
                  "on_bound": calibration.on_bound},
              # a fixed matrix is what every iteration used (its estimate was not fed back)
              "history": [{"measurement_noise": r if "R" in args.fix else h.r.tolist(),
                           "process_noise": q if "Q" in fix else h.q.tolist()} for h in history],
              "prediction_error": {"horizon": args.horizon, **errors}}
    for regime in (calibration.on_bound if calibration else []):
        print(f"{PROG}: warning: the {regime} regime's NIS median could not be brought to 2.37 within its "
              f"range (the search ended at an end): its noise is not what is off there (e.g. R at rest)",
              file=sys.stderr)
    if args.out is not None:
        _write(args.out, r, q, final.r_per_speed, args, calibration)
    print(json_text(result) if args.json else _format(result, args.out))
    return 2 if loaded.errors else 0


def _format(result: dict, out: Path | None) -> str:
    fmt = lambda values: "[" + ", ".join(f"{v:.3e}" for v in values) + "]"  # noqa: E731
    lines = [f"{result['trajectories']} trajectories, {result['iterations']} iterations"
             + (f", fixed: {', '.join(result['fixed'])}" if result["fixed"] else "")]
    fixed = lambda name: " (fixed)" if name in result["fixed"] else ""  # noqa: E731
    for i, h in enumerate(result["history"], 1):
        lines.append(f"  iteration {i}: R {fmt(h['measurement_noise'])}{fixed('R')}  "
                     f"Q {fmt(h['process_noise'])}{fixed('Q')}")
    lines.append(f"R (x, y, theta) = {fmt(result['measurement_noise'])}")
    per_speed = result["measurement_noise_per_speed"]
    if per_speed is not None:
        at_rest = np.sqrt(result["measurement_noise"][0])
        lines.append(f"  position noise at rest above, growing by {per_speed:.3e} s per m/s (in quadrature): "
                     f"{at_rest * 1e3:.3f} mm at rest, {np.hypot(at_rest, 3.0 * per_speed) * 1e3:.3f} mm at 3 m/s")
    regime = result["by_regime"]
    lines.append(f"Q (x, y, vx, vy, theta, omega) = {fmt(result['process_noise'])}"
                 + (" in flight (NIS calibrated)" if regime else ""))
    if regime:
        lines.append(f"Q at rest = {fmt(regime['process_noise_rest'])}, impact noise {regime['impact_noise']:.3f}")
        lines.append("NIS median by regime after calibration (consistent 2.37): " + ", ".join(
            f"{r} " + ("-" if m is None else f"{m:.2f}") + f" ({regime['frames'][r]} frames)"
            for r, m in regime["nis_median"].items()) + f"; {regime['filter_passes']} filter passes")
    h = result["prediction_error"]["horizon"]
    lines.append(f"prediction error at {h} s: mean / median per trajectory [mm]")
    for name, r in result["prediction_error"].items():
        if name != "horizon":
            lines.append(f"  {name:<15} {r['loss_m'] * 1e3:8.2f} {r['median_m'] * 1e3:8.2f}")
    if out is not None:
        lines.append(f"wrote {out}")
    return "\n".join(lines)


def _write(path: Path, r: list, q: list, per_speed: float | None, args: argparse.Namespace,
           calibration=None) -> None:
    text = (f"# Noise covariances estimated by `air-hockey noise-estimate` (eq. 3.12, 3.13; {args.iterations} "
            f"iterations{', fixed ' + args.fix[0] if args.fix else ''}).\n/**/puck_tracker:\n  ros__parameters:\n"
            f"    measurement_noise: {yaml_value(r)}\n    process_noise: {yaml_value(q)}\n")
    if per_speed is not None:
        text += f"    measurement_noise_per_speed: {yaml_value(per_speed)}\n"
    if calibration is not None:
        text += (f"    process_noise_rest: {yaml_value(calibration.values['process_noise_rest'])}\n"
                 f"    impact_noise: {yaml_value(calibration.values['impact_noise'])}\n")
    write_text_atomic(path, text)

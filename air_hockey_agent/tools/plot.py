"""``air-hockey plot BAG_DIR...``: PNG figures like thesis figures 5.1-5.6.

* ``velocity.png``: the filter's velocity and spin against finite differences of the measurements;
* ``prediction.png``: measured x, y, theta against the prediction made ``--horizon`` seconds before;
* ``error_vs_horizon.png``: mean prediction error over all comparisons and the median of the trajectories'
  mean errors (the thesis's median column) against the horizon, from the filter ``sysid`` and
  ``eval-prediction``'s thesis-style columns run (nothing learned online, no hand regime:
  :func:`~air_hockey_agent.tracker_params.trajectory_loss_params`).

One trajectory (``--trajectory``, default the longest) is drawn in the first two; trajectories come
from the same preprocessing as ``sysid``. ``--params-file`` plots with other (e.g. identified)
parameters; give it twice as ``--compare`` to draw a second parameter set next to the first.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from air_hockey_agent.core.estimation.ekf import PuckEKF
from air_hockey_agent.core.estimation.evaluation import prediction_series
from air_hockey_agent.core.identification.sysid import position_loss_reports
from air_hockey_agent.params import ParameterFileError, ParameterValueError, check_files_read
from air_hockey_agent.tools.recordings import ToolError, add_recording_arguments, load_recordings, report_error
from air_hockey_agent.tracker_params import load_tracker_params, trajectory_loss_params
from air_hockey_agent.tools.argtypes import count, number
from air_hockey_agent.tools.files import save_figure

PROG = "air-hockey plot"
HORIZON_GRID = np.round(np.arange(0.1, 1.51, 0.1), 2)


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser("plot", help="PNG figures: velocity, prediction, error vs horizon",
                                   description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_recording_arguments(parser)
    parser.add_argument("--out", type=Path, default=Path("plots"), help="output directory (default ./plots)")
    parser.add_argument("--horizon", type=number(0.0, low_open=True), default=0.5, help="prediction horizon of prediction.png [s]")
    parser.add_argument("--trajectory", type=count(0), help="index of the trajectory to draw (default: longest)")
    parser.add_argument("--compare", type=Path, help="a second tracker parameter YAML drawn for comparison")
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    if args.out.exists() and not args.out.is_dir():
        print(f"{PROG}: error: --out {args.out} is a file; it names the directory the PNGs are written to",
              file=sys.stderr)
        return 2
    try:
        other = load_tracker_params([*args.params_file, args.compare]) if args.compare else None
        check_files_read([args.compare] if args.compare else [], ("puck_tracker",), "--compare")
        recordings = load_recordings(PROG, args)  # after the files: before the (possibly long) read of the bags
    except (ToolError, ParameterFileError, ParameterValueError) as exc:
        return report_error(PROG, exc)
    tracker, loaded = recordings.tracker, recordings.loaded
    index = args.trajectory if args.trajectory is not None else int(np.argmax([len(t) for t in loaded.trajectories]))
    if not 0 <= index < len(loaded.trajectories):
        print(f"{PROG}: error: --trajectory {index} out of range 0..{len(loaded.trajectories) - 1}", file=sys.stderr)
        return 2
    import matplotlib
    matplotlib.use("Agg")
    try:
        args.out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        print(f"{PROG}: error: --out {args.out}: cannot create the directory ({exc.strerror})", file=sys.stderr)
        return 2
    sets = {"current": tracker} if other is None else {"current": tracker, str(args.compare.name): other}
    traj = loaded.trajectories[index]
    written = [_velocity(args.out, traj, tracker), _prediction(args.out, traj, sets, args.horizon),
               _error_vs_horizon(args.out, loaded.trajectories, sets)]
    print(f"trajectory {index} of {len(loaded.trajectories)} ({loaded.sources[index]}, {traj.duration:.1f} s)")
    for path in written:
        print(f"wrote {path}")
    return 2 if loaded.errors else 0


def _velocity(out: Path, traj, params) -> Path:
    import matplotlib.pyplot as plt
    s = prediction_series(PuckEKF.from_params(params), traj.frames(), 0.0)
    t = s.t - s.t[0]
    fd = np.diff(s.measured, axis=0) / np.diff(s.t)[:, None]
    fd[:, 2] = np.diff(np.unwrap(s.measured[:, 2])) / np.diff(s.t)
    fig, axes = plt.subplots(3, 1, figsize=(9, 7), sharex=True)
    for ax, col, fd_col, label in zip(axes, (2, 3, 5), (0, 1, 2), ("vx [m/s]", "vy [m/s]", "omega [rad/s]")):
        ax.plot(t[1:], fd[:, fd_col], ".", ms=2, color="tab:blue", label="finite differences of measurements")
        ax.plot(t, s.estimated[:, col], color="tab:orange", label="EKF estimate")
        ax.set_ylabel(label)
    axes[0].legend(loc="upper right", fontsize=8)
    axes[-1].set_xlabel("time [s]")
    fig.suptitle("Estimated and measured velocity (cf. thesis fig. 5.1)")
    fig.tight_layout()
    return save_figure(fig, out / "velocity.png")


def _legend_below(fig, ax) -> None:
    """The legend under the axes, outside the data (it hid the curves it names)."""
    handles, labels = ax.get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=min(len(labels), 3), fontsize=8, frameon=False)
    rows = -(-len(labels) // 3)
    fig.tight_layout(rect=(0.0, 0.04 * rows + 0.01, 1.0, 1.0))


def _prediction(out: Path, traj, sets: dict, horizon: float) -> Path:
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(3, 1, figsize=(9, 7), sharex=True)
    first = True
    # a compared set is drawn dashed over the first, so both stay visible where they agree
    for (name, params), color, style in zip(sets.items(), ("tab:orange", "tab:green"), ("-", "--")):
        s = prediction_series(PuckEKF.from_params(params), traj.frames(), horizon)
        t = s.t - s.t[0]
        for ax, mcol, pcol, label in zip(axes, (0, 1, 2), (0, 1, 4), ("x [m]", "y [m]", "theta [rad]")):
            if first:
                ax.plot(t, s.measured[:, mcol], color="tab:blue", lw=1, label="measured")
            ax.plot(t, s.predicted[:, pcol], style, color=color, lw=1.2,
                    label=f"predicted {horizon} s before ({name})")
            ax.set_ylabel(label)
        first = False
    _legend_below(fig, axes[0])
    axes[-1].set_xlabel("time [s]")
    fig.suptitle(f"Measured and predicted position, horizon {horizon} s (cf. thesis fig. 5.2-5.4)")
    return save_figure(fig, out / "prediction.png")


def _error_vs_horizon(out: Path, trajectories, sets: dict) -> Path:
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(7, 4.5))
    for (name, params), color in zip(sets.items(), ("tab:orange", "tab:green")):
        reports = list(position_loss_reports(trajectory_loss_params(params), trajectories,
                                             [float(h) for h in HORIZON_GRID]).values())
        ax.plot(HORIZON_GRID, [r.loss * 1e3 for r in reports], "o-", color=color, label=f"mean ({name})")
        ax.plot(HORIZON_GRID, [r.median * 1e3 for r in reports], "s--", color=color,
                label=f"median of trajectory means ({name})")
    ax.set_xlabel("prediction horizon [s]")
    ax.set_ylabel("position error [mm]")
    ax.grid(alpha=0.3)
    ax.set_title(f"Prediction error against horizon, {len(trajectories)} trajectories (cf. thesis fig. 5.5)")
    _legend_below(fig, ax)
    return save_figure(fig, out / "error_vs_horizon.png")

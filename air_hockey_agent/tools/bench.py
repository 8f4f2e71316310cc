"""``air-hockey bench``: benchmarks that print figures (never timed assertions in tests)."""
from __future__ import annotations

import argparse

from air_hockey_agent.tools import bench_planner, bench_sim, bench_smash, bench_tactics, bench_tracker


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser("bench", help="benchmarks (tracker timing, simulation speed, motion planner, tactics, smash accuracy)")
    bench_subparsers = parser.add_subparsers(title="benchmarks", metavar="BENCH")
    bench_tracker.add_parser(bench_subparsers)
    bench_sim.add_parser(bench_subparsers)
    bench_planner.add_parser(bench_subparsers)
    bench_tactics.add_parser(bench_subparsers)
    bench_smash.add_parser(bench_subparsers)
    parser.set_defaults(run=lambda args: parser.print_help() or 2)

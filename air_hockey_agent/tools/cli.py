"""``air-hockey``: one command with a subcommand per tool (``air-hockey --help`` lists them)."""
from __future__ import annotations

import argparse
import importlib
import sys
from importlib import metadata

from air_hockey_agent.params import ParameterFileError, ParameterValueError
from air_hockey_agent.tools import interrupt
from air_hockey_agent.tools.argtypes import OneLineParser

# Subcommand modules; each provides add_parser(subparsers) that sets `run` as the handler.
TOOL_MODULES = (
    "air_hockey_agent.tools.game",
    "air_hockey_agent.tools.game_check",
    "air_hockey_agent.tools.strategy_test",
    "air_hockey_agent.tools.bench",
    "air_hockey_agent.tools.eval_prediction",
    "air_hockey_agent.tools.synth_bag",
    "air_hockey_agent.tools.record",
    "air_hockey_agent.tools.play",
    "air_hockey_agent.tools.sysid",
    "air_hockey_agent.tools.noise_estimate",
    "air_hockey_agent.tools.plot",
    "air_hockey_agent.tools.ros_cli",
)


def package_version() -> str:
    try:
        return metadata.version("air_hockey_agent")
    except metadata.PackageNotFoundError:
        return "unknown (not installed)"


def build_parser() -> argparse.ArgumentParser:
    parser = OneLineParser(
        prog="air-hockey",
        description="Robot air hockey baseline agent: game launcher and tools for tracking, "
                    "recorded data, system identification and benchmarks.")
    parser.add_argument("--version", action="version", version=f"air-hockey {package_version()}")
    subparsers = parser.add_subparsers(title="commands", metavar="COMMAND")
    for module in TOOL_MODULES:
        importlib.import_module(module).add_parser(subparsers)
    return parser


def chosen_parser(parser: argparse.ArgumentParser, argv: list[str]) -> argparse.ArgumentParser:
    """The deepest subcommand parser ``argv`` selects (``bench tracker`` -> its parser), so that an
    unknown option is reported by the tool it was given to, with that tool's ``--help``."""
    for token in argv:
        actions = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
        if not actions or token.startswith("-"):
            continue
        if token not in actions[0].choices:
            break
        parser = actions[0].choices[token]
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    argv = sys.argv[1:] if argv is None else list(argv)
    args, unknown = parser.parse_known_args(argv)
    if unknown:
        chosen_parser(parser, argv).error(f"unrecognized arguments: {' '.join(unknown)}")
    if not hasattr(args, "run"):
        parser.print_help()
        return 2
    interrupt.install()
    try:
        return int(args.run(args) or 0)
    except KeyboardInterrupt as exc:
        return interrupt.exit_code(exc)
    except (ParameterFileError, ParameterValueError) as exc:  # e.g. an edited config/ with a value out of bounds
        print(f"{chosen_parser(parser, argv).prog}: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())

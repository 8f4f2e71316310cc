"""Argument types for the ``air-hockey`` tools: a bad value is refused by argparse in one line
("argument --batch: must be an integer >= 1, got '0'") before any work starts."""
from __future__ import annotations

import argparse
import math
import re
from typing import Callable

_ROLE = re.compile(r":[a-z]+:`~?([^`<]*?)(?:\s*<[^>]*>)?`")   # :class:`~a.b.C` -> C (last part), :func:`x`
_LITERAL = re.compile(r"``([^`]+)``")                          # ``air-hockey game`` -> air-hockey game


def plain(text: str) -> str:
    """Help text without reStructuredText markup (the tools' docstrings are their descriptions)."""
    text = _ROLE.sub(lambda m: m.group(1).rsplit(".", 1)[-1], text)
    return _LITERAL.sub(r"\1", text)


def count(low: int = 1, high: int | None = None) -> Callable[[str], int]:
    """A whole number in [low, high]."""
    bounds = f">= {low}" if high is None else f"in {low}..{high}"

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"must be an integer {bounds}, got '{text}'") from None
        if value < low or (high is not None and value > high):
            raise argparse.ArgumentTypeError(f"must be an integer {bounds}, got '{text}'")
        return value
    return parse


SEED_MAX = 2 ** 31 - 1  # numpy's and pybullet's seeds: a non-negative 32-bit integer (game checks its own)
seed = count(0, SEED_MAX)  # --seed: refused in one line (numpy's default_rng raised on a negative seed)


def number(low: float | None = None, high: float | None = None, low_open: bool = False,
           high_open: bool = False) -> Callable[[str], float]:
    """A finite number within the given bounds (``*_open``: the bound itself excluded)."""
    parts = []
    if low is not None:
        parts.append(f"{'>' if low_open else '>='} {low:g}")
    if high is not None:
        parts.append(f"{'<' if high_open else '<='} {high:g}")
    bounds = " and ".join(parts) or "finite"

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"must be a number {bounds}, got '{text}'") from None
        bad = (not math.isfinite(value)
               or (low is not None and (value < low or (low_open and value == low)))
               or (high is not None and (value > high or (high_open and value == high))))
        if bad:
            raise argparse.ArgumentTypeError(f"must be a number {bounds}, got '{text}'")
        return value
    return parse


class OneLineParser(argparse.ArgumentParser):
    """argparse with its error in one line (``prog: error: message``), no usage block: every tool's
    bad input is reported the same way, and scripts can read the reason from one line."""

    def error(self, message: str):  # noqa: D401 (argparse API)
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")

    def format_help(self) -> str:
        return plain(super().format_help())

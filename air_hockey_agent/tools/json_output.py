"""What the tools print with ``--json`` and write as JSON lines: strict JSON (RFC 8259), which has no NaN
or infinity; Python's ``json.dumps`` writes those as the bare words ``NaN`` / ``Infinity`` that most
parsers refuse. A figure that is not a number (no comparison at a horizon, a standard deviation from one
sample) is written as ``null``."""
from __future__ import annotations

import json
import math
from typing import Any


def finite_or_none(value: Any) -> Any:
    """``value`` with every float that is NaN or infinite (in dicts, lists and tuples, at any depth) as None."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {key: finite_or_none(item) for key, item in value.items()}
    if isinstance(value, (list, tuple)):
        return [finite_or_none(item) for item in value]
    return value


def json_text(value: Any) -> str:
    """``value`` as one line of strict JSON (non-finite floats as null)."""
    return json.dumps(finite_or_none(value), allow_nan=False)

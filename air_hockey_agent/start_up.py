"""What a long-running process does once it stands, and what it logs then (ROS-free: nodes, benchmarks and
the launcher alike)."""
from __future__ import annotations

import gc

READY_MARKER = "node ready:"  # a node logs it once constructed (nodes/runtime.py); the game launcher waits for it


def freeze_start_up() -> None:
    """Move every object made so far (the node, its models, loaded modules) out of the garbage collector's
    reach: a full collection otherwise walks them all and stalls a callback by tens of milliseconds
    (``air-hockey bench tactics``: decision time max about 100 ms without, about 35 ms with)."""
    gc.collect()
    gc.freeze()

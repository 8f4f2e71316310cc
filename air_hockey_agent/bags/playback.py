"""Timing of a bag replay (ROS-free): when each message is due, at a rate factor, optionally looping."""
from __future__ import annotations

import time
from typing import Callable, Iterable, Iterator

Message = tuple[str, int, bytes]  # topic, log time [ns], serialised message


def paced(read: Callable[[], Iterable[Message]], rate: float, loop: bool,
          clock: Callable[[], float] = time.monotonic,
          wait: Callable[[float], None] = time.sleep) -> Iterator[tuple[str, int, bytes]]:
    """Yield messages when due: the first at once, the rest spaced by their log times divided by ``rate``.

    ``read()`` returns the bag's messages in log-time order (called again for every loop). The yielded
    time [ns] is the bag time of the message, continued across loops (each loop starts one gap after the
    previous end), so a ``/clock`` derived from it never runs backwards.
    """
    if rate <= 0.0:
        raise ValueError(f"rate must be positive, got {rate}")
    start_wall, offset_ns, first_ns, last_ns = clock(), 0, None, None
    while True:
        count = 0
        for topic, log_ns, raw in read():
            if first_ns is None:
                first_ns = log_ns
            bag_ns = log_ns + offset_ns
            delay = start_wall + (bag_ns - first_ns) * 1e-9 / rate - clock()
            if delay > 0.0:
                wait(delay)
            last_ns = bag_ns
            count += 1
            yield topic, bag_ns, raw
        if not loop or count == 0:
            return
        offset_ns = last_ns - first_ns + max(1, (last_ns - first_ns) // max(count, 1))

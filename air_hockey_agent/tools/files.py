"""Output files of the command-line tools, written atomically: the complete file or none."""
from __future__ import annotations

import os
from pathlib import Path


def write_text_atomic(path: Path, text: str) -> None:
    """Write ``text`` to a temporary file beside ``path``, then rename it into place."""
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}")
    tmp.write_text(text)
    os.replace(tmp, path)


def save_figure(fig, path: Path, dpi: int = 110) -> Path:
    """Save a matplotlib figure as PNG atomically (a temporary file beside ``path``, then renamed) and
    close it."""
    import matplotlib.pyplot as plt
    tmp = path.with_name(f".{path.stem}.tmp-{os.getpid()}.png")
    fig.savefig(tmp, dpi=dpi)
    plt.close(fig)
    os.replace(tmp, path)
    return path


def output_bag_directory(out: Path) -> Path:
    """The bag directory an ``OUT.mcap`` (or ``OUT``) argument names: ``OUT`` (rosbag2 writes a directory)."""
    return out.with_suffix("") if out.suffix == ".mcap" else out

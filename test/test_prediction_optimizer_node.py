"""prediction_optimizer (separate process) identifies parameters through a running puck_tracker's services."""
import subprocess
import sys
from pathlib import Path

import pytest

from air_hockey_agent.tools.launch import ProcessSpec

pytestmark = [pytest.mark.integration, pytest.mark.slow]
BIN = Path(sys.executable).parent


def test_optimizer_improves_the_loss_through_the_services(launcher, tmp_path):
    true = tmp_path / "true.yaml"
    true.write_text("/**/puck_tracker:\n  ros__parameters:\n    restitution: 0.7\n    damping: 0.3\n")
    made = subprocess.run([str(BIN / "air-hockey"), "synth-bag", str(tmp_path / "bags" / "a"), "--shots", "3",
                           "--params-file", str(true)], capture_output=True, text=True, timeout=120)
    assert made.returncode == 0, made.stderr
    # a short run (3 x 2 suggestions, a brief polish) in a box narrowed around the truth, as a user
    # with prior knowledge would set it in sysid.yaml: the mechanism is tested here, the optimiser's
    # reach over the whole table 4.1 box in test_sysid.py and the closing figures
    short = tmp_path / "short.yaml"
    short.write_text("/**:\n  ros__parameters:\n    min_duration: 1.0\n    polish_evaluations: 8\n"
                     "    random_samples: 4\n    bounds:\n      friction_surface: [0.0, 0.001]\n"
                     "      friction_rim: [0.05, 0.15]\n      restitution: [0.6, 1.0]\n      damping: [0.2, 0.6]\n")
    launcher.start(ProcessSpec("puck_tracker", [str(BIN / "puck_tracker")]))
    out = tmp_path / "identified.yaml"
    optimizer = launcher.start(ProcessSpec("prediction_optimizer", [
        str(BIN / "prediction_optimizer"), "--ros-args", "--params-file", str(short), "-p",
        f"bags:={tmp_path / 'bags'}", "-p", "iterations:=3", "-p", "batch:=2", "-p", "horizon:=0.5",
        "-p", f"out:={out}"]))
    assert optimizer.popen.wait(timeout=600) == 0
    optimizer.reader.join(timeout=10)
    lines = "\n".join(optimizer.lines)
    assert "loss at 0.5 s:" in lines and "(set in the tracker)" in lines
    before, after = [float(v.split()[0]) for v in lines.split("loss at 0.5 s: ")[1].split(" -> ")[:2]]
    assert after < before
    assert "ros__parameters" in out.read_text()

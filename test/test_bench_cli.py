"""`air-hockey bench tracker --json` prints one JSON object with the documented keys (figures not asserted)."""
import json
import subprocess
import sys
from pathlib import Path


def test_bench_tracker_json_shape():
    exe = Path(sys.executable).parent / "air-hockey"
    out = subprocess.run([str(exe), "bench", "tracker", "--samples", "60", "--json"], capture_output=True,
                         text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    result = json.loads(out.stdout)
    assert set(result["update_us"]) == {"mean", "p99"}
    for method in ("stepwise", "fast", "fast_mean_only"):
        assert set(result["predict_us"][method]) == {"0.5", "1.0", "1.5"}
        assert all(v["mean"] > 0 for v in result["predict_us"][method].values())


def test_bench_sim_json_shape():
    exe = Path(sys.executable).parent / "air-hockey"
    out = subprocess.run([str(exe), "bench", "sim", "--duration", "1", "--json"], capture_output=True, text=True,
                         timeout=300)
    assert out.returncode == 0, out.stderr
    result = json.loads(out.stdout)  # nothing but the JSON object on stdout (pybullet's prints silenced)
    assert set(result) == {"rtf_puck_only", "rtf_arms_idle", "rtf_with_arms"}
    assert all(v > 0 for v in result.values())


def test_bench_smash_json_shape():
    exe = Path(sys.executable).parent / "air-hockey"
    out = subprocess.run([str(exe), "bench", "smash", "--shots", "2", "--json"], capture_output=True, text=True,
                         timeout=300)
    assert out.returncode == 0, out.stderr
    result = json.loads(out.stdout)
    assert set(result) == {"smash_straight", "smash_left", "smash_right"}
    for r in result.values():
        assert r["shots"] == 2 and 0 <= r["planned"] <= 2 and 0.0 <= r["goal_rate"] <= 1.0
        assert set(r["offset_m"]) == {"mean", "std"} and set(r["direction_error_deg"]) == {"mean", "std"}
    bad = subprocess.run([str(exe), "bench", "smash", "--shots", "0"], capture_output=True, text=True, timeout=60)
    assert bad.returncode == 2 and "argument --shots: must be an integer >= 1" in bad.stderr

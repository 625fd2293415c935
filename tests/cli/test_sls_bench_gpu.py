"""`sls bench --device cuda`: the GPU section the README documents (memory, the budget, the copy
bandwidth and each hot kernel's share of it, `gpu.kernels`), its figures consistent with one
another. Exits 77 (skipped) where `sls info` lists no CUDA device.
Usage: test_sls_bench_gpu.py SLS"""
import json
import math
import subprocess
import sys

# The kernels `gpu.kernels` may name (README, `sls bench`), and those every scan launches.
DOCUMENTED = {"decode", "icp_reduction", "integrate", "gtsdf_sweep", "raycast", "resample", "ship_region"}
EVERY_SCAN = {"decode", "icp_reduction", "integrate", "gtsdf_sweep", "raycast"}
KEYS = {"name", "launches", "gpu_s", "mean_ms", "model_bytes", "achieved_gb_s", "fraction_of_copy"}


def run(sls, *args):
    return subprocess.run([sls, *args], capture_output=True, text=True, timeout=600)


def check(sls):
    info = run(sls, "--json", "info")
    assert info.returncode == 0, info.stderr
    if not json.loads(info.stdout)["cuda_devices"]:
        print("no CUDA device: skipped")
        return 77
    budget = 6e9
    result = run(sls, "--json", "bench", "--preset", "ci", "--device", "cuda", "--frames", "12",
                 "--max-gpu-memory", str(budget))
    assert result.returncode == 0, result.stderr
    bench = json.loads(result.stdout)
    assert bench["device"].startswith("cuda"), bench["device"]
    gpu = bench["gpu"]
    assert gpu["name"], gpu
    assert 0 < gpu["memory_used_bytes"] <= gpu["memory_total_bytes"], gpu
    assert gpu["budget_bytes"] == budget, gpu
    assert 0 <= gpu["allocated_before_scan_bytes"] <= gpu["allocated_peak_bytes"] <= budget, gpu
    copy = gpu["copy_bandwidth_gb_s"]
    assert copy > 0, gpu
    rows = gpu["kernels"]
    names = [row["name"] for row in rows]
    assert len(names) == len(set(names)), names
    assert set(names) <= DOCUMENTED, names
    assert EVERY_SCAN <= set(names), names
    # A move launches the resampling (and, beside the frames, the search for what leaves).
    assert ("resample" in names) == (bench["volume"]["moves"] > 0), (names, bench["volume"])
    for row in rows:
        assert set(row) == KEYS, row
        assert row["launches"] > 0 and row["gpu_s"] > 0 and row["model_bytes"] > 0, row
        assert math.isclose(row["mean_ms"], 1e3 * row["gpu_s"] / row["launches"], rel_tol=1e-9), row
        assert math.isclose(row["achieved_gb_s"], row["model_bytes"] / row["gpu_s"] * 1e-9, rel_tol=1e-9), row
        assert math.isclose(row["fraction_of_copy"], row["achieved_gb_s"] / copy, rel_tol=1e-9), row
        # The GPU time of a kernel's launches lies within the run's end-to-end time.
        assert row["gpu_s"] <= bench["end_to_end_s"], (row, bench["end_to_end_s"])
    # The human-readable form prints the same section.
    text = run(sls, "bench", "--preset", "ci", "--device", "cuda", "--frames", "2")
    assert text.returncode == 0, text.stderr
    for name in EVERY_SCAN:
        assert name in text.stdout, (name, text.stdout)
    print(json.dumps({"copy_bandwidth_gb_s": copy, "kernels": rows}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(check(sys.argv[1]))

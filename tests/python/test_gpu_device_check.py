"""examples/scripts/gpu_device_check.sh, the prepared real-GPU run, works end to end: run here on
whatever adapter wgpu finds (lavapipe in CI) at a tiny size, so the script cannot rot while no
GPU machine is at hand."""
import json
import os
import pathlib
import subprocess

ROOT = pathlib.Path(__file__).resolve().parents[2]


def test_device_check_times_every_job(prismbake, tmp_path):
    env = dict(os.environ, RES="32", SPP="1", ASSETS="rock", TRACE_PIXELS="1 3")
    # Without the denoise rows the script adds where Open Image Denoise is named.
    env.pop("PRISMBAKE_OIDN", None)
    proc = subprocess.run(
        [str(ROOT / "examples" / "scripts" / "gpu_device_check.sh"), prismbake, str(tmp_path)],
        capture_output=True, text=True, env=env, timeout=600,
    )
    assert proc.returncode == 0, proc.stderr
    rows = json.loads((tmp_path / "summary.json").read_text())
    assert [r["job"] for r in rows] == [
        "rock_aov_gpu_ray", "rock_aov_gpu_packet", "rock_beauty_gpu", "rock_aov_cpu_512",
        "rock_4rays_trace1", "rock_4rays_trace3",
    ]
    assert [len(r["frames"]) for r in rows] == [3, 3, 2, 3, 2, 2]
    assert rows[0]["device"].startswith("gpu") and rows[3]["device"].startswith("cpu")
    # Each AOV job took the BVH walk it asked for (lavapipe on Vulkan has subgroups).
    assert [r["walk"] for r in rows[:2]] == ["ray", "packet"] and rows[3]["walk"] is None
    # The rock's 8-bit map goes up two texels a word on the GPU; the CPU has no such row.
    assert rows[0]["map_encoding"] == "unorm16" and rows[3]["map_encoding"] is None
    for r in rows:
        assert r["ms_per_frame"] > 0 and r["mrays_per_s"] > 0
        # The trace time is part of the frame's, the kernels' part of the trace's.
        assert 0 < r["trace_ms"] <= r["ms_per_frame"]
    # lavapipe (and every desktop Vulkan driver) has timestamp queries: the GPU jobs' Mrays/s
    # come from the kernels' own time; the CPU has no such clock.
    # The "4 rays per pixel" sample: one camera ray per pixel, shadow rays for the key light
    # and the environment where it hits; the same picture whatever the pixels per trace
    # invocation; beauty rows count their rays, AOV rows do not.
    four = rows[4]["rays_per_pixel"]
    assert four["rays"] == 1.0 and four["key_shadow_rays"] > 0 and four["env_shadow_rays"] > 0
    assert rows[4]["picture_md5"] and rows[4]["picture_md5"] == rows[5]["picture_md5"]
    assert rows[2]["rays_per_pixel"]["rays"] >= 1.0 and rows[0]["rays_per_pixel"] is None
    for r in rows[:3] + rows[4:]:
        assert r["kernel_ms"] is not None and 0 < r["kernel_ms"] <= r["trace_ms"]
        assert r["mrays_per_s_from"] == "kernel"
    assert rows[3]["kernel_ms"] is None and rows[3]["mrays_per_s_from"] == "trace"
    assert "trace" in proc.stdout and "kernels" in proc.stdout and "Mrays/s" in proc.stdout
    # The renders themselves were written, after the card's warm-up frame.
    assert (tmp_path / "rock_aov_gpu_packet" / "mask_0002.exr").is_file()
    assert (tmp_path / "warmup" / "beauty.exr").is_file()


def test_device_check_says_when_the_binary_is_missing(tmp_path):
    proc = subprocess.run(
        [str(ROOT / "examples" / "scripts" / "gpu_device_check.sh"), str(tmp_path / "nope"), str(tmp_path)],
        capture_output=True, text=True, timeout=60,
    )
    assert proc.returncode == 2
    assert "no binary" in proc.stderr

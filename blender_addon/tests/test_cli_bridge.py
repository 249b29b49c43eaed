"""cli_bridge without Blender: argument lists, JSON parsing, error lines, the background job.

The module is loaded from its file, outside the add-on package; that it imports nothing from
Blender is checked on its source (bpy may already be imported by other tests in the run)."""
import ast
import importlib.util
import json
import os
import pathlib
import stat
import sys
import time

import pytest

BRIDGE = pathlib.Path(__file__).resolve().parents[1] / "cli_bridge.py"


@pytest.fixture(scope="module")
def cb():
    spec = importlib.util.spec_from_file_location("prismbake_cli_bridge_alone", BRIDGE)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look the module up by name
    spec.loader.exec_module(module)
    return module


def test_bridge_imports_nothing_from_blender():
    tree = ast.parse(BRIDGE.read_text())
    names = {a.name.split(".")[0] for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names}
    names |= {(n.module or "").split(".")[0] for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)}
    assert not names & {"bpy", "bmesh", "mathutils", "addon_utils"}, names
    assert not any(isinstance(n, ast.ImportFrom) and n.level for n in ast.walk(tree)), "relative import"


def test_render_args_carry_every_setting(cb):
    disp = cb.Displacement("/maps/h.png", 0.08, 0.5, uv_set=1, wrap="clamp")
    s = cb.RenderSettings("reference", "gpu", 256, 4, ("normal", "mask"))
    argv = cb.render_args("/bin/prismbake", "/tmp/a.glb", disp, s, "/out")
    assert argv == ["/bin/prismbake", "render", "/tmp/a.glb", "--disp", "/maps/h.png", "--scale", "0.08",
                    "--midlevel", "0.5", "--uv-set", "1", "--wrap", "clamp", "--method", "reference",
                    "--device", "gpu", "--res", "256x256", "--spp", "4", "--aov", "normal,mask",
                    "-o", "/out", "--json"]
    tt = cb.render_args("p", "m.glb", disp, s, "/out", turntable=24)
    assert tt[-4:] == ["/out", "--turntable", "24", "--json"]


def test_other_commands_args(cb):
    disp = cb.Displacement("h.exr", 1.0, 0.0)
    assert cb.bake_args("p", "m.glb", disp, "o.prisms") == [
        "p", "bake", "m.glb", "--disp", "h.exr", "--scale", "1.0", "--midlevel", "0.0", "-o", "o.prisms", "--json"]
    assert cb.validate_args("p", "m.glb", disp, max_disp=0.2)[-4:] == ["--format", "json", "--max-disp", "0.2"]
    assert cb.validate_args("p", "m.glb", disp)[-2:] == ["--format", "json"]
    assert cb.validate_args("p", "m.glb", disp, max_seam_jump=0.05)[-2:] == ["--max-seam-jump", "0.05"]
    assert cb.export_usd_args("p", "m.glb", disp, "o.usda")[-2:] == ["--usd", "o.usda"]


def test_gpu_is_passed_through_and_its_refusal_reported(cb, prismbake_bin, tmp_path):
    disp = cb.Displacement(str(tmp_path / "h.png"), 0.1, 0.5)
    argv = cb.render_args(prismbake_bin, str(tmp_path / "m.glb"), disp, cb.RenderSettings(device="gpu"),
                          str(tmp_path))
    assert argv[argv.index("--device") + 1] == "gpu"
    result = cb.CliJob(argv).start().wait(timeout=30)
    if result.returncode == 0:
        pytest.skip("this build renders on the GPU")
    msg = result.error_message()
    assert msg.startswith("prismbake render failed (input or I/O error, exit 2): ") and "\n" not in msg


def test_bad_settings_are_refused_before_running(cb):
    with pytest.raises(cb.BridgeError, match="unknown method"):
        cb.RenderSettings(method="rmipx").args()
    with pytest.raises(cb.BridgeError, match="unknown device"):
        cb.RenderSettings(device="tpu").args()
    with pytest.raises(cb.BridgeError, match="at least 1"):
        cb.RenderSettings(resolution=0).args()


def test_find_binary_explains_what_is_wrong(cb, tmp_path, monkeypatch):
    assert cb.find_binary(str(tmp_path / "nope"))[1].startswith("prismbake binary not found at")
    assert "is a folder" in cb.find_binary(str(tmp_path))[1]
    f = tmp_path / "prismbake"
    f.write_text("#!/bin/sh\n")
    assert "not executable" in cb.find_binary(str(f))[1]
    f.chmod(f.stat().st_mode | stat.S_IXUSR)
    assert cb.find_binary(str(f)) == (str(f), "")
    monkeypatch.setenv("PATH", str(tmp_path))
    assert cb.find_binary("") == (str(f), "")
    monkeypatch.setenv("PATH", str(tmp_path / "empty"))
    path, why = cb.find_binary("")
    assert path is None and "not on PATH" in why


def test_error_message_is_the_clis_line_with_the_command_and_exit_code(cb):
    r = cb.CliResult(["p", "render"], 2, "", "error: /x.png: No such file or directory (os error 2)\n", 0.1)
    assert r.error_message() == ("prismbake render failed (input or I/O error, exit 2): "
                                 "/x.png: No such file or directory (os error 2)")
    panic = "thread 'main' panicked at core/src/x.rs:1:2:\nindex out of bounds\nnote: run with RUST_BACKTRACE=1"
    assert "panicked at" in cb.CliResult(["p", "bake"], 101, "", panic, 0).error_message()
    assert "crashed" in cb.CliResult(["p", "bake"], 101, "", panic, 0).error_message()
    assert "killed by signal 9" in cb.CliResult(["p", "bake"], -9, "", "", 0).error_message()
    assert "no message on stderr" in cb.CliResult(["p", "bake"], 3, "", "", 0).error_message()
    assert cb.CliResult(["p", "bake"], -9, "", "", 0, cancelled=True).error_message() == "prismbake bake was cancelled"


def test_json_that_is_not_json_is_a_readable_error(cb):
    with pytest.raises(cb.BridgeError, match="printed no valid JSON"):
        cb.CliResult(["p", "render"], 0, "Rendering...", "", 0).json()


def test_parse_render_summary(cb):
    data = {"method": "pdm", "device": "cpu (2 threads)", "setup_seconds": 0.5,
            "frames": [{"frame": None, "seconds": 0.25, "coverage": 0.35}],
            "files": ["/o/normal.exr", "/o/normal.png", "/o/mask.exr", "/o/mask.png"]}
    s = cb.parse_render(data)
    assert s.first("mask") == "/o/mask.png" and s.first("normal", ".exr") == "/o/normal.exr"
    assert s.first("depth") is None
    assert s.seconds == pytest.approx(0.75) and s.coverage == 0.35 and s.frames == 1
    assert s.gpu_fallback is None and s.device_note() == ""


def test_parse_render_says_when_the_cpu_stood_in_for_the_gpu(cb):
    why = "height map: 268435456 bytes exceed this GPU's storage-binding limit of 134217728 bytes"
    s = cb.parse_render({"method": "pdm", "device": "cpu (2 threads)", "frames": [],
                         "files": [], "gpu_fallback": why})
    assert s.gpu_fallback == why
    assert s.device_note() == f"; rendered on the CPU: {why}"


def test_parse_validate_collects_failures_and_faces(cb):
    data = {"assets": [{"asset": "a.glb", "checks": [
        {"name": "mesh", "status": "pass", "message": "960 triangles, 559 vertices"},
        {"name": "sharp-creases", "status": "fail", "message": "3 sharp corners", "faces": [347, 348, 413]},
        {"name": "degenerate-faces", "status": "fail", "message": "1 zero-area", "faces": [3, 347]},
        {"name": "uvs", "status": "pass", "message": "present"}]}],
        "summary": {"assets": 1, "failed": 1}}
    r = cb.parse_validate(data)
    assert [p.check for p in r.problems] == ["sharp-creases", "degenerate-faces"]
    assert r.faces == [3, 347, 348, 413]
    assert r.passed == ["mesh", "uvs"] and r.failed_assets == 1 and r.mesh_triangles == 960


def test_parse_validate_keeps_seam_edges_apart_from_faces(cb):
    data = {"assets": [{"asset": "a.glb", "checks": [
        {"name": "seam-jump", "status": "fail", "message": "78 seam edges", "faces": [1, 2, 14, 15],
         "seam_edges": [[1, 2], [14, 15]]},
        {"name": "degenerate-faces", "status": "fail", "message": "1 zero-area", "faces": [3]}]}],
        "summary": {"assets": 1, "failed": 1}}
    r = cb.parse_validate(data)
    assert r.seam_edges == [(1, 2), (14, 15)]
    assert r.faces == [3], "a seam's faces are selected as its edge, not as faces"


def test_seam_edges_map_back_to_polygon_pairs(cb):
    tri_to_poly = [0, 0, 1, 2, 2]
    assert cb.seam_edges_to_polygon_pairs([(1, 2), (2, 3), (0, 1)], tri_to_poly) == ([(0, 1), (1, 2)], [])
    assert cb.seam_edges_to_polygon_pairs([(1, 7)], tri_to_poly) == ([], [7])


def test_triangles_map_back_to_polygons(cb):
    tri_to_poly = [0, 0, 1, 2, 2]
    assert cb.triangles_to_polygons([1, 3, 4], tri_to_poly) == ([0, 2], [])
    assert cb.triangles_to_polygons([0, 9], tri_to_poly) == ([0], [9])


def test_has_command_reads_the_command_list(cb, prismbake_bin):
    assert cb.has_command(prismbake_bin, "render")
    assert cb.has_command(prismbake_bin, "validate")
    assert not cb.has_command(prismbake_bin, "teleport")
    assert not cb.has_command("/nonexistent/prismbake", "render")


def test_job_runs_in_the_background_and_is_polled(cb, prismbake_bin):
    job = cb.CliJob([prismbake_bin, "--version"]).start()
    deadline = time.monotonic() + 30
    while job.poll() is None:
        assert time.monotonic() < deadline
        time.sleep(0.01)
    assert job.result.returncode == 0 and "prismbake" in job.result.stdout
    assert job.poll() is job.result


def test_job_of_a_missing_binary_fails_to_start(cb):
    with pytest.raises(cb.BridgeError, match="cannot run /nonexistent/prismbake"):
        cb.CliJob(["/nonexistent/prismbake", "render"]).start()


def test_cancel_kills_the_process_group(cb, tmp_path):
    script = tmp_path / "slow.sh"
    script.write_text("#!/bin/sh\nsleep 30 &\necho $! > " + str(tmp_path / "child") + "\nwait\n")
    script.chmod(0o755)
    job = cb.CliJob([str(script), "render"]).start()
    deadline = time.monotonic() + 10
    while not (tmp_path / "child").exists() or not (tmp_path / "child").read_text().strip():
        assert time.monotonic() < deadline
        time.sleep(0.01)
    child = int((tmp_path / "child").read_text())
    t0 = time.monotonic()
    result = job.cancel()
    assert result.cancelled and time.monotonic() - t0 < 5
    assert "cancelled" in result.error_message()
    deadline = time.monotonic() + 5
    while _alive(child):
        assert time.monotonic() < deadline, f"child {child} of the cancelled job still runs"
        time.sleep(0.02)


def _alive(pid):
    """Running (not gone, not a zombie waiting for a reaper that is not us)."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] not in ("Z", "X")
    except FileNotFoundError:
        return False


def test_wait_with_timeout_stops_the_process(cb, tmp_path):
    job = cb.CliJob(["sleep", "30"]).start()
    with pytest.raises(cb.BridgeError, match="took longer than"):
        job.wait(timeout=0.2)
    assert job.result.cancelled


def test_chatty_process_does_not_block_on_a_full_pipe(cb):
    # 4 MB on stdout: a pipe nobody reads would fill at 64 KB and hang the process.
    job = cb.CliJob([sys.executable, "-c", "import sys; sys.stdout.write('x' * 4_000_000)"]).start()
    result = job.wait(timeout=30)
    assert result.returncode == 0 and len(result.stdout) == 4_000_000


def test_progress_counts_new_frames_only(cb, tmp_path):
    (tmp_path / "normal_0000.png").write_bytes(b"")
    since = time.time() + 1
    os.utime(tmp_path / "normal_0000.png", (since - 10, since - 10))
    (tmp_path / "normal_0001.png").write_bytes(b"")
    os.utime(tmp_path / "normal_0001.png", (since + 1, since + 1))
    (tmp_path / "mask_0001.png").write_bytes(b"")
    assert cb.count_files(str(tmp_path), ".png", prefix="normal_", since=since) == 1
    assert cb.progress_text("render", 1.25, 3, 24) == "prismbake render: 1.2 s, frame 3/24 (Esc to cancel)"

"""Shared fixtures for the Python tests: the prismbake binary built by `cargo test`."""
import json
import os
import pathlib
import struct
import subprocess
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]


@pytest.fixture(scope="session")
def prismbake():
    """Path of the binary; the README test command builds it before running pytest."""
    path = os.environ.get("PRISMBAKE_BIN", str(ROOT / "target" / "debug" / "prismbake"))
    assert os.path.isfile(path), f"{path} is missing: run `cargo build` first"
    return path


@pytest.fixture
def blender():
    """`blender(script, *args)`: run `script` under the real bpy (a fresh Python, its arguments
    `args`) and return the JSON it prints on its `RESULT ` line."""
    def _blender(script, *args):
        proc = subprocess.run([sys.executable, "-c", script, *map(str, args)], capture_output=True,
                              text=True, timeout=300)
        line = next((l for l in proc.stdout.splitlines() if l.startswith("RESULT ")), None)
        assert line, proc.stderr[-2000:]
        return json.loads(line[len("RESULT "):])
    return _blender


@pytest.fixture
def run(prismbake):
    def _run(*args, check=None):
        proc = subprocess.run([prismbake, *map(str, args)], capture_output=True, text=True)
        if check is not None:
            assert proc.returncode == check, f"exit {proc.returncode}\n{proc.stdout}\n{proc.stderr}"
        return proc
    return _run


@pytest.fixture
def examples():
    return ROOT / "examples"


@pytest.fixture
def edited_sphere(tmp_path):
    """`edit(name, change)`: a copy of the example sphere as `tmp_path/NAME.glb` with its glTF
    JSON changed by `change(doc)`, and a sidecar naming the example's map."""
    def edit(name, change):
        glb = (ROOT / "examples" / "sphere" / "sphere.glb").read_bytes()
        n = struct.unpack("<I", glb[12:16])[0]
        doc = json.loads(glb[20:20 + n])
        change(doc)
        text = json.dumps(doc).encode()
        text += b" " * (-len(text) % 4)
        rest = glb[20 + n:]
        out = tmp_path / f"{name}.glb"
        out.write_bytes(struct.pack("<III", 0x46546C67, 2, 20 + len(text) + len(rest))
                        + struct.pack("<II", len(text), 0x4E4F534A) + text + rest)
        side = (ROOT / "examples" / "sphere" / "sphere.prismbake.toml").read_text()
        side = side.replace('"../maps/', '"' + str(ROOT / "examples" / "maps") + "/")
        (tmp_path / f"{name}.prismbake.toml").write_text(side)
        return out
    return edit

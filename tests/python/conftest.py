"""Shared fixtures for the Python tests: the prismbake binary built by `cargo test`."""
import os
import pathlib
import subprocess

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]


@pytest.fixture(scope="session")
def prismbake():
    """Path of the binary; the README test command builds it before running pytest."""
    path = os.environ.get("PRISMBAKE_BIN", str(ROOT / "target" / "debug" / "prismbake"))
    assert os.path.isfile(path), f"{path} is missing: run `cargo build` first"
    return path


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

"""Paths and names the add-on tests share (a plain module: two conftest.py files in one pytest
run cannot both be imported as `conftest`)."""
import pathlib

ADDON = pathlib.Path(__file__).resolve().parents[1]
ROOT = ADDON.parent
REPO_MODULE = "prismbake_tests"
PACKAGE = f"bl_ext.{REPO_MODULE}.prismbake"
MAP = ROOT / "examples" / "maps" / "scales_256.png"

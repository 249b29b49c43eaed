#!/usr/bin/env bash
# The whole test suite, from a fresh clone on Debian 12: system packages, then every Rust test
# (unit + integration, CLI end to end). `.ci/run` calls exactly this.
set -euo pipefail
cd "$(dirname "$0")"

SUDO=""
if [ "$(id -u)" != 0 ] && command -v sudo >/dev/null; then SUDO=sudo; fi
if command -v apt-get >/dev/null; then
  need=()
  for p in build-essential pkg-config mesa-vulkan-drivers libvulkan1 python3-venv \
           libx11-6 libxrender1 libxfixes3 libxi6 libxkbcommon0 libxext6 libsm6 libice6 libgl1; do
    dpkg -s "$p" >/dev/null 2>&1 || need+=("$p")
  done
  if [ ${#need[@]} -gt 0 ]; then
    $SUDO apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq "${need[@]}"
  fi
  # The GPU tests run on lavapipe: Debian 13's Mesa, from bookworm-backports on Debian 12.
  if [ "${PRISMBAKE_SYSTEM_MESA:-0}" != 1 ]; then
    . scripts/mesa_backports.sh
    mesa_backports "$SUDO"
  fi
fi
if ! command -v cargo >/dev/null && [ -f "$HOME/.cargo/env" ]; then . "$HOME/.cargo/env"; fi

# Python side first: the Blender add-on's tests need the real bpy wheel, and the `--denoise`
# tests use the Open Image Denoise that wheel ships (tests/denoise.rs).
PY=${PYTHON:-python3}
if [ ! -x .venv/bin/python ]; then "$PY" -m venv .venv; fi
.venv/bin/python -m pip install -q -r tests/python/requirements.txt

# One profile (dev, dependencies optimised) for unit tests, integration tests and the binary.
# No incremental caches: a fresh clone never reuses them, and they took 588 MB of the 1.8 GB
# target folder (a CI machine once ran out of disk linking the examples).
export CARGO_INCREMENTAL=0
cargo test --workspace --locked
# The GPU suite again on wgpu's GL backend: what a machine without Vulkan drivers renders with
# (docs/gpu.md, "wgpu's GL backend").
# One test thread: wgpu's GL device is one EGL context behind a lock that panics after 6 s
# ("Could not lock adapter context"), and with Mesa's shader cache cold (as in CI) one test's
# kernel compilation can hold it that long while another test waits (seen twice in three cold
# runs with two threads; cold, one thread takes 74 s against 59 s).
# `--workspace --test gpu`, not `-p prismbake-gpu`: the workspace's features, so the binary
# built above runs again (`-p` alone resolved other features and rebuilt the core library and
# its dependencies: 5 min 37 s and 260 MB in a fresh-clone run).
WGPU_BACKEND=gl cargo test --workspace --test gpu --locked -- --test-threads=1

# The Blender add-on against the real bpy wheel, USD output against Pixar's usd-core, JUnit
# output against a JUnit consumer. They drive the binary built above.
export PRISMBAKE_BIN="$PWD/target/debug/prismbake"
HOME="$(mktemp -d)" .venv/bin/python -m pytest -q tests/python blender_addon/tests

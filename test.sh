#!/usr/bin/env bash
# The whole test suite, from a fresh clone on Debian 12: system packages, then every Rust test
# (unit + integration, CLI end to end). `.ci/run` calls exactly this.
set -euo pipefail
cd "$(dirname "$0")"

SUDO=""
if [ "$(id -u)" != 0 ] && command -v sudo >/dev/null; then SUDO=sudo; fi
if command -v apt-get >/dev/null; then
  need=()
  for p in build-essential pkg-config mesa-vulkan-drivers libvulkan1; do
    dpkg -s "$p" >/dev/null 2>&1 || need+=("$p")
  done
  if [ ${#need[@]} -gt 0 ]; then
    $SUDO apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq "${need[@]}"
  fi
fi
if ! command -v cargo >/dev/null && [ -f "$HOME/.cargo/env" ]; then . "$HOME/.cargo/env"; fi

# One profile (dev, dependencies optimised) for unit tests, integration tests and the binary.
cargo test --workspace --locked

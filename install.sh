#!/usr/bin/env bash
# Install prismbake on a fresh Debian 12 machine: system packages, a Rust toolchain if there is
# none, then `cargo install` of the `prismbake` binary into ~/.cargo/bin.
set -euo pipefail
cd "$(dirname "$0")"

SUDO=""
if [ "$(id -u)" != 0 ] && command -v sudo >/dev/null; then SUDO=sudo; fi
if command -v apt-get >/dev/null; then
  need=()
  for p in build-essential pkg-config ca-certificates curl mesa-vulkan-drivers libvulkan1; do
    dpkg -s "$p" >/dev/null 2>&1 || need+=("$p")
  done
  if [ ${#need[@]} -gt 0 ]; then
    $SUDO apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq "${need[@]}"
  fi
fi

if ! command -v cargo >/dev/null; then
  if [ -f "$HOME/.cargo/env" ]; then . "$HOME/.cargo/env"; fi
fi
if ! command -v cargo >/dev/null; then
  curl -sSf https://sh.rustup.rs | sh -s -- -y --profile minimal
  . "$HOME/.cargo/env"
fi

cargo install --locked --quiet --path cli
echo "installed: $(command -v prismbake || echo "$HOME/.cargo/bin/prismbake")"

#!/usr/bin/env bash
# Install prismbake on a fresh Debian 12 machine: system packages, a Rust toolchain if there is
# none, `cargo install` of the `prismbake` binary into ~/.cargo/bin, then Intel Open Image
# Denoise for `render --denoise` (PRISMBAKE_NO_OIDN=1 skips it; scripts/install_oidn.sh).
set -euo pipefail
cd "$(dirname "$0")"

SUDO=""
if [ "$(id -u)" != 0 ] && command -v sudo >/dev/null; then SUDO=sudo; fi
if command -v apt-get >/dev/null; then
  need=()
  for p in build-essential pkg-config ca-certificates curl mesa-vulkan-drivers libvulkan1 \
           python3 python3-pip; do
    dpkg -s "$p" >/dev/null 2>&1 || need+=("$p")
  done
  if [ ${#need[@]} -gt 0 ]; then
    $SUDO apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq "${need[@]}"
  fi
  # Opt-in: a faster lavapipe (the GPU path without a GPU) from bookworm-backports.
  if [ "${PRISMBAKE_MESA_BACKPORTS:-0}" = 1 ]; then
    . scripts/mesa_backports.sh
    mesa_backports "$SUDO"
  fi
fi

if ! command -v cargo >/dev/null; then
  if [ -f "$HOME/.cargo/env" ]; then . "$HOME/.cargo/env"; fi
fi
if ! command -v cargo >/dev/null; then
  curl -sSf https://sh.rustup.rs | sh -s -- -y --profile minimal
  . "$HOME/.cargo/env"
fi

# Built on the machine it runs on, so for its CPU (AVX2/FMA where there are: ~10% faster
# traces, docs/benchmarks.md). PRISMBAKE_PORTABLE=1 builds for the baseline of the
# architecture instead: a binary to copy to other machines (a render farm's nodes).
if [ "${PRISMBAKE_PORTABLE:-0}" = 1 ]; then
  cargo install --locked --quiet --path cli
else
  RUSTFLAGS="${RUSTFLAGS:-} -C target-cpu=native" cargo install --locked --quiet --path cli
fi
echo "installed: $(command -v prismbake || echo "$HOME/.cargo/bin/prismbake")"

if [ "${PRISMBAKE_NO_OIDN:-0}" != 1 ]; then
  . scripts/install_oidn.sh
  install_oidn
fi

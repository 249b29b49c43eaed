# Sourced by test.sh and install.sh: on Debian 12, replace the system's Mesa 22.3 Vulkan
# drivers with bookworm-backports' (Mesa 25, the version Debian 13 ships). lavapipe, Mesa's
# software Vulkan and the GPU path's device on machines without a GPU, renders the example
# assets' AOVs 3-4x faster there: Mesa 22.3 runs the body of every `if` in a shader, under a
# mask, whether any SIMD lane takes it or not; later versions branch over it (docs/gpu.md,
# "lavapipe versions").
#
# mesa_backports SUDO: does nothing off Debian 12 or with Mesa >= 24 installed; on failure
# (no network, no backports mirror) it warns and leaves the system's Mesa, which also works.
mesa_backports() {
  local sudo="$1" version codename
  codename=$(. /etc/os-release 2>/dev/null && echo "${VERSION_CODENAME:-}")
  [ "$codename" = bookworm ] || return 0
  version=$(dpkg-query -W -f='${Version}' mesa-vulkan-drivers 2>/dev/null || echo 0)
  if dpkg --compare-versions "$version" ge 24; then return 0; fi
  echo "lavapipe: Mesa $version -> bookworm-backports (set PRISMBAKE_SYSTEM_MESA=1 to keep it)" >&2
  if echo "deb http://deb.debian.org/debian bookworm-backports main" \
       | $sudo tee /etc/apt/sources.list.d/bookworm-backports.list >/dev/null \
     && $sudo apt-get update -qq \
     && DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq -o Dpkg::Use-Pty=0 -t bookworm-backports \
          mesa-vulkan-drivers; then
    echo "lavapipe: Mesa $(dpkg-query -W -f='${Version}' mesa-vulkan-drivers)" >&2
  else
    echo "warning: bookworm-backports' Mesa could not be installed; keeping Mesa $version" >&2
  fi
}

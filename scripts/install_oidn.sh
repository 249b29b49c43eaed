# Intel Open Image Denoise for `prismbake render --denoise`, sourced by install.sh.
#
# prismbake loads the library at run time (core/src/render/denoise.rs) from
# ${XDG_DATA_HOME:-~/.local/share}/prismbake/oidn/lib. Debian 12 does not package it; the x86-64
# Linux build comes from PyPI's `pyoidn` wheel (Intel's OIDN 2.5.1 libraries, Apache-2.0),
# pinned by its SHA-256. Only the CPU device is kept: the library, its core (the trained
# weights), the CPU device and TBB, about 60 MB. A failure warns and leaves prismbake
# without --denoise; it never fails the install.

OIDN_WHEEL_VERSION=2.5.1.0
OIDN_WHEEL_SHA256=32ad13368f8de1ef63001942ad05b02a00cd732d1206d97f352d3a3f606d823e

install_oidn() {
  # The libraries find each other through their run path, $ORIGIN/../lib: a folder named lib.
  local dest="${XDG_DATA_HOME:-$HOME/.local/share}/prismbake/oidn/lib"
  if [ -f "$dest/libOpenImageDenoise.so.2" ]; then
    echo "denoiser: $dest (already installed)"
    return 0
  fi
  if [ "$(uname -s)-$(uname -m)" != Linux-x86_64 ]; then
    echo "warning: no Open Image Denoise download for $(uname -s) $(uname -m); --denoise needs PRISMBAKE_OIDN set to a libOpenImageDenoise" >&2
    return 0
  fi
  local tmp
  tmp="$(mktemp -d)"
  if ! python3 -m pip download --quiet --no-deps --only-binary=:all: --dest "$tmp" \
        "pyoidn==$OIDN_WHEEL_VERSION" >/dev/null 2>&1; then
    echo "warning: could not download Open Image Denoise (pyoidn $OIDN_WHEEL_VERSION from PyPI); prismbake works, --denoise needs PRISMBAKE_OIDN" >&2
    rm -rf "$tmp"
    return 0
  fi
  local wheel="$tmp/pyoidn-$OIDN_WHEEL_VERSION-py3-none-manylinux2014_x86_64.whl"
  if ! echo "$OIDN_WHEEL_SHA256  $wheel" | sha256sum --check --status; then
    echo "warning: the Open Image Denoise wheel's SHA-256 is not the pinned one; not installed" >&2
    rm -rf "$tmp"
    return 0
  fi
  # Unpacked beside the folder, then renamed: never a half-installed library.
  rm -rf "$dest.part"
  mkdir -p "$dest.part"
  if ! python3 - "$wheel" "$dest.part" <<'PY'
import sys, zipfile, os
wheel, dest = sys.argv[1], sys.argv[2]
keep = {
    "libOpenImageDenoise.so.2",
    "libOpenImageDenoise_core.so.2.5.1",
    "libOpenImageDenoise_device_cpu.so.2.5.1",
    "libtbb.so.12",
}
with zipfile.ZipFile(wheel) as z:
    for name in z.namelist():
        base = os.path.basename(name)
        if name.startswith("pyoidn/oidn/lib/") and base in keep:
            part = os.path.join(dest, base + ".part")
            with z.open(name) as src, open(part, "wb") as out:
                out.write(src.read())
            os.replace(part, os.path.join(dest, base))
            keep.discard(base)
if keep:
    sys.exit("missing from the wheel: " + ", ".join(sorted(keep)))
PY
  then
    echo "warning: could not unpack Open Image Denoise into $dest; --denoise needs PRISMBAKE_OIDN" >&2
    rm -rf "$tmp" "$dest.part"
    return 0
  fi
  rm -rf "$tmp" "$dest"
  mv "$dest.part" "$dest"
  echo "denoiser: Open Image Denoise 2.5.1 in $dest"
}

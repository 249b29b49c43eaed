#!/usr/bin/env bash
# The prepared real-GPU run of docs/gpu.md ("Running on a real GPU"): one script, one call, so
# a session that is lent a GPU machine spends its minutes measuring, not typing.
#
#   examples/scripts/gpu_device_check.sh [PRISMBAKE] [OUT]
#
# PRISMBAKE: the release binary (default target/release/prismbake; build it first, where the
# machine has no toolchain carry it). OUT: where the renders and summary.json go (default
# $OUT, else ./gpu_check). Per asset: 2048² primary rays (AOVs depth,normal,mask) as a 3-frame
# turntable and 2048² beauty at SPP samples per pixel as a 2-frame one, the fastest frame after
# the first timed (the first includes pipeline compilation); the same AOV job at 512² on the
# CPU for the ratio, after a beauty frame that warms the card. Prints per job the frame's wall
# time (files included), its trace time
# (tracing, dispatches and read-back, no files) and its kernels' own time (GPU timestamp
# queries, where the adapter has them), and Mrays/s (pixels × spp over the kernel time, else
# the trace time); writes them to summary.json.
#
# Beside the default beauty (2 bounces, environment only) each asset renders the issue's
# "4 rays per pixel" sample as a 2-frame turntable: --bounces 1 --key-light 30,45,3 (per pixel
# that hits: the camera ray, the key light's and the environment's shadow rays and the
# continuation), once per value of TRACE_PIXELS (default "1 4 8": PRISMBAKE_GPU_TRACE_PIXELS,
# pixels per invocation of the wavefront's trace kernel; docs/gpu.md, "Rays per invocation").
# The summary's md5 of each beauty frame shows that they all give the same picture.
#
# The AOV job runs once per BVH walk in WALKS (default "ray packet": PRISMBAKE_GPU_WALK; docs/gpu.md,
# "Packets on lavapipe"): a GPU takes the per-ray walk by default, and whether a subgroup's
# packet pays there is not known yet (on an adapter without subgroups the packet job fails
# with a message naming them, and the summary skips it).
#
# With PRISMBAKE_OIDN set (Open Image Denoise carried to the machine: install.sh's
# ~/.local/share/prismbake/oidn/lib, 54 MB), the sphere's 16-spp beauty is also denoised at
# each quality, on the host's cores (docs/denoising.md): the summary's denoise_seconds.
#
# Smaller runs (to check the script itself on lavapipe): RES=256 SPP=2 ASSETS=sphere.
set -euo pipefail
cd "$(dirname "$0")/../.."
BIN=${1:-target/release/prismbake}
DEST=${2:-${OUT:-gpu_check}}
RES=${RES:-2048}
SPP=${SPP:-64}
ASSETS=${ASSETS:-"sphere torus rock"}
TRACE_PIXELS=${TRACE_PIXELS:-"1 4 8"}
WALKS=${WALKS:-"ray packet"}
mkdir -p "$DEST"
[ -x "$BIN" ] || { echo "gpu_device_check: no binary at $BIN (cargo build --release -p prismbake-cli)" >&2; exit 2; }

asset_path() {
  case "$1" in
    sphere) echo examples/sphere/sphere.glb ;;
    torus) echo examples/torus/torus.obj ;;
    rock) echo examples/rock/rock.glb ;;
    *) echo "gpu_device_check: unknown asset $1" >&2; exit 2 ;;
  esac
}

# job NAME RES SPP FRAMES DEVICE ASSET -- extra render flags: runs one render with --json, keeps
# its summary as DEST/NAME.json.
job() {
  local name=$1 res=$2 spp=$3 frames=$4 device=$5 asset=$6
  shift 6
  local turntable=()
  [ "$frames" -gt 1 ] && turntable=(--turntable "$frames")
  echo "== $name: $asset ${res}² spp $spp frames $frames on $device" >&2
  "$BIN" render "$asset" --device "$device" --res "${res}x${res}" --spp "$spp" \
    "${turntable[@]}" --json -o "$DEST/$name" "$@" > "$DEST/$name.json"
}

# A card idles at low clocks and short AOV frames (milliseconds of kernel between host work)
# do not raise them: on an NVIDIA H200 the same 2048² frames took 6–12 ms in one run and
# 43–75 ms in another, cold. A beauty frame first warms the card (its summary is kept apart).
job warmup "$RES" 16 1 gpu "$(asset_path torus)" --aov beauty

for a in $ASSETS; do
  path=$(asset_path "$a")
  for w in $WALKS; do
    PRISMBAKE_GPU_WALK=$w job "${a}_aov_gpu_$w" "$RES" 1 3 gpu "$path" --aov depth,normal,mask ||
      echo "gpu_device_check: the $w walk failed on this adapter (above)" >&2
  done
  job "${a}_beauty_gpu" "$RES" "$SPP" 2 gpu "$path" --aov beauty
  job "${a}_aov_cpu_512" 512 1 3 cpu "$path" --aov depth,normal,mask
  for k in $TRACE_PIXELS; do
    PRISMBAKE_GPU_TRACE_PIXELS=$k job "${a}_4rays_trace$k" "$RES" "$SPP" 2 gpu "$path" --aov beauty \
      --bounces 1 --key-light 30,45,3
  done
done

DENOISE=""
if [ -n "${PRISMBAKE_OIDN:-}" ]; then
  DENOISE="high balanced fast"
  for q in $DENOISE; do
    job "sphere_denoise_$q" "$RES" 16 2 gpu "$(asset_path sphere)" --aov beauty --denoise "$q"
  done
fi

python3 - "$DEST" "$RES" "$SPP" "$ASSETS" "$TRACE_PIXELS" "$DENOISE" "$WALKS" <<'PY'
import hashlib, json, pathlib, sys
dest, res, spp, assets = pathlib.Path(sys.argv[1]), int(sys.argv[2]), int(sys.argv[3]), sys.argv[4].split()
trace_pixels = sys.argv[5].split()
walks = sys.argv[7].split()
rows = []
denoised = []
for q in sys.argv[6].split():
    d = json.loads((dest / f"sphere_denoise_{q}.json").read_text())
    secs = [f["denoise_seconds"] for f in d["frames"]]
    print(f"denoise {q:<8} {res}²: {', '.join(f'{s:.3f}' for s in secs)} s per frame ({d['denoiser']})")
    denoised.append({"job": f"sphere_denoise_{q}", "res": res, "denoise_seconds": secs, "frames": d["frames"]})
for a in assets:
    jobs = [(f"{a}_aov_gpu_{w}", res, 1) for w in walks if (dest / f"{a}_aov_gpu_{w}.json").stat().st_size > 0]
    jobs += [(f"{a}_beauty_gpu", res, spp), (f"{a}_aov_cpu_512", 512, 1)]
    jobs += [(f"{a}_4rays_trace{k}", res, spp) for k in trace_pixels]
    for job, r, s in jobs:
        d = json.loads((dest / f"{job}.json").read_text())
        frames = d["frames"]
        timed = frames[1:] if len(frames) > 1 else frames
        # The fastest frame (by its kernels' time where measured); its trace time (tracing,
        # dispatches, read-back: no files) and, where the adapter has timestamp queries, its
        # kernels' own time.
        best = min(timed, key=lambda f: f.get("device_seconds") or f["trace_seconds"])
        kernel = best.get("device_seconds")
        sec = kernel if kernel else best["trace_seconds"]
        # Rays per pixel per sample (beauty: closest-hit, key-light and environment shadow
        # rays) and the last frame's picture, to see that settings that should agree do.
        rays = d.get("beauty_rays")
        per_pixel = {k: round(v / (r * r * s * len(frames)), 3) for k, v in rays.items()} if rays and rays.get("rays") else None
        last = sorted((dest / job).glob("beauty_*.exr"))
        picture = hashlib.md5(last[-1].read_bytes()).hexdigest()[:12] if last else None
        rows.append({"job": job, "device": d.get("device"), "walk": d.get("gpu_walk"),
                     "map_encoding": d.get("gpu_map_encoding"), "res": r, "spp": s,
                     "ms_per_sample": round(sec * 1e3 / s, 2), "rays_per_pixel": per_pixel,
                     "picture_md5": picture,
                     "ms_per_frame": round(best["seconds"] * 1e3, 2),
                     "trace_ms": round(best["trace_seconds"] * 1e3, 2),
                     "kernel_ms": round(kernel * 1e3, 3) if kernel else None,
                     "mrays_per_s": round(r * r * s / sec / 1e6, 2),
                     "mrays_per_s_from": "kernel" if kernel else "trace",
                     "frames": frames})
(dest / "summary.json").write_text(json.dumps(rows + denoised, indent=1))
for row in rows:
    kernel = f"{row['kernel_ms']:>9.3f}" if row["kernel_ms"] is not None else "        -"
    print(f"{row['job']:<24} {row['res']}² spp {row['spp']:<3} frame {row['ms_per_frame']:>9.2f} ms "
          f"trace {row['trace_ms']:>9.2f} ms kernels {kernel} ms ({row['ms_per_sample']} ms/sample) "
          f"{row['mrays_per_s']:>9.2f} Mrays/s ({row['mrays_per_s_from']}; {row['device']})"
          + (f" rays/px/sample {row['rays_per_pixel']} md5 {row['picture_md5']}" if row["rays_per_pixel"] else ""))
PY

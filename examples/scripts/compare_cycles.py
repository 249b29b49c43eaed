"""Compare prismbake against Blender Cycles' true displacement on one glTF asset: the picture
(mask mismatch, normal angle error) and the cost (seconds, peak memory) from one run.

    .venv/bin/python examples/scripts/compare_cycles.py examples/sphere/sphere.glb \
        --disp examples/maps/rock_1024.png --scale 0.08 [--res 512] [--cycles-tool PATH]

Runs the project's Cycles reference tool (shared/tools/cycles_reference.py: adaptive dicing at
0.5 px, CPU, 2 threads, 1 spp) and `prismbake render --method pdm` with the same glTF camera,
then prints one JSON line (an asset without a glTF camera gets the tool's default camera on both sides). Needs bpy==5.0.1, OpenEXR and numpy (tests/python/requirements.txt).
"""
import argparse
import json
import os
import pathlib
import resource
import subprocess
import sys
import tempfile
import time

import numpy as np
import OpenEXR

ROOT = pathlib.Path(__file__).resolve().parents[2]


def read_exr(path):
    f = OpenEXR.File(str(path))
    ch = f.parts[0].channels
    if "RGB" in ch:
        return np.asarray(ch["RGB"].pixels, dtype=np.float64)
    if "Y" in ch:
        return np.asarray(ch["Y"].pixels, dtype=np.float64)
    return np.stack([np.asarray(ch[c].pixels, dtype=np.float64) for c in "RGB"], -1)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("asset")
    ap.add_argument("--disp", required=True)
    ap.add_argument("--scale", type=float, required=True)
    ap.add_argument("--midlevel", type=float, default=0.5)
    ap.add_argument("--res", type=int, default=512)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--prismbake", default=os.environ.get("PRISMBAKE_BIN", str(ROOT / "target/release/prismbake")))
    ap.add_argument("--extra", default="", help="more prismbake render flags in one string, e.g. \"--normal geometric\"")
    ap.add_argument("--cycles-tool", default=str(ROOT.parent / "shared/tools/cycles_reference.py"))
    a = ap.parse_args()
    out = pathlib.Path(tempfile.mkdtemp(prefix="pb-cycles-"))
    env = dict(os.environ, HOME=str(out / "home"))
    cyc = subprocess.run([sys.executable, a.cycles_tool, a.asset, "--disp", a.disp, "--scale", str(a.scale),
                          "--midlevel", str(a.midlevel), "-o", str(out / "cycles"), "--res", str(a.res),
                          "--spp", "1", "--threads", str(a.threads)], capture_output=True, text=True, env=env)
    if cyc.returncode != 0:
        sys.exit(f"cycles failed:\n{cyc.stderr[-2000:]}")
    cinfo = json.loads((out / "cycles" / "timing.json").read_text())
    # Run prismbake under a fresh Python parent so its peak RSS is its own, not Cycles'.
    wrapper = ("import resource, subprocess, sys; p = subprocess.run(sys.argv[1:], capture_output=True, text=True); "
               "sys.stdout.write(p.stdout); sys.stderr.write(p.stderr); "
               "sys.stderr.write('\\nPEAK_RSS_KB %d\\n' % resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss); sys.exit(p.returncode)")
    # Without a glTF camera the Cycles tool places its own (Blender (0, -4, 2.5) looking at the
    # origin, 50 mm lens on a 36 mm sensor); give prismbake the same one in the glTF frame.
    inspect = subprocess.run([a.prismbake, "inspect", a.asset, "--json"], capture_output=True, text=True)
    camera = []
    if inspect.returncode == 0 and not json.loads(inspect.stdout).get("camera", False):
        camera = ["--camera-from", "0,2.5,4", "--camera-to", "0,0,0", "--fov", "39.6"]
    t = time.perf_counter()
    pb = subprocess.run([sys.executable, "-c", wrapper, a.prismbake, "render", a.asset, "--disp", a.disp, "--scale", str(a.scale),
                         "--midlevel", str(a.midlevel), "--res", f"{a.res}x{a.res}", "--aov", "mask,normal",
                         "--threads", str(a.threads), "-o", str(out / "pb"), "--json", *camera, *a.extra.split()], capture_output=True, text=True)
    wall = time.perf_counter() - t
    if pb.returncode != 0:
        sys.exit(f"prismbake failed:\n{pb.stderr}")
    rss_mb = int(pb.stderr.rsplit("PEAK_RSS_KB", 1)[1].split()[0]) // 1024
    summary = json.loads(pb.stdout)
    frame_s = summary["frames"][0]["seconds"]
    cm = read_exr(out / "cycles" / "mask.exr") > 0.5
    pm = read_exr(out / "pb" / "mask.exr") > 0.5
    cn = read_exr(out / "cycles" / "normal.exr")
    pn = read_exr(out / "pb" / "normal.exr")
    both = cm & pm
    dots = np.clip(np.sum(cn[both] * pn[both], -1) / (np.linalg.norm(cn[both], axis=-1) * np.linalg.norm(pn[both], axis=-1) + 1e-12), -1, 1)
    ang = np.degrees(np.arccos(dots))
    res = {
        "asset": a.asset, "res": a.res,
        "cycles_render_s": cinfo["render_seconds"], "cycles_peak_rss_mb": cinfo["peak_rss_mb"],
        "prismbake_frame_s": round(frame_s, 4), "prismbake_total_s": round(wall, 3),
        "prismbake_setup_s": round(summary["setup_seconds"], 4), "prismbake_peak_rss_mb": rss_mb,
        "speedup_frame": round(cinfo["render_seconds"] / frame_s, 1),
        "speedup_total": round(cinfo["render_seconds"] / wall, 1),
        "memory_ratio": round(rss_mb / max(cinfo["peak_rss_mb"], 1), 3),
        "mask_mismatch": round(float(np.mean(cm != pm)), 5),
        "normal_err_median_deg": round(float(np.median(ang)), 2) if ang.size else None,
        "normal_err_p90_deg": round(float(np.percentile(ang, 90)), 2) if ang.size else None,
    }
    print(json.dumps(res))


if __name__ == "__main__":
    main()

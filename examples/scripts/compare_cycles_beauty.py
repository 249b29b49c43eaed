"""Compare prismbake's lookdev beauty against Blender Cycles' on one glTF or USD asset: the
same displaced surface, camera, material, HDRI environment and the file's lights (as Blender's
importer makes them), rendered by both; prints one JSON line of the differences.

    .venv/bin/python examples/scripts/compare_cycles_beauty.py examples/sphere/sphere.glb \
        [--res 128] [--spp 256] [--roughness 0.5] [--metallic 0] [--clearcoat 0]
        [--clearcoat-roughness 0.03] [--env-rotate 0] [--file-materials]

The environment is a generated 128 x 64 equirect OpenEXR whose colour changes with azimuth
and elevation (red, green, blue and yellow quarters around the horizon, a blue sky above), so a
turned or mirrored environment shows in the asset's colour, not only in its shading. Cycles: Principled BSDF (base colour, roughness, metallic, IOR 1.5, i.e. F0 = 0.04),
true displacement with adaptive dicing at 0.5 px, 4 bounces, no clamping, no denoising, box
pixel filter, the Environment Texture node (linear interpolation). prismbake: `render --aov
beauty --env` with `--base-color`, `--roughness`, `--metallic`, `--specular 0.04`,
`--clearcoat`, `--clearcoat-roughness` (Blender's Coat Weight and Coat Roughness), `--bounces
4`. With `--file-materials` both keep the asset's own materials instead (Blender's importer's
node trees, the displacement added to each; prismbake with no material flags): textures,
normal maps, emission and all; a `--clearcoat` above 0 is then set on each (Blender: every
Principled BSDF's Coat Weight and Roughness). Both write linear EXRs; the comparison reads those.

Reports, over the asset's pixels (one pixel in from its silhouette, where pixels mix surface
and sky): each renderer's mean RGB, their ratio, and the mean |difference| relative to the mean
(Monte Carlo noise included: it shrinks with --spp); and over the whole image, the fraction of
pixels one covers and the other does not (alpha over 0.5: the silhouette, so the camera's
projection). Both EXRs leave the background transparent and black (Cycles' film transparent),
so the background is not compared. `--extra` passes more flags to prismbake. Needs bpy==5.0.1, OpenEXR and
numpy (tests/python/requirements.txt). The displacement comes from the asset's sidecar.
"""
import argparse
import json
import math
import os
import pathlib
import subprocess
import sys
import tempfile
import time
import tomllib

import numpy as np
import OpenEXR

ROOT = pathlib.Path(__file__).resolve().parents[2]


def write_env(path, w=128, h=64):
    """Quarters of colour around the horizon (by the image's u), a sky that blues towards the
    top (the image's first rows) and a darker ground."""
    u = (np.arange(w) + 0.5) / w
    v = (np.arange(h) + 0.5) / h
    uu, vv = np.meshgrid(u, v)
    quarter = np.floor(uu * 4).astype(int) % 4
    colours = np.array([[1.0, 0.2, 0.2], [0.2, 1.0, 0.2], [0.2, 0.3, 1.0], [1.0, 0.9, 0.2]])
    rgb = colours[quarter]
    # Smooth the quarters' borders a little so that bilinear lookups agree across them.
    elevation = (0.5 - vv) * math.pi
    sky = np.clip(np.sin(elevation), 0, 1)[..., None]
    ground = np.clip(-np.sin(elevation), 0, 1)[..., None]
    rgb = rgb * (1 - sky) * (1 - 0.7 * ground) + sky * np.array([0.3, 0.5, 1.5])
    hdr = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    OpenEXR.File(hdr, {"RGB": rgb.astype(np.float32)}).write(str(path))


def read_rgba(path, name="RGBA"):
    """The RGBA channel group `name` of an EXR (Cycles' multilayer: "ViewLayer.Combined")."""
    for p in OpenEXR.File(str(path)).parts:
        if name in p.channels:
            return np.asarray(p.channels[name].pixels, dtype=np.float64)
    sys.exit(f"{path}: no {name} channels")


def render_cycles(a, disp, out_exr, env):
    import bpy
    bpy.ops.wm.read_factory_settings(use_empty=True)
    if pathlib.Path(a.asset).suffix in (".usd", ".usda", ".usdc"):
        bpy.ops.wm.usd_import(filepath=os.path.abspath(a.asset))
    else:
        bpy.ops.import_scene.gltf(filepath=os.path.abspath(a.asset))
    sc = bpy.context.scene
    cams = [o for o in sc.objects if o.type == "CAMERA"]
    if not cams:
        sys.exit("the asset needs a glTF camera (both renderers then use it)")
    sc.camera = cams[0]
    img = bpy.data.images.load(os.path.abspath(disp["disp"]))
    img.colorspace_settings.name = "Non-Color"
    def displace(mat):
        # The height map through a Displacement node into the material's output.
        nt = mat.node_tree
        out = next(n for n in nt.nodes if n.type == "OUTPUT_MATERIAL")
        tex = nt.nodes.new("ShaderNodeTexImage")
        tex.image = img
        tex.interpolation = "Linear"
        d = nt.nodes.new("ShaderNodeDisplacement")
        d.inputs["Scale"].default_value = disp["scale"]
        d.inputs["Midlevel"].default_value = disp["midlevel"]
        nt.links.new(tex.outputs["Color"], d.inputs["Height"])
        nt.links.new(d.outputs["Displacement"], out.inputs["Displacement"])
        mat.displacement_method = "DISPLACEMENT"

    for ob in [o for o in sc.objects if o.type == "MESH"]:
        if a.file_materials:
            # The file's own materials, as Blender's importer built them (textures and all).
            mats = [m for m in ob.data.materials if m is not None]
            if not mats:
                sys.exit(f"{ob.name} has no material to keep (drop --file-materials)")
            for mat in mats:
                displace(mat)
                # --clearcoat over the file's materials: each Principled BSDF's Coat.
                if a.clearcoat > 0:
                    for n in mat.node_tree.nodes:
                        if n.type == "BSDF_PRINCIPLED":
                            n.inputs["Coat Weight"].default_value = a.clearcoat
                            n.inputs["Coat Roughness"].default_value = a.clearcoat_roughness
        else:
            mat = bpy.data.materials.new("lookdev")
            mat.use_nodes = True
            bsdf = mat.node_tree.nodes["Principled BSDF"]
            bsdf.inputs["Base Color"].default_value = (*a.base_color, 1.0)
            bsdf.inputs["Roughness"].default_value = a.roughness
            bsdf.inputs["Metallic"].default_value = a.metallic
            bsdf.inputs["IOR"].default_value = 1.5
            bsdf.inputs["Coat Weight"].default_value = a.clearcoat
            bsdf.inputs["Coat Roughness"].default_value = a.clearcoat_roughness
            displace(mat)
            ob.data.materials.clear()
            ob.data.materials.append(mat)
        m = ob.modifiers.new("subd", "SUBSURF")
        m.subdivision_type = "SIMPLE"
        m.use_adaptive_subdivision = True
        m.adaptive_pixel_size = 0.5
    world = bpy.data.worlds.new("hdri")
    world.use_nodes = True
    wt = world.node_tree
    envtex = wt.nodes.new("ShaderNodeTexEnvironment")
    envtex.image = bpy.data.images.load(str(env))
    envtex.interpolation = "Linear"
    wt.links.new(envtex.outputs["Color"], wt.nodes["Background"].inputs["Color"])
    sc.world = world
    sc.render.resolution_x = sc.render.resolution_y = a.res
    sc.render.resolution_percentage = 100
    sc.render.engine = "CYCLES"
    c = sc.cycles
    c.device = "CPU"
    c.samples = a.spp
    c.use_denoising = False
    c.use_adaptive_sampling = False
    c.pixel_filter_type = "BOX"
    c.filter_width = 1.0
    c.max_bounces = c.diffuse_bounces = c.glossy_bounces = 4
    c.sample_clamp_direct = c.sample_clamp_indirect = 0.0
    sc.render.threads_mode = "FIXED"
    sc.render.threads = a.threads
    # The background's alpha 0 (its light still reaches the asset): the coverage to compare.
    sc.render.film_transparent = True
    ims = sc.render.image_settings
    if hasattr(ims, "media_type"):
        ims.media_type = "MULTI_LAYER_IMAGE"
    ims.file_format = "OPEN_EXR_MULTILAYER"
    ims.color_depth = "32"
    sc.render.filepath = str(out_exr)
    t = time.perf_counter()
    bpy.ops.render.render(write_still=True)
    return time.perf_counter() - t


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("asset")
    ap.add_argument("--res", type=int, default=128)
    ap.add_argument("--spp", type=int, default=256)
    ap.add_argument("--roughness", type=float, default=0.5)
    ap.add_argument("--metallic", type=float, default=0.0)
    ap.add_argument("--base-color", type=lambda s: tuple(float(x) for x in s.split(",")), default=(0.8, 0.8, 0.8))
    ap.add_argument("--clearcoat", type=float, default=0.0, help="Coat Weight / --clearcoat")
    ap.add_argument("--clearcoat-roughness", type=float, default=0.03)
    ap.add_argument("--env-rotate", type=float, default=0.0, help="passed to prismbake's --env-rotate")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--prismbake", default=os.environ.get("PRISMBAKE_BIN", str(ROOT / "target/release/prismbake")))
    ap.add_argument("--keep", help="folder to keep the renders in")
    ap.add_argument("--extra", default="", help="more prismbake render flags in one string, e.g. \"--fov 30\"")
    ap.add_argument("--file-materials", action="store_true",
                    help="keep the asset's own materials (textures, normal maps, emission) in both "
                         "renderers, in place of --base-color, --roughness, --metallic and F0 0.04")
    a = ap.parse_args()
    sidecar = pathlib.Path(a.asset).with_name(pathlib.Path(a.asset).stem + ".prismbake.toml")
    side = tomllib.loads(sidecar.read_text())
    disp = {"disp": str(sidecar.parent / side["disp"]), "scale": side["scale"], "midlevel": side.get("midlevel", 0.5)}
    out = pathlib.Path(a.keep or tempfile.mkdtemp(prefix="pb-cycles-beauty-"))
    out.mkdir(parents=True, exist_ok=True)
    env = out / "env.exr"
    write_env(env)
    cycles_s = render_cycles(a, disp, out / "cycles.exr", env)
    coat = ["--clearcoat", str(a.clearcoat), "--clearcoat-roughness", str(a.clearcoat_roughness)]
    material_flags = (coat if a.clearcoat > 0 else []) if a.file_materials else [
        "--base-color", ",".join(map(str, a.base_color)), "--roughness", str(a.roughness),
        "--metallic", str(a.metallic), "--specular", "0.04", "--specular-tint", "1,1,1", *coat]
    t = time.perf_counter()
    pb = subprocess.run([a.prismbake, "render", a.asset, "--aov", "beauty", "--env", str(env),
                         "--env-rotate", str(a.env_rotate), "--res", f"{a.res}x{a.res}", "--spp", str(a.spp),
                         "--bounces", "4", *material_flags,
                         "--threads", str(a.threads), "-o", str(out / "pb"), *a.extra.split()],
                        capture_output=True, text=True)
    pb_s = time.perf_counter() - t
    if pb.returncode != 0:
        sys.exit(f"prismbake failed:\n{pb.stderr}")
    cyc = read_rgba(out / "cycles.exr", "ViewLayer.Combined")
    ours = read_rgba(out / "pb" / "beauty.exr")
    mask = ours[..., 3] > 0.5
    # One pixel in from the silhouette on both sides: edge pixels mix surface and sky.
    pad = np.pad(mask, 1, mode="edge")
    near = np.zeros_like(mask)
    for dy in (0, 1, 2):
        for dx in (0, 1, 2):
            near |= pad[dy:dy + mask.shape[0], dx:dx + mask.shape[1]] != mask
    obj = mask & ~near
    rel = lambda x, y: float(np.mean(np.abs(x - y)) / max(np.mean(np.abs(y)), 1e-9))
    res = {
        "asset": a.asset, "res": a.res, "spp": a.spp, "roughness": a.roughness, "metallic": a.metallic,
        "env_rotate": a.env_rotate, "file_materials": a.file_materials, "cycles_s": round(cycles_s, 2), "prismbake_s": round(pb_s, 2),
        "asset_pixels": int(obj.sum()),
        # Pixels one renderer covers and the other does not (alpha over 0.5), of all pixels.
        "mask_mismatch": round(float(np.mean(mask != (cyc[..., 3] > 0.5))), 5),
        "asset_mean_rgb_prismbake": [round(float(x), 4) for x in ours[obj][:, :3].mean(0)],
        "asset_mean_rgb_cycles": [round(float(x), 4) for x in cyc[obj][:, :3].mean(0)],
        "asset_rel_mean_abs_diff": round(rel(ours[obj][:, :3], cyc[obj][:, :3]), 4),
        "out": str(out),
    }
    res["asset_mean_ratio"] = [round(p / c, 4) if c else None for p, c in
                               zip(res["asset_mean_rgb_prismbake"], res["asset_mean_rgb_cycles"])]
    print(json.dumps(res))


if __name__ == "__main__":
    main()

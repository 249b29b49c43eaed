"""USD in and out, checked against the real tools: files written by Blender (`bpy`) and by
Pixar's `usd-core` load in prismbake, and what `prismbake export --usd` writes passes every
registered `pxr.UsdValidation` validator, `UsdGeom.Mesh.ValidateTopology` and reads back with
its displacement intact. Blender → USD → prismbake must render the same mask as
Blender → glTF → prismbake.

bpy runs in a subprocess: it bundles its own USD libraries, which must not meet usd-core's
in one process.
"""
import json
import pathlib
import struct
import subprocess
import sys
import textwrap
import zlib

import numpy as np
import OpenEXR
import pytest
from pxr import Gf, Sdf, Usd, UsdGeom, UsdShade, UsdValidation, Vt

ROOT = pathlib.Path(__file__).resolve().parents[2]
MAP = ROOT / "examples" / "maps" / "rock_1024.png"
ALBEDO = ROOT / "examples" / "maps" / "rock_albedo_256.png"
SCALE, MIDLEVEL = 0.1, 0.5

# Blender is Z-up; its glTF exporter writes Y-up: glTF (x, y, z) = Blender (x, z, -y).
CAM_GLTF = ("0.5,0.8,3.5", "0.5,0,0")
CAM_ZUP = ("0.5,-3.5,0.8", "0.5,0,0")

BLENDER_SCRIPT = textwrap.dedent(
    """
    import sys, bpy
    out, image = sys.argv[1], sys.argv[2]
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.mesh.primitive_uv_sphere_add(segments=32, ring_count=16, radius=1.0)
    ob = bpy.context.active_object
    bpy.ops.object.shade_smooth()
    ob.location = (0.5, 0.0, 0.0)
    mat = bpy.data.materials.new("Rock")
    mat.use_nodes = True
    nt = mat.node_tree
    tex = nt.nodes.new("ShaderNodeTexImage")
    tex.image = bpy.data.images.load(image)
    tex.image.colorspace_settings.name = "Non-Color"
    disp = nt.nodes.new("ShaderNodeDisplacement")
    disp.inputs["Midlevel"].default_value = %(mid)r
    disp.inputs["Scale"].default_value = %(scale)r
    nt.links.new(tex.outputs["Color"], disp.inputs["Height"])
    nt.links.new(disp.outputs["Displacement"], nt.nodes["Material Output"].inputs["Displacement"])
    ob.data.materials.append(mat)
    bpy.ops.wm.usd_export(filepath=out + ".usdc")
    bpy.ops.wm.usd_export(filepath=out + ".usda")
    bpy.ops.export_scene.gltf(filepath=out + ".glb")
    """
    % {"mid": MIDLEVEL, "scale": SCALE}
)


@pytest.fixture(scope="session")
def blender_sphere(tmp_path_factory):
    """A smooth UV sphere with an image-texture displacement material, exported by Blender
    as sphere.usdc, sphere.usda (textures copied to textures/) and sphere.glb."""
    d = tmp_path_factory.mktemp("blender")
    base = d / "sphere"
    proc = subprocess.run(
        [sys.executable, "-c", "import sys; exec(sys.stdin.read())", str(base), str(MAP)],
        input=BLENDER_SCRIPT, capture_output=True, text=True, timeout=300,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    for ext in ("usdc", "usda", "glb"):
        assert (d / f"sphere.{ext}").is_file(), f"Blender wrote no sphere.{ext}\n{proc.stderr[-2000:]}"
    return d


def read_mask(path):
    with OpenEXR.File(str(path)) as f:
        channels = f.channels()
        name = next(iter(channels))
        return np.asarray(channels[name].pixels, dtype=np.float32)


def render_mask(run, mesh, out, camera, *flags):
    run("render", mesh, *flags, "--aov", "mask", "--res", "64x64",
        "--camera-from", camera[0], "--camera-to", camera[1], "--no-jitter", "-o", out, check=0)
    return read_mask(out / "mask.exr")


def mismatch(a, b):
    assert a.shape == b.shape
    return float(np.mean((a > 0.5) != (b > 0.5)))


def quad_stage(path):
    """A new stage at `path` holding a 2 × 2 quad `/Quad` (corners ±1 in x and y, its `st` the
    unit square), for the light tests to add to."""
    stage = Usd.Stage.CreateNew(str(path))
    quad = UsdGeom.Mesh.Define(stage, "/Quad")
    quad.CreatePointsAttr([(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)])
    quad.CreateFaceVertexCountsAttr([4])
    quad.CreateFaceVertexIndicesAttr([0, 1, 2, 3])
    UsdGeom.PrimvarsAPI(quad).CreatePrimvar("st", Sdf.ValueTypeNames.TexCoord2fArray,
                                            UsdGeom.Tokens.vertex).Set([(0, 0), (1, 0), (1, 1), (0, 1)])
    return stage


def inspect(run, mesh, *flags):
    return json.loads(run("inspect", mesh, *flags, "--json", check=0).stdout)


def validate_stage(stage):
    """Every registered validator over the stage; returns the errors (all severities)."""
    registry = UsdValidation.ValidationRegistry()
    validators = registry.GetOrLoadAllValidators()
    assert len(validators) > 10, "usd-core registered no validators: the check would be empty"
    return UsdValidation.ValidationContext(validators).Validate(stage)


# ---- ingest ----

def test_blender_usdc_and_usda_load_like_its_gltf(run, blender_sphere):
    glb = inspect(run, blender_sphere / "sphere.glb", "--disp", MAP)
    for ext in ("usdc", "usda"):
        usd = inspect(run, blender_sphere / f"sphere.{ext}")
        assert usd["triangles"] == glb["triangles"], ext
        assert usd["vertices"] == glb["vertices"], f"{ext}: corners shared where point, normal and UV agree"
        assert usd["has_uvs"]
        # Same sphere, Z-up vs Y-up: bounds agree after the axis swap.
        lo, hi = usd["bounds_min"], usd["bounds_max"]
        g_lo, g_hi = glb["bounds_min"], glb["bounds_max"]
        assert np.allclose([lo[0], lo[2], -hi[1]], g_lo, atol=1e-4), (lo, hi, g_lo)
        assert np.allclose([hi[0], hi[2], -lo[1]], g_hi, atol=1e-4), (lo, hi, g_hi)


def test_blender_material_gives_the_displacement(run, blender_sphere):
    """No --disp and no sidecar: the map, scale and midlevel come from the USD material."""
    info = inspect(run, blender_sphere / "sphere.usdc")
    m = info["map"]
    assert pathlib.Path(m["path"]).name == MAP.name
    assert pathlib.Path(m["path"]).is_file()
    # D = S·(h − M) over the map's values: S 0.1 and M 0.5 as Blender's Displacement node set.
    assert m["displacement_min"] == pytest.approx(SCALE * (m["value_min"] - MIDLEVEL), abs=1e-6), m
    assert m["displacement_max"] == pytest.approx(SCALE * (m["value_max"] - MIDLEVEL), abs=1e-6), m


@pytest.mark.parametrize("ext", ["usdc", "usda"])
def test_blender_usd_renders_the_same_mask_as_its_gltf(run, blender_sphere, tmp_path, ext):
    flags = ("--disp", MAP, "--scale", SCALE, "--midlevel", MIDLEVEL)
    ref = render_mask(run, blender_sphere / "sphere.glb", tmp_path / "glb", CAM_GLTF, *flags)
    assert 0.1 < ref.mean() < 0.9, "the sphere fills part of the frame"
    flat = render_mask(run, blender_sphere / "sphere.glb", tmp_path / "flat", CAM_GLTF, "--disp", MAP, "--scale", 0)
    assert mismatch(ref, flat) > 0.01, "control: the displacement shows in the mask"
    usd = render_mask(run, blender_sphere / f"sphere.{ext}", tmp_path / "usd", CAM_ZUP, *flags)
    assert mismatch(ref, usd) <= 0.005
    # The same again with the displacement taken from the USD material instead of flags.
    own = render_mask(run, blender_sphere / f"sphere.{ext}", tmp_path / "own", CAM_ZUP)
    assert mismatch(ref, own) <= 0.005


CAMERA_SCRIPT = textwrap.dedent(
    """
    import sys, bpy
    from mathutils import Vector
    out = sys.argv[1]
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y = 64, 64
    bpy.ops.mesh.primitive_uv_sphere_add(segments=32, ring_count=16, radius=1.0)
    bpy.ops.object.shade_smooth()
    bpy.context.active_object.location = (0.5, 0.0, 0.0)
    bpy.ops.object.camera_add(location=(2.0, -5.0, 2.5))
    cam = bpy.context.active_object
    # Aimed off the sphere's centre, pitched down, a longer lens than the default framing's.
    cam.rotation_euler = (Vector((0.0, 0.0, 0.3)) - cam.location).to_track_quat("-Z", "Y").to_euler()
    cam.data.lens = 70.0
    scene.camera = cam
    bpy.ops.wm.usd_export(filepath=out + ".usda")
    bpy.ops.wm.usd_export(filepath=out + ".usdc")
    bpy.ops.export_scene.gltf(filepath=out + ".glb", export_cameras=True)
    """
)


def test_a_blender_camera_frames_the_usd_as_it_frames_the_gltf(run, tmp_path):
    """A camera Blender exports to USD (UsdGeomCamera: its transform, focal length and
    aperture) renders the asset as the same camera exported to glTF (yfov) does, with no
    camera flags; the framing from the bounds, which either would fall back to, differs."""
    base = tmp_path / "shot"
    proc = subprocess.run(
        [sys.executable, "-c", "import sys; exec(sys.stdin.read())", str(base)],
        input=CAMERA_SCRIPT, capture_output=True, text=True, timeout=300,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    flags = ("--disp", MAP, "--scale", SCALE, "--aov", "mask", "--res", "64x64", "--no-jitter")

    def mask(mesh, out, *extra):
        run("render", mesh, *flags, *extra, "-o", out, check=0)
        return read_mask(out / "mask.exr")

    gltf = mask(base.with_suffix(".glb"), tmp_path / "glb")
    assert 0.05 < gltf.mean() < 0.9, "the sphere is in the camera's view"
    for ext in ("usda", "usdc"):
        assert inspect(run, base.with_suffix(f".{ext}"), "--disp", MAP)["camera"] is True, ext
        usd = mask(base.with_suffix(f".{ext}"), tmp_path / ext)
        assert mismatch(gltf, usd) <= 0.005, ext
    framed = mask(base.with_suffix(".glb"), tmp_path / "framed", "--camera-to", "0.5,0,0")
    assert mismatch(gltf, framed) > 0.05, "control: the scene camera changes the picture"


# Blender's default plane (2 x 2, at the origin, its UVs the unit square) for the material
# tests: each test's script adds a material to `ob`, then `blender_plane` exports it. In the
# script, `halves(name, left, right)` saves an 8 x 8 PNG `<out>_<name>.png`, one RGBA colour
# on its left half and another on its right, and returns the image.
PLANE_PREAMBLE = textwrap.dedent(
    """
    import math, sys, bpy
    out = sys.argv[1]
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.mesh.primitive_plane_add(size=2.0)
    ob = bpy.context.active_object

    def halves(name, left, right, non_color=False):
        img = bpy.data.images.new(name, 8, 8, alpha=False)
        img.pixels[:] = [c for y in range(8) for x in range(8) for c in (left if x < 4 else right)]
        img.filepath_raw = out + "_" + name + ".png"
        img.file_format = "PNG"
        img.save()
        if non_color:
            img.colorspace_settings.name = "Non-Color"
        return img
    """
)
EXPORTERS = {
    "usda": 'bpy.ops.wm.usd_export(filepath=out + ".usda")',
    "glb": 'bpy.ops.export_scene.gltf(filepath=out + ".glb")',
    "obj": 'bpy.ops.wm.obj_export(filepath=out + ".obj")',
}
# The same view of the plane in either frame (Blender's Z-up; glTF's and OBJ's Y-up).
PLANE_CAMERAS = {"glb": "0,5,0.5", "usda": "0,-0.5,5", "obj": "0,5,0.5"}


def blender_plane(tmp_path, script, *formats):
    """Run the plane preamble, `script` and the exporters of `formats` in Blender; the files'
    common path without extension."""
    base = tmp_path / "plane"
    body = PLANE_PREAMBLE + script + "\n".join(EXPORTERS[f] for f in formats) + "\n"
    proc = subprocess.run(
        [sys.executable, "-c", "import sys; exec(sys.stdin.read())", str(base)],
        input=body, capture_output=True, text=True, timeout=300,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    return base


def render_plane(run, base, ext, out, *flags, scale="0", spp="2"):
    """The plane's beauty, 32 x 32, head-on: (the summary's JSON, the RGBA pixels)."""
    proc = run("render", base.with_suffix(f".{ext}"), "--disp", MAP, "--scale", scale,
               "--aov", "beauty", "--res", "32x32", "--spp", spp, "--camera-from",
               PLANE_CAMERAS[ext], "--camera-to", "0,0,0", "--fov", "30", "--json", "-o", out,
               *flags, check=0)
    with OpenEXR.File(str(out / "beauty.exr")) as f:
        rgba = np.asarray(f.channels()["RGBA"].pixels, dtype=np.float64)
    return json.loads(proc.stdout), proc.stderr, rgba



MR_SCRIPT = textwrap.dedent(
    """
    # 8 x 8 texels: red unused (glTF's occlusion), green the roughness, blue the metallic;
    # the left half a rough dielectric, the right half a smooth metal.
    img = halves("orm", [1.0, 1.0, 0.0, 1.0], [0.0, 0.08, 1.0, 1.0], non_color=True)
    mat = bpy.data.materials.new("HalfMetal")
    mat.use_nodes = True
    nt = mat.node_tree
    bsdf = nt.nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (0.9, 0.9, 0.9, 1)
    tex = nt.nodes.new("ShaderNodeTexImage")
    tex.image = img
    sep = nt.nodes.new("ShaderNodeSeparateColor")
    nt.links.new(tex.outputs["Color"], sep.inputs["Color"])
    nt.links.new(sep.outputs["Green"], bsdf.inputs["Roughness"])
    nt.links.new(sep.outputs["Blue"], bsdf.inputs["Metallic"])
    ob.data.materials.append(mat)
    """
)


def test_blender_roughness_and_metallic_textures_shade_from_gltf_and_usd_alike(run, tmp_path):
    """A Blender material whose roughness and metallic come from one image's green and blue
    (glTF: a metallicRoughnessTexture; USD: a raw UsdUVTexture's `g` and `b` outputs) renders
    its rough dielectric half lit and its smooth metal half dark under a key light, and the
    same beauty from either file."""
    base = blender_plane(tmp_path, MR_SCRIPT, "usda", "glb")
    images = {}
    for ext in ("glb", "usda"):
        summary, _, rgba = render_plane(run, base, ext, tmp_path / ext, "--env-intensity", "0",
                                        "--key-light", "30,40,3", scale="0.001", spp="4")
        (m,) = summary["materials"]
        assert (m["roughness"], m["metallic"]) == (1.0, 1.0), m
        assert m["roughness_texture"].endswith("8x8, repeat/repeat, bilinear, channel g"), m
        assert m["metallic_texture"].endswith("8x8, repeat/repeat, bilinear, channel b"), m
        lum = rgba[..., :3] @ [0.2126, 0.7152, 0.0722]
        left, right = lum[10:22, 6:12].mean(), lum[10:22, 20:26].mean()
        assert left > 0.1 and left > 10 * right, (ext, left, right)
        images[ext] = rgba
    assert np.abs(images["glb"] - images["usda"]).mean() < 1e-4


NM_SCRIPT = textwrap.dedent(
    """
    # 8 x 8 tangent-space normals: the left half tilted 20 degrees towards -u, the right half
    # towards +u (the plane's u runs along +x).
    s, c = math.sin(math.radians(20)), math.cos(math.radians(20))
    img = halves("normal", [(1 - s) / 2, 0.5, (c + 1) / 2, 1.0], [(1 + s) / 2, 0.5, (c + 1) / 2, 1.0],
                 non_color=True)
    mat = bpy.data.materials.new("Tilted")
    mat.use_nodes = True
    nt = mat.node_tree
    bsdf = nt.nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (0.9, 0.9, 0.9, 1)
    bsdf.inputs["Roughness"].default_value = 1.0
    tex = nt.nodes.new("ShaderNodeTexImage")
    tex.image = img
    nmap = nt.nodes.new("ShaderNodeNormalMap")
    nt.links.new(tex.outputs["Color"], nmap.inputs["Color"])
    nt.links.new(nmap.outputs["Normal"], bsdf.inputs["Normal"])
    ob.data.materials.append(mat)
    """
)


def test_blender_normal_maps_shade_from_gltf_usd_and_obj_alike(run, tmp_path):
    """A Blender material with a Normal Map node (glTF: a normalTexture; USD: a UsdUVTexture's
    rgb on `normal` with scale 2 and bias -1; OBJ: map_Bump) bends the shading normal: under
    a key light 60 degrees off the plane's normal, the half tilted 20 degrees towards it is
    lit by about cos 40 / cos 80 times the other half, and the three files render the same
    beauty; --no-normal-maps shades both halves alike."""
    base = blender_plane(tmp_path, NM_SCRIPT, "usda", "glb", "obj")
    images = {}
    lights = ("--env-intensity", "0", "--bounces", "1", "--specular", "0", "--key-light", "90,30,3")
    for ext in PLANE_CAMERAS:
        summary, _, rgba = render_plane(run, base, ext, tmp_path / ext, *lights)
        (m,) = summary["materials"]
        assert m["normal_texture"].endswith("8x8, repeat/repeat, bilinear, strength 1"), (ext, m)
        lum = rgba[..., :3] @ [0.2126, 0.7152, 0.0722]
        left, right = lum[10:22, 6:12].mean(), lum[10:22, 20:26].mean()
        assert 3.5 * left < right < 5.5 * left, (ext, left, right)
        images[ext] = rgba
        if ext == "glb":
            _, _, flat = render_plane(run, base, ext, tmp_path / "flat", *lights, "--no-normal-maps")
            lum = flat[..., :3] @ [0.2126, 0.7152, 0.0722]
            left, right = lum[10:22, 6:12].mean(), lum[10:22, 20:26].mean()
            assert abs(left - right) < 1e-3 * right, (left, right)
    for ext in ("usda", "obj"):
        assert np.abs(images["glb"] - images[ext]).mean() < 1e-4, ext


EMISSION_SCRIPT = textwrap.dedent(
    """
    mat = bpy.data.materials.new("Lamp")
    mat.use_nodes = True
    bsdf = mat.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (0, 0, 0, 1)
    bsdf.inputs["Emission Color"].default_value = (1.0, 0.5, 0.25, 1)
    bsdf.inputs["Emission Strength"].default_value = 2.0
    ob.data.materials.append(mat)
    """
)


def test_blender_emission_glows_from_gltf_usd_and_obj_alike(run, tmp_path):
    """A Principled BSDF's Emission (colour (1, 0.5, 0.25), strength 2) exported to .glb
    (emissiveFactor and KHR_materials_emissive_strength), .usda (emissiveColor) and .obj (Ke)
    renders, in the dark, a black plane of radiance (2, 1, 0.5) from each."""
    base = blender_plane(tmp_path, EMISSION_SCRIPT, "usda", "glb", "obj")
    for ext in PLANE_CAMERAS:
        summary, _, rgba = render_plane(run, base, ext, tmp_path / ext, "--env-intensity", "0")
        (m,) = summary["materials"]
        assert m["emission"] == pytest.approx([2.0, 1.0, 0.5]), (ext, m)
        assert np.allclose(rgba[10:22, 10:22, :3].mean(axis=(0, 1)), [2.0, 1.0, 0.5], atol=1e-4), ext


MAPPING_SCRIPT = textwrap.dedent(
    """
    # 8 x 8 texels, red on the left half, blue on the right.
    img = halves("color", [1.0, 0.2, 0.1, 1.0], [0.1, 0.3, 1.0, 1.0])
    mat = bpy.data.materials.new("Mapped")
    mat.use_nodes = True
    nt = mat.node_tree
    tex = nt.nodes.new("ShaderNodeTexImage")
    tex.image = img
    # Tiled twice, turned a quarter, shifted a quarter.
    mapping = nt.nodes.new("ShaderNodeMapping")
    mapping.inputs["Location"].default_value = (0.25, 0.0, 0.0)
    mapping.inputs["Rotation"].default_value = (0.0, 0.0, math.radians(90))
    mapping.inputs["Scale"].default_value = (2.0, 2.0, 1.0)
    coord = nt.nodes.new("ShaderNodeTexCoord")
    nt.links.new(coord.outputs["UV"], mapping.inputs["Vector"])
    nt.links.new(mapping.outputs["Vector"], tex.inputs["Vector"])
    nt.links.new(tex.outputs["Color"], nt.nodes["Principled BSDF"].inputs["Base Color"])
    ob.data.materials.append(mat)
    """
)


def test_blender_mapping_node_reads_the_same_from_gltf_and_usd(run, tmp_path):
    """A Blender Mapping node (scale, rotation, location) on a colour texture, which Blender
    writes as glTF's KHR_texture_transform and as a USD UsdTransform2d, renders the same
    beauty from either file: the transformed texture (turned stripes), not the image as it
    lies."""
    base = blender_plane(tmp_path, MAPPING_SCRIPT, "usda", "glb")
    assert "UsdTransform2d" in base.with_suffix(".usda").read_text()
    images = {}
    for ext in ("glb", "usda"):
        _, stderr, images[ext] = render_plane(run, base, ext, tmp_path / ext, "--env-intensity",
                                              "0", "--key-light", "30,60,3")
        assert "warning" not in stderr, stderr
    # Turned a quarter, the halves run across the image's rows: red and blue alternate down
    # its middle column, where the image as it lies would be one colour.
    column = images["usda"][6:26, 16, :3]
    assert (column[:, 0] > column[:, 2]).any() and (column[:, 2] > column[:, 0]).any(), column
    assert np.abs(images["glb"] - images["usda"]).mean() < 1e-4


SUBSETS_SCRIPT = textwrap.dedent(
    """
    bpy.ops.object.mode_set(mode="EDIT")
    bpy.ops.mesh.subdivide(number_cuts=1)
    bpy.ops.object.mode_set(mode="OBJECT")
    for name, color in (("Red", (0.8, 0.05, 0.05, 1)), ("Blue", (0.05, 0.05, 0.8, 1))):
        mat = bpy.data.materials.new(name)
        mat.use_nodes = True
        mat.node_tree.nodes["Principled BSDF"].inputs["Base Color"].default_value = color
        ob.data.materials.append(mat)
    # The faces right of x = 0 take the second material.
    for poly in ob.data.polygons:
        poly.material_index = 1 if poly.center.x > 0 else 0
    """
)


def test_blender_material_slots_shade_their_faces_from_gltf_and_usd_alike(run, tmp_path):
    """A Blender mesh with two material slots (glTF: a primitive each; USD: GeomSubsets of
    family materialBind, each with its binding) shades its left faces red and its right faces
    blue from either file, the same beauty."""
    base = blender_plane(tmp_path, SUBSETS_SCRIPT, "usda", "glb")
    assert "GeomSubset" in base.with_suffix(".usda").read_text()
    images = {}
    for ext in ("glb", "usda"):
        summary, _, rgba = render_plane(run, base, ext, tmp_path / ext)
        prisms = sorted(m["prisms"] for m in summary["materials"])
        assert prisms == [4, 4], (ext, prisms)
        left, right = rgba[10:22, 6:12, :3].mean(axis=(0, 1)), rgba[10:22, 20:26, :3].mean(axis=(0, 1))
        assert left[0] > 4 * left[2] and right[2] > 4 * right[0], (ext, left, right)
        images[ext] = rgba
    assert np.abs(images["glb"] - images["usda"]).mean() < 1e-4


def make_usd_core_mesh(path):
    """A quad + triangle mesh under transformed Xforms, with indexed faceVarying st and a
    UsdUVTexture displacement (scale 0.2, bias -0.1 → S 0.2, M 0.5), written by usd-core."""
    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    root = UsdGeom.Xform.Define(stage, "/World")
    root.AddTranslateOp().Set(Gf.Vec3d(1, 2, 3))
    root.AddRotateXYZOp().Set(Gf.Vec3f(0, 0, 90))
    child = UsdGeom.Xform.Define(stage, "/World/Part")
    child.AddScaleOp().Set(Gf.Vec3f(2, 2, 2))
    mesh = UsdGeom.Mesh.Define(stage, "/World/Part/Panel")
    mesh.CreatePointsAttr([(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (2, 0.5, 0)])
    mesh.CreateFaceVertexCountsAttr([4, 3])
    mesh.CreateFaceVertexIndicesAttr([0, 1, 2, 3, 1, 4, 2])
    mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
    st = UsdGeom.PrimvarsAPI(mesh).CreatePrimvar("st", Sdf.ValueTypeNames.TexCoord2fArray, UsdGeom.Tokens.faceVarying)
    st.Set([(0, 0), (0.5, 0), (0.5, 1), (0, 1), (1, 0.5)])
    st.SetIndices(Vt.IntArray([0, 1, 2, 3, 1, 4, 2]))
    mat = UsdShade.Material.Define(stage, "/World/Looks/M")
    surf = UsdShade.Shader.Define(stage, "/World/Looks/M/Surface")
    surf.CreateIdAttr("UsdPreviewSurface")
    tex = UsdShade.Shader.Define(stage, "/World/Looks/M/Height")
    tex.CreateIdAttr("UsdUVTexture")
    tex.CreateInput("file", Sdf.ValueTypeNames.Asset).Set(Sdf.AssetPath(str(MAP)))
    tex.CreateInput("scale", Sdf.ValueTypeNames.Float4).Set(Gf.Vec4f(0.2, 0.2, 0.2, 1))
    tex.CreateInput("bias", Sdf.ValueTypeNames.Float4).Set(Gf.Vec4f(-0.1, -0.1, -0.1, 0))
    tex.CreateInput("wrapS", Sdf.ValueTypeNames.Token).Set("clamp")
    tex.CreateInput("wrapT", Sdf.ValueTypeNames.Token).Set("clamp")
    reader = UsdShade.Shader.Define(stage, "/World/Looks/M/Reader")
    reader.CreateIdAttr("UsdPrimvarReader_float2")
    reader.CreateInput("varname", Sdf.ValueTypeNames.String).Set("st")
    tex.CreateInput("st", Sdf.ValueTypeNames.Float2).ConnectToSource(reader.ConnectableAPI(), "result")
    surf.CreateInput("displacement", Sdf.ValueTypeNames.Float).ConnectToSource(tex.ConnectableAPI(), "r")
    mat.CreateSurfaceOutput().ConnectToSource(surf.ConnectableAPI(), "surface")
    mat.CreateDisplacementOutput().ConnectToSource(surf.ConnectableAPI(), "displacement")
    UsdShade.MaterialBindingAPI.Apply(mesh.GetPrim()).Bind(mat)
    stage.SetDefaultPrim(root.GetPrim())
    stage.GetRootLayer().Save()
    world = UsdGeom.BBoxCache(Usd.TimeCode.Default(), [UsdGeom.Tokens.default_]).ComputeWorldBound(mesh.GetPrim())
    return world.ComputeAlignedRange()


@pytest.mark.parametrize("ext", ["usda", "usdc"])
def test_usd_core_mesh_loads_with_transforms_and_material(run, tmp_path, ext):
    path = tmp_path / f"panel.{ext}"
    box = make_usd_core_mesh(path)
    info = inspect(run, path)
    assert info["triangles"] == 2 + 1
    assert np.allclose(info["bounds_min"], list(box.GetMin()), atol=1e-5), (info, box)
    assert np.allclose(info["bounds_max"], list(box.GetMax()), atol=1e-5), (info, box)
    assert info["uv_min"] == [0.0, 0.0] and info["uv_max"] == [1.0, 1.0]
    assert pathlib.Path(info["map"]["path"]) == MAP


@pytest.mark.parametrize("ext", ["usda", "usdc"])
def test_usd_core_preview_surface_shades_the_beauty(run, tmp_path, ext):
    """The bound UsdPreviewSurface's diffuse texture (through the mesh's own `st`), roughness
    and metallic are the beauty's material, from text and binary layers alike."""
    path = tmp_path / f"panel.{ext}"
    make_usd_core_mesh(path)
    stage = Usd.Stage.Open(str(path))
    surf = UsdShade.Shader.Get(stage, "/World/Looks/M/Surface")
    reader = UsdShade.Shader.Get(stage, "/World/Looks/M/Reader")
    albedo = UsdShade.Shader.Define(stage, "/World/Looks/M/Albedo")
    albedo.CreateIdAttr("UsdUVTexture")
    albedo.CreateInput("file", Sdf.ValueTypeNames.Asset).Set(Sdf.AssetPath(str(ALBEDO)))
    albedo.CreateInput("wrapS", Sdf.ValueTypeNames.Token).Set("mirror")
    albedo.CreateInput("st", Sdf.ValueTypeNames.Float2).ConnectToSource(reader.ConnectableAPI(), "result")
    surf.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).ConnectToSource(albedo.ConnectableAPI(), "rgb")
    surf.CreateInput("roughness", Sdf.ValueTypeNames.Float).Set(0.3)
    surf.CreateInput("metallic", Sdf.ValueTypeNames.Float).Set(0.25)
    stage.GetRootLayer().Save()
    proc = run("render", path, "--aov", "beauty", "--res", "32x32", "--spp", "2", "--json",
               "-o", tmp_path / "out", check=0)
    (m,) = json.loads(proc.stdout)["materials"]
    assert m["name"] == "/World/Looks/M" and m["prisms"] >= 3, m
    assert m["texture"] == "rock_albedo_256.png, 256x256, mirror/repeat, bilinear", m
    assert m["base_color"] == [1.0, 1.0, 1.0], m
    assert m["roughness"] == pytest.approx(0.3) and m["metallic"] == pytest.approx(0.25), m


def test_broken_usd_files_fail_cleanly(run, blender_sphere, tmp_path):
    data = (blender_sphere / "sphere.usdc").read_bytes()
    for n, cut in enumerate([0, 8, 88, len(data) // 3, len(data) - 16]):
        p = tmp_path / f"cut{n}.usdc"
        p.write_bytes(data[:cut])
        proc = run("inspect", p, "--disp", MAP)
        assert proc.returncode in (0, 2), proc.stderr
        assert "panicked" not in proc.stderr, proc.stderr
        if proc.returncode == 2:
            assert str(p.name) in proc.stderr, proc.stderr


# ---- export ----

@pytest.fixture(scope="session")
def exported(blender_sphere, prismbake, tmp_path_factory):
    """`prismbake export` of Blender's sphere.usdc (displacement from its material) into a
    folder of its own, so the texture path has to be relative across folders."""
    out = tmp_path_factory.mktemp("export") / "sub" / "sphere_out.usda"
    out.parent.mkdir()
    proc = subprocess.run([prismbake, "export", str(blender_sphere / "sphere.usdc"), "--usd", str(out)],
                          capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    return out


def test_export_passes_every_usd_validator(exported):
    stage = Usd.Stage.Open(str(exported))
    errors = validate_stage(stage)
    assert not errors, "\n".join(f"{e.GetName()}: {e.GetMessage()}" for e in errors)


def test_validators_do_catch_a_broken_export(exported, tmp_path):
    """Control: the same file without upAxis/metersPerUnit and with a dangling texture fails,
    so an empty error list above means something."""
    text = exported.read_text()
    text = text.replace('    metersPerUnit = 1\n', '').replace('    upAxis = "Z"\n', '')
    text = text.replace("rock_1024.png", "missing.png")
    bad = tmp_path / "bad.usda"
    bad.write_text(text)
    names = {e.GetName() for e in validate_stage(Usd.Stage.Open(str(bad)))}
    assert {"MissingUpAxisMetadata", "MissingMetersPerUnitMetadata", "UnresolvableDependency"} <= names, names


def test_export_topology_primvars_and_metadata(exported):
    stage = Usd.Stage.Open(str(exported))
    assert UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.z, "Blender's Z-up is kept"
    assert UsdGeom.GetStageMetersPerUnit(stage) == 1.0
    default = stage.GetDefaultPrim()
    assert default and default.GetPath() == Sdf.Path("/sphere")
    meshes = [UsdGeom.Mesh(p) for p in stage.Traverse() if p.IsA(UsdGeom.Mesh)]
    assert len(meshes) == 1
    mesh = meshes[0]
    counts = mesh.GetFaceVertexCountsAttr().Get()
    indices = mesh.GetFaceVertexIndicesAttr().Get()
    points = mesh.GetPointsAttr().Get()
    ok, why = UsdGeom.Mesh.ValidateTopology(indices, counts, len(points))
    assert ok, why
    primvars = UsdGeom.PrimvarsAPI(mesh)
    n_faces = len(counts)
    for name in ("prismbake:wmin", "prismbake:wmax"):
        pv = primvars.GetPrimvar(name)
        assert pv and pv.GetInterpolation() == UsdGeom.Tokens.uniform, name
        assert pv.GetTypeName() == Sdf.ValueTypeNames.FloatArray, name
        assert len(pv.Get()) == n_faces, f"{name}: one value per face"
    wmin = np.array(primvars.GetPrimvar("prismbake:wmin").Get())
    wmax = np.array(primvars.GetPrimvar("prismbake:wmax").Get())
    assert np.all(wmin <= wmax)
    assert wmin.min() >= -SCALE * MIDLEVEL - 1e-6 and wmax.max() <= SCALE * (1 - MIDLEVEL) + 1e-6
    st = primvars.GetPrimvar("st")
    assert st.GetInterpolation() == UsdGeom.Tokens.vertex and len(st.Get()) == len(points)
    assert len(mesh.GetNormalsAttr().Get()) == len(points)
    extent = mesh.GetExtentAttr().Get()
    computed = UsdGeom.Boundable.ComputeExtentFromPlugins(mesh, Usd.TimeCode.Default())
    assert all(extent[0][i] <= computed[0][i] + 1e-6 and extent[1][i] >= computed[1][i] - 1e-6 for i in range(3)), \
        "the extent holds the points (and the displaced shell around them)"


def test_export_material_carries_the_displacement(exported):
    stage = Usd.Stage.Open(str(exported))
    mesh = next(p for p in stage.Traverse() if p.IsA(UsdGeom.Mesh))
    material, _ = UsdShade.MaterialBindingAPI(mesh).ComputeBoundMaterial()
    assert material
    surface = material.ComputeDisplacementSource()[0]
    assert surface.GetIdAttr().Get() == "UsdPreviewSurface"
    sources, _ = surface.GetInput("displacement").GetConnectedSources()
    tex = UsdShade.Shader(sources[0].source.GetPrim())
    assert tex.GetIdAttr().Get() == "UsdUVTexture" and sources[0].sourceName == "r"
    scale = tex.GetInput("scale").Get()
    bias = tex.GetInput("bias").Get()
    assert scale[0] == pytest.approx(SCALE) and bias[0] == pytest.approx(-MIDLEVEL * SCALE)
    file = tex.GetInput("file").Get()
    assert file.path.startswith("../"), f"relative asset path, got {file.path}"
    assert pathlib.Path(file.resolvedPath).name == MAP.name
    assert pathlib.Path(file.resolvedPath).is_file(), "usd-core resolves the texture"


def test_export_reads_back_and_renders_the_same_mask(run, blender_sphere, exported, tmp_path):
    ref = render_mask(run, blender_sphere / "sphere.usdc", tmp_path / "src", CAM_ZUP)
    back = render_mask(run, exported, tmp_path / "back", CAM_ZUP)
    assert mismatch(ref, back) <= 0.005


def test_export_refuses_other_extensions(run, blender_sphere, tmp_path):
    proc = run("export", blender_sphere / "sphere.usdc", "--usd", tmp_path / "x.usdc")
    assert proc.returncode == 2 and ".usda" in proc.stderr
    assert not (tmp_path / "x.usdc").exists()


BLENDER_DOME = textwrap.dedent(
    """
    import json, math, sys, bpy
    bpy.ops.wm.read_factory_settings(use_empty=False)
    bpy.ops.wm.usd_import(filepath=sys.argv[1], import_lights=True, create_world_material=True)
    nodes = bpy.context.scene.world.node_tree.nodes
    tint = next(n for n in nodes if n.type == "VECT_MATH").inputs[1].default_value
    strength = next(n for n in nodes if n.type == "BACKGROUND").inputs["Strength"].default_value
    turn = next(n for n in nodes if n.type == "MAPPING").inputs["Rotation"].default_value[2]
    image = next(n for n in nodes if n.type == "TEX_ENVIRONMENT").image.filepath
    sun = next(o for o in bpy.context.scene.objects if o.type == "LIGHT" and o.data.type == "SUN")
    toward = list(sun.matrix_world.col[2][:3])
    print("RESULT " + json.dumps({"tint": [c * strength for c in tint], "turn": math.degrees(turn),
                                  "image": image, "sun_toward": toward, "sun_energy": sun.data.energy,
                                  "sun_angle": math.degrees(sun.data.angle),
                                  "sun_color": list(sun.data.color)}))
    """
)


def test_usd_lights_light_the_beauty_as_blender_imports_them(run, blender, tmp_path):
    """A `UsdLux.DomeLight` written by usd-core (texture, colour, intensity, exposure, turned
    30° about the up axis) is the beauty's environment; Blender's own USD importer makes of it
    a world whose texture is tinted by the same colour × strength (but for the exposure, which
    it leaves out) and turned the same way:
    its mapping turns lookups by 90° − the dome's turn (Blender's centre column faces +X,
    OpenEXR's +Z, and Blender's Z-up is the stage's Y-up). A `DistantLight` beside it is the
    key light, pointing where Blender's sun points, in its colour (its width and strength are
    not UsdLux's in Blender: see below)."""
    sky = tmp_path / "sky.exr"
    sky.write_bytes((ROOT / "examples" / "maps" / "bumps_512.exr").read_bytes())
    path = tmp_path / "dome.usda"
    stage = quad_stage(path)
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    from pxr import UsdLux
    dome = UsdLux.DomeLight.Define(stage, "/Lights/Sky")
    dome.CreateTextureFileAttr(Sdf.AssetPath("sky.exr"))
    dome.CreateIntensityAttr(2.0)
    dome.CreateExposureAttr(1.0)
    dome.CreateColorAttr(Gf.Vec3f(1.0, 0.5, 0.25))
    UsdGeom.Xformable(dome.GetPrim()).AddRotateYOp().Set(30.0)
    sun = UsdLux.DistantLight.Define(stage, "/Lights/Sun")
    sun.CreateIntensityAttr(3.0)
    sun.CreateAngleAttr(4.0)
    sun.CreateNormalizeAttr(True)
    sun.CreateColorAttr(Gf.Vec3f(0.6, 0.8, 1.0))
    UsdGeom.Xformable(sun.GetPrim()).AddRotateXYZOp().Set(Gf.Vec3f(-50.0, 20.0, 0.0))
    stage.GetRootLayer().Save()

    proc = run("render", path, "--disp", MAP, "--scale", "0.05", "--aov", "beauty", "--res", "8x8",
               "--spp", "1", "--json", "-o", tmp_path / "out", check=0)
    summary = json.loads(proc.stdout)
    said = summary["environment"]
    assert said.startswith("the file's dome light '/Lights/Sky' (") and str(sky) in said, said
    tint = [float(x) for x in said.split("tint ")[1].split(", turned")[0].split(", ")]
    turn = float(said.split("turned ")[1].rstrip("°)"))
    assert tint == [4.0, 2.0, 1.0] and abs(turn - 30.0) < 1e-3, said

    theirs = blender(BLENDER_DOME, path)
    assert pathlib.Path(theirs["image"]).resolve() == sky.resolve(), theirs
    # Blender 5.0's importer leaves `inputs:exposure` out (UsdLux scales by 2^exposure).
    assert np.allclose(np.array(theirs["tint"]) * 2.0, tint, rtol=1e-4), (theirs, tint)
    assert abs((theirs["turn"] - (90.0 - turn) + 180.0) % 360.0 - 180.0) < 0.01, (theirs, turn)

    # The distant light: the same direction (ours in the stage's Y-up terms, Blender's Z-up:
    # (x, y, z) -> (x, -z, y)), irradiance and angle.
    key = summary["key_light"]
    assert key.startswith("the file's directional light '/Lights/Sun' ("), key
    az = np.radians(float(key.split("azimuth ")[1].split("°")[0]))
    el = np.radians(float(key.split("elevation ")[1].split("°")[0]))
    ours = np.array([np.sin(az) * np.cos(el), np.sin(el), np.cos(az) * np.cos(el)])
    blender_toward = np.array(theirs["sun_toward"]) / np.linalg.norm(theirs["sun_toward"])
    assert np.allclose([ours[0], -ours[2], ours[1]], blender_toward, atol=2e-3), (key, theirs)
    # UsdLux's angle is the disc's diameter, and normalized, the intensity is the irradiance.
    # Blender 5.0's importer makes a sun twice as wide (it reads the angle as a radius) and 4 ×
    # as strong whatever `normalize` says: only ours is held to UsdLux's here.
    # Normalized, the intensity is the light's luminance times its colour's; the colour is the
    # light's over its luminance (Blender keeps it as it is).
    luminance = 0.2126 * 0.6 + 0.7152 * 0.8 + 0.0722 * 1.0
    irradiance = float(key.split("irradiance ")[1].split(",")[0])
    colour = np.array([float(c) for c in key.split("colour (")[1].split(")")[0].split(",")])
    assert "4° across" in key and abs(irradiance - 3.0 * luminance) < 1e-4, key
    assert np.allclose(colour * luminance, theirs["sun_color"], rtol=2e-3), (key, theirs)
    assert abs(theirs["sun_angle"] - 8.0) < 1e-3 and abs(theirs["sun_energy"] - 12.0) < 1e-4, theirs


def test_a_lights_colour_temperature_tints_it_as_usd_lux_does(run, tmp_path):
    """`inputs:enableColorTemperature` (as Blender writes on every light it exports) tints a
    light by the black body at `inputs:colorTemperature`: a 3000 K distant light and sphere
    light take UsdLux's own colour for it (`UsdLux.BlackbodyTemperatureAsRgb`) within 2% a
    channel, times their `inputs:color`; without the switch the temperature is not read."""
    from pxr import UsdLux
    path = tmp_path / "warm.usda"
    stage = quad_stage(path)
    sun = UsdLux.DistantLight.Define(stage, "/Sun")
    sun.CreateEnableColorTemperatureAttr(True)
    sun.CreateColorTemperatureAttr(3000.0)
    bulb = UsdLux.SphereLight.Define(stage, "/Bulb")
    bulb.CreateEnableColorTemperatureAttr(True)
    bulb.CreateColorTemperatureAttr(3000.0)
    bulb.CreateColorAttr(Gf.Vec3f(0.5, 1.0, 1.0))
    cold = UsdLux.SphereLight.Define(stage, "/Cold")
    cold.CreateColorTemperatureAttr(3000.0)
    stage.GetRootLayer().Save()

    info = inspect(run, path, "--disp", MAP)
    colour = lambda said: np.array([float(c) for c in said.split("colour (")[1].split(")")[0].split(",")])
    lum = lambda c: c @ [0.2126, 0.7152, 0.0722]
    usd = np.array(UsdLux.BlackbodyTemperatureAsRgb(3000.0))
    for ours, want in ((colour(info["directional_light"]), usd),
                       (colour(info["lights"][0]), usd * [0.5, 1.0, 1.0])):
        assert np.allclose(ours, want / lum(want), rtol=0.02), (ours, want / lum(want))
    assert "colour" not in info["lights"][1], info["lights"]


BLENDER_AREA = textwrap.dedent(
    """
    import json, sys, bpy
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.wm.usd_import(filepath=sys.argv[1])
    out = {}
    for o in bpy.context.scene.objects:
        if o.type == "LIGHT":
            d = o.data
            out[o.name] = {"type": d.type, "shape": d.shape, "energy": d.energy, "size": d.size,
                           "size_y": d.size_y, "at": list(o.matrix_world.col[3][:3]),
                           "down": [-x for x in o.matrix_world.col[2][:3]]}
    print("RESULT " + json.dumps(out))
    """
)


def test_rect_and_disk_lights_light_as_blender_imports_them(run, blender, tmp_path):
    """A normalized `RectLight` and a `DiskLight` written by usd-core light the beauty where
    Blender's importer puts its area lamps, shining the same way. The normalized rect light
    has the radiance a Cycles area lamp of Blender's power has (P / (π × area)). The disk is
    not normalized: UsdLux makes its intensity its radiance, whatever its size; Blender's
    importer reads it as normalized all the same (P = π × intensity), so there the two differ
    by the disk's area, and the test pins that rather than copying it."""
    from pxr import UsdLux
    path = tmp_path / "areas.usda"
    stage = quad_stage(path)
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)  # Blender scales a centimetre stage to metres
    box = UsdLux.RectLight.Define(stage, "/Box")
    box.CreateWidthAttr(2.0)
    box.CreateHeightAttr(0.5)
    box.CreateIntensityAttr(31.830988)
    box.CreateNormalizeAttr(True)
    UsdGeom.Xformable(box.GetPrim()).AddTranslateOp().Set(Gf.Vec3d(0, 0, 3))
    disk = UsdLux.DiskLight.Define(stage, "/Round")
    disk.CreateRadiusAttr(0.4)
    disk.CreateIntensityAttr(5.0)
    xf = UsdGeom.Xformable(disk.GetPrim())
    xf.AddTranslateOp().Set(Gf.Vec3d(2, 0, 1))
    xf.AddRotateYOp().Set(-90.0)
    stage.GetRootLayer().Save()

    lights = inspect(run, path, "--disp", MAP)["lights"]
    theirs = blender(BLENDER_AREA, path)
    vec = lambda said, after: np.array([float(x) for x in said.split(after + " (")[1].split(")")[0].split(",")])
    radiance = lambda said: float(said.split("radiance ")[1].split(",")[0])
    for said, lamp in ((lights[0], theirs["Box"]), (lights[1], theirs["Round"])):
        assert lamp["type"] == "AREA", lamp
        # Z-up stage, Blender Z-up: the same coordinates.
        assert np.allclose(vec(said, "at"), lamp["at"], atol=1e-4), (said, lamp)
        assert np.allclose(vec(said, "shining along"), lamp["down"], atol=1e-4), (said, lamp)
    box, round_ = radiance(lights[0]), radiance(lights[1])
    assert abs(box - theirs["Box"]["energy"] / (np.pi * 2.0 * 0.5)) < 2e-3 * box, (lights[0], theirs["Box"])
    assert round_ == 5.0 and abs(theirs["Round"]["energy"] - np.pi * 5.0) < 1e-3, (lights[1], theirs["Round"])
    assert theirs["Box"]["shape"] == "RECTANGLE" and (theirs["Box"]["size"], theirs["Box"]["size_y"]) == (2.0, 0.5)
    assert theirs["Round"]["shape"] == "DISK" and abs(theirs["Round"]["size"] - 0.8) < 1e-6


OPACITY_USDA = """#usda 1.0
(
    upAxis = "Y"
)
def Xform "root"
{
    def Mesh "half"
    {
        int[] faceVertexCounts = [4]
        int[] faceVertexIndices = [0, 1, 2, 3]
        point3f[] points = [(-1, -1, -1), (1, -1, -1), (1, 1, -1), (-1, 1, -1)]
        texCoord2f[] primvars:st = [(0, 0), (1, 0), (1, 1), (0, 1)] (interpolation = "vertex")
        rel material:binding = </root/mats/half>
    }
    def Mesh "leaf"
    {
        int[] faceVertexCounts = [4]
        int[] faceVertexIndices = [0, 1, 2, 3]
        point3f[] points = [(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)]
        texCoord2f[] primvars:st = [(0, 0), (1, 0), (1, 1), (0, 1)] (interpolation = "vertex")
        rel material:binding = </root/mats/leaf>
    }
    def Scope "mats"
    {
        def Material "half"
        {
            token outputs:surface.connect = </root/mats/half/pbr.outputs:surface>
            def Shader "pbr"
            {
                uniform token info:id = "UsdPreviewSurface"
                float inputs:opacity = 0.5
                token outputs:surface
            }
        }
        def Material "leaf"
        {
            token outputs:surface.connect = </root/mats/leaf/pbr.outputs:surface>
            def Shader "pbr"
            {
                uniform token info:id = "UsdPreviewSurface"
                float inputs:opacity.connect = </root/mats/leaf/tex.outputs:a>
                float inputs:opacityThreshold = 0.3
                token outputs:surface
            }
            def Shader "tex"
            {
                uniform token info:id = "UsdUVTexture"
                asset inputs:file = @leaf.png@
                token inputs:wrapS = "clamp"
                token inputs:wrapT = "clamp"
                float2 inputs:st.connect = </root/mats/leaf/st.outputs:result>
                float outputs:a
            }
            def Shader "st"
            {
                uniform token info:id = "UsdPrimvarReader_float2"
                string inputs:varname = "st"
                float2 outputs:result
            }
        }
    }
}
"""

BLENDER_ALPHA = textwrap.dedent(
    """
    import json, sys, bpy
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.wm.usd_import(filepath=sys.argv[1])
    out = {}
    for m in bpy.data.materials:
        n = next(x for x in m.node_tree.nodes if x.type == "BSDF_PRINCIPLED")
        cut = [x.inputs[1].default_value for x in m.node_tree.nodes
               if x.type == "MATH" and x.operation == "LESS_THAN"]
        out[m.name] = {"alpha": n.inputs["Alpha"].default_value,
                       "linked": n.inputs["Alpha"].is_linked, "cutoff": cut}
    print("RESULT " + json.dumps(out))
    """
)


def test_usd_opacity_cuts_the_surface_as_blender_imports_it(run, blender, tmp_path):
    """UsdPreviewSurface's opacity is the Principled BSDF's Alpha (a value: blended), and a
    UsdUVTexture's `a` on it under an opacityThreshold is cut at the threshold, as Blender's
    importer wires them: the textured quad's transparent half is out of the mask AOV, and the
    half-opaque quad behind it shows through it with half its samples."""
    size = 4
    raw = b"".join(b"\x00" + b"".join(bytes([255, 255, 255, 0 if x < size // 2 else 255])
                                      for x in range(size)) for _ in range(size))
    chunk = lambda t, d: (struct.pack(">I", len(d)) + t + d
                          + struct.pack(">I", zlib.crc32(t + d) & 0xFFFFFFFF))
    (tmp_path / "leaf.png").write_bytes(
        b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", size, size, 8, 6, 0, 0, 0))
        + chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b""))
    usda = tmp_path / "alpha.usda"
    usda.write_text(OPACITY_USDA)
    theirs = blender(BLENDER_ALPHA, usda)
    ours = {m["name"]: m for m in json.loads(run("inspect", usda, "--json", check=0).stdout)["materials"]}
    assert theirs["half"] == {"alpha": 0.5, "linked": False, "cutoff": []}, theirs
    assert theirs["leaf"]["linked"] and theirs["leaf"]["cutoff"] == [pytest.approx(0.3)], theirs
    assert ours["/root/mats/half"]["alpha"] == "blend, alpha 0.5", ours
    assert ours["/root/mats/leaf"]["alpha"] == "mask at 0.3, alpha 1 x texture leaf.png, alpha channel", ours
    out = tmp_path / "out"
    run("render", usda, "--disp", MAP, "--scale", "0", "--aov", "mask", "--res", "32x32", "--spp",
        "64", "--camera-from", "0,0,6", "--camera-to", "0,0,0", "--fov", "30", "-o", out, check=0)
    with OpenEXR.File(str(out / "mask.exr")) as f:
        mask = np.asarray(list(f.channels().values())[0].pixels, dtype=np.float64)
    left, right = mask[11:21, 8:13].mean(), mask[11:21, 19:24].mean()
    # The leaf's left half is cut away: the half-opaque quad behind shows with half its
    # samples; its right half covers every one.
    assert abs(left - 0.5) < 0.08 and right == 1.0, (left, right)

"""Each operator against the real CLI, run synchronously (`execute`), and their error paths."""
import json
import os
import subprocess
import time

import numpy as np
import OpenEXR
import pytest

from pbtest import MAP


def exr_channel(path, name=None):
    channels = OpenEXR.File(str(path)).channels()
    return np.asarray(channels[name or next(iter(channels))].pixels, dtype=np.float64)


def test_preview_loads_an_image_named_for_the_object(bpy_module, addon, scene):
    bpy = bpy_module
    assert bpy.ops.prismbake.preview() == {"FINISHED"}
    image = bpy.data.images["prismbake preview: Sphere"]
    assert tuple(image.size) == (64, 64)
    assert image.packed_file is not None  # survives the temporary folder and a .blend save
    px = np.empty(64 * 64 * 4, dtype=np.float32)
    image.pixels.foreach_get(px)
    assert px.reshape(-1, 4)[:, :3].max() > 0.1, "the preview is black"
    record = addon.jobs.RESULTS["Sphere"]["preview"]
    assert {os.path.basename(f) for f in record.files} >= {"normal.png", "mask.png", "mask.exr"}


def test_preview_mask_matches_a_direct_cli_render_of_the_same_export(bpy_module, addon, scene, prismbake_bin,
                                                                     tmp_path):
    assert bpy_module.ops.prismbake.preview() == {"FINISHED"}
    record = addon.jobs.RESULTS["Sphere"]["preview"]
    direct = tmp_path / "direct"
    subprocess.run([prismbake_bin, "render", record.glb, "--disp", str(MAP), "--scale", "0.08",
                    "--midlevel", "0.5", "--aov", "mask", "--res", "64x64", "-o", str(direct)],
                   check=True, capture_output=True)
    ours = exr_channel(next(f for f in record.files if f.endswith("mask.exr")))
    theirs = exr_channel(direct / "mask.exr")
    assert ours.shape == theirs.shape == (64, 64)
    assert 0.05 < theirs.mean() < 0.95, "the object should fill part of the frame"
    assert np.mean(np.abs(ours - theirs) > 0.5) <= 0.005


def test_preview_frames_the_scene_camera(bpy_module, addon, scene):
    """Moving the camera away shrinks the object in the preview: the camera was exported."""
    bpy = bpy_module
    assert bpy.ops.prismbake.preview() == {"FINISHED"}
    near = exr_channel(next(f for f in addon.jobs.RESULTS["Sphere"]["preview"].files if f.endswith("mask.exr")))
    bpy.context.scene.camera.location = (0.0, -12.0, 2.0)
    assert bpy.ops.prismbake.preview() == {"FINISHED"}
    far = exr_channel(next(f for f in addon.jobs.RESULTS["Sphere"]["preview"].files if f.endswith("mask.exr")))
    assert far.mean() < 0.5 * near.mean()


def test_preview_through_an_orthographic_scene_camera(bpy_module, addon, scene):
    """An orthographic camera previews orthographically: moving it away leaves the object's
    size alone, and doubling its orthographic scale halves it on each side."""
    bpy = bpy_module
    camera = bpy.context.scene.camera.data
    camera.type = "ORTHO"
    camera.ortho_scale = 4.0

    def coverage():
        assert bpy.ops.prismbake.preview() == {"FINISHED"}
        files = addon.jobs.RESULTS["Sphere"]["preview"].files
        return exr_channel(next(f for f in files if f.endswith("mask.exr"))).mean()

    near = coverage()
    assert 0.1 < near < 0.9, near
    bpy.context.scene.camera.location = (0.0, -12.0, 2.0)
    far = coverage()
    assert abs(far - near) < 0.1 * near, (near, far)
    camera.ortho_scale = 8.0
    wide = coverage()
    assert abs(wide - 0.25 * far) < 0.1 * far, (far, wide)


def test_preview_rerun_replaces_the_image_and_its_folder(bpy_module, addon, scene):
    bpy = bpy_module
    assert bpy.ops.prismbake.preview() == {"FINISHED"}
    first = addon.jobs.RESULTS["Sphere"]["preview"].folder
    assert bpy.ops.prismbake.preview() == {"FINISHED"}
    assert [i.name for i in bpy.data.images if i.name.startswith("prismbake preview")] == ["prismbake preview: Sphere"]
    assert not os.path.exists(first)


def test_preview_timing_at_256(bpy_module, addon, scene, prefs, record_property, capsys):
    """Invoking Preview to the image loaded, UV sphere (32x16), 256x256, normal + mask AOVs."""
    prefs.resolution = 256
    t0 = time.perf_counter()
    assert bpy_module.ops.prismbake.preview() == {"FINISHED"}
    cold = time.perf_counter() - t0
    t0 = time.perf_counter()
    assert bpy_module.ops.prismbake.preview() == {"FINISHED"}
    seconds = time.perf_counter() - t0
    record = addon.jobs.RESULTS["Sphere"]["preview"]
    assert tuple(bpy_module.data.images["prismbake preview: Sphere"].size) == (256, 256)
    record_property("preview_seconds", round(seconds, 3))
    with capsys.disabled():
        print(f"\npreview 256x256: {seconds:.3f} s from invoke to image loaded, first run {cold:.3f} s "
              f"(CLI render {record.render_seconds:.3f} s)")
    assert seconds < 30


def test_preview_of_a_displace_modifier(bpy_module, addon, scene, prismbake_bin, tmp_path):
    """Same map and numbers through a Displace modifier: the CLI gets the same flags."""
    bpy = bpy_module
    image = scene.active_material.node_tree.nodes["Image Texture"].image
    scene.data.materials.clear()
    tex = bpy.data.textures.new("Height", type="IMAGE")
    tex.image = image
    mod = scene.modifiers.new("Displace", "DISPLACE")
    mod.texture, mod.texture_coords, mod.strength, mod.mid_level = tex, "UV", 0.08, 0.5
    assert bpy.ops.prismbake.preview() == {"FINISHED"}
    argv = addon.jobs.RESULTS["Sphere"]["preview"].argv
    assert argv[argv.index("--disp") + 1] == str(MAP)
    assert float(argv[argv.index("--scale") + 1]) == pytest.approx(0.08)
    assert mod.show_viewport  # the user's modifier is left as it was


def test_preview_from_edit_mode_sees_the_edits_and_stays_in_edit_mode(bpy_module, addon, scene):
    bpy = bpy_module
    bpy.ops.object.mode_set(mode="EDIT")
    bpy.ops.mesh.select_all(action="SELECT")
    bpy.ops.transform.resize(value=(0.5, 0.5, 0.5))  # not yet in obj.data until Edit Mode is left
    assert bpy.ops.prismbake.preview() == {"FINISHED"}
    assert bpy.context.mode == "EDIT_MESH"
    import glb
    pos, _, _ = glb.triangles(addon.jobs.RESULTS["Sphere"]["preview"].glb)
    assert np.linalg.norm(pos, axis=1).max() == pytest.approx(0.5, abs=1e-4)


def test_turntable_writes_every_frame(bpy_module, addon, scene, tmp_path):
    out = tmp_path / "tt"
    assert bpy_module.ops.prismbake.turntable(frames=4, directory=str(out)) == {"FINISHED"}
    for i in range(4):
        mask = exr_channel(out / f"mask_{i:04d}.exr")
        assert mask.shape == (64, 64) and mask.max() == 1.0
        assert (out / f"normal_{i:04d}.png").stat().st_size > 0
    assert addon.jobs.RESULTS["Sphere"]["turntable"]["frames"] == 4


def test_turntable_uses_the_scene_settings(bpy_module, scene):
    settings = bpy_module.context.scene.prismbake
    settings.turntable_frames = 2
    assert bpy_module.ops.prismbake.turntable() == {"FINISHED"}
    assert sorted(f for f in os.listdir(settings.turntable_dir) if f.endswith(".png")) == [
        "mask_0000.png", "mask_0001.png", "mask_contact_sheet.png",
        "normal_0000.png", "normal_0001.png", "normal_contact_sheet.png"]


def test_bake_writes_a_table_the_cli_can_read(bpy_module, addon, scene, prismbake_bin, tmp_path):
    """The table, and the base mesh it names beside it: a render of the table looks through the
    scene camera that went along with the export, without a warning."""
    path = bpy_module.context.scene.prismbake.prisms_path
    assert bpy_module.ops.prismbake.bake() == {"FINISHED"}
    assert os.path.getsize(path) > 1000
    inspect = subprocess.run([prismbake_bin, "inspect", path, "--json"], capture_output=True, text=True)
    assert inspect.returncode == 0, inspect.stderr
    info = json.loads(inspect.stdout)
    assert info["mesh"] == os.path.basename(path)[:-len(".prisms")] + ".base.glb", info
    assert info["mesh_scene"].startswith("read"), info
    assert addon.jobs.RESULTS["Sphere"]["bake"]["prisms"] >= 960
    render = subprocess.run([prismbake_bin, "render", path, "--aov", "mask", "--res", "16x16", "--json",
                             "-o", str(tmp_path / "table")], capture_output=True, text=True)
    assert render.returncode == 0 and "warning" not in render.stderr, render.stderr
    assert json.loads(render.stdout)["camera"] == "the file's camera 'Camera'", render.stdout


def test_bake_next_to_the_blend(bpy_module, scene, tmp_path):
    bpy = bpy_module
    bpy.context.scene.prismbake.prisms_path = ""
    with pytest.raises(RuntimeError, match="the .blend is not saved"):
        bpy.ops.prismbake.bake()
    blend = tmp_path / "shot.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend))
    assert bpy.ops.prismbake.bake() == {"FINISHED"}
    assert (tmp_path / "Sphere.prisms").stat().st_size > 1000


def test_validate_clean_sphere_passes(bpy_module, addon, scene):
    # The UV sphere's pole fans are UV seams the map jumps across (the next test); with the
    # seam limit relaxed, nothing else is wrong with it.
    bpy_module.context.scene.prismbake.max_seam_jump = 1.0
    assert bpy_module.ops.prismbake.validate() == {"FINISHED"}
    result = addon.jobs.RESULTS["Sphere"]["validate"]
    assert result["problems"] == [] and "uvs" in result["passed"]
    assert "seam-jump" in result["passed"]
    assert bpy_module.context.mode == "OBJECT"


def test_validate_selects_the_worst_seam_edges(bpy_module, addon, scene):
    """Blender's UV sphere gives every pole triangle its own UV at the pole, so the map
    jumps across the pole fans' edges: shaded smooth (flat shading makes every edge a hard
    edge, not a seam), validate fails `seam-jump` at the default limit and selects those
    edges (each shared by the two polygons the report names) in Edit Mode."""
    bpy = bpy_module
    me = scene.data
    bpy.ops.object.shade_smooth()
    assert bpy.ops.prismbake.validate() == {"FINISHED"}
    result = addon.jobs.RESULTS["Sphere"]["validate"]
    assert [p["check"] for p in result["problems"]] == ["seam-jump"]
    assert result["problems"][0]["seam_edges"], result["problems"][0]
    edges = result["seam_edges"]
    assert 1 <= len(edges) <= 10, edges
    assert result["polygons"] == []
    assert bpy.context.mode == "EDIT_MESH"
    assert tuple(bpy.context.tool_settings.mesh_select_mode) == (False, True, True)
    bpy.ops.object.mode_set(mode="OBJECT")
    assert sorted(e.index for e in me.edges if e.select) == sorted(edges)
    # Each is a pole-fan edge: one end at a pole (the sphere's top or bottom vertex).
    zs = [v.co.z for v in me.vertices]
    for e in edges:
        ends = [me.vertices[i].co.z for i in me.edges[e].vertices]
        assert max(zs) in ends or min(zs) in ends, ends


def test_validate_selects_the_faces_it_names(bpy_module, addon, scene):
    """Collapse the UVs of two polygons: validate reports their triangles as zero UV area
    (each reported face maps back to one of the two), and exactly those two polygons end up
    selected in Edit Mode."""
    bpy = bpy_module
    me = scene.data
    bad = [100, 301]
    bpy.context.scene.prismbake.max_seam_jump = 1.0
    uv = me.uv_layers["UVMap"].data
    for p in bad:
        for li in me.polygons[p].loop_indices:
            uv[li].uv = (0.25, 0.25)
    assert bpy.ops.prismbake.validate() == {"FINISHED"}
    result = addon.jobs.RESULTS["Sphere"]["validate"]
    assert [p["check"] for p in result["problems"]] == ["degenerate-faces"]
    assert 2 <= len(result["problems"][0]["faces"]) <= 4
    assert result["polygons"] == bad
    assert bpy.context.mode == "EDIT_MESH"
    assert tuple(bpy.context.tool_settings.mesh_select_mode) == (False, False, True)
    bpy.ops.object.mode_set(mode="OBJECT")
    assert [p.index for p in me.polygons if p.select] == bad


def test_validate_max_displacement(bpy_module, addon, scene):
    bpy_module.context.scene.prismbake.max_seam_jump = 1.0
    bpy_module.context.scene.prismbake.max_disp = 0.001
    assert bpy_module.ops.prismbake.validate() == {"FINISHED"}
    checks = [p["check"] for p in addon.jobs.RESULTS["Sphere"]["validate"]["problems"]]
    assert checks == ["max-displacement"]


def test_export_usd(bpy_module, addon, scene, prismbake_bin):
    if not addon.cli_bridge.has_command(prismbake_bin, "export"):
        op = bpy_module.ops.prismbake.export_usd
        assert not op.poll()
        with pytest.raises(RuntimeError, match="has no `export` command: update the binary"):
            op()
        pytest.skip("this prismbake has no export command yet; poll() says so (checked above)")
    path = bpy_module.context.scene.prismbake.usd_path
    assert bpy_module.ops.prismbake.export_usd() == {"FINISHED"}
    assert os.path.getsize(path) > 0
    from pxr import Usd, UsdGeom
    stage = Usd.Stage.Open(path)
    meshes = [p for p in stage.Traverse() if p.IsA(UsdGeom.Mesh)]
    assert meshes, "no UsdGeom.Mesh in the export"
    counts = UsdGeom.Mesh(meshes[0]).GetFaceVertexCountsAttr().Get()
    assert len(counts) >= 960  # the repaired mesh: crease repair may insert triangles
    from pxr import UsdShade
    tex = next(UsdShade.Shader(p) for p in stage.Traverse()
               if p.IsA(UsdShade.Shader) and UsdShade.Shader(p).GetInput("file"))
    file = tex.GetInput("file").Get()
    assert os.path.normpath(file.resolvedPath or os.path.join(os.path.dirname(path), file.path)) == str(MAP)
    assert tuple(tex.GetInput("scale").Get())[0] == pytest.approx(0.08)
    assert tuple(tex.GetInput("bias").Get())[0] == pytest.approx(-0.04)


# --- error paths ----------------------------------------------------------------------------

def test_cli_failure_is_one_readable_error(bpy_module, addon, scene, tmp_path):
    """A map that exists but is not an image: detection passes, the CLI fails with exit 2."""
    broken = tmp_path / "broken.png"
    broken.write_bytes(b"not a png at all")
    scene.active_material.node_tree.nodes["Image Texture"].image.filepath = str(broken)
    with pytest.raises(RuntimeError) as err:
        bpy_module.ops.prismbake.preview()
    msg = str(err.value)
    assert "prismbake render failed (input or I/O error, exit 2):" in msg and "broken.png" in msg
    assert len(msg.strip().splitlines()) == 1
    assert "broken.png" in addon.jobs.RESULTS["Sphere"]["error"]
    assert "prismbake preview: Sphere" not in bpy_module.data.images


def test_map_path_that_does_not_exist(bpy_module, scene, tmp_path):
    scene.active_material.node_tree.nodes["Image Texture"].image.filepath = str(tmp_path / "gone.png")
    for op in ("preview", "bake", "validate", "turntable"):
        with pytest.raises(RuntimeError, match=f"image file {tmp_path / 'gone.png'} does not exist"):
            getattr(bpy_module.ops.prismbake, op)()


def test_the_clis_error_line_becomes_the_report(bpy_module, scene, prefs, tmp_path):
    fake = tmp_path / "prismbake"
    fake.write_text("#!/bin/sh\necho 'error: boom: the CLI broke' >&2\nexit 2\n")
    fake.chmod(0o755)
    prefs.binary_path = str(fake)
    with pytest.raises(RuntimeError, match=r"prismbake bake failed \(input or I/O error, exit 2\): boom: the CLI broke"):
        bpy_module.ops.prismbake.bake()


def test_cli_crash_is_reported_with_the_panic_line(bpy_module, scene, prefs, tmp_path):
    fake = tmp_path / "prismbake"
    fake.write_text("#!/bin/sh\necho \"thread 'main' panicked at core/src/bake.rs:1:1:\" >&2\n"
                    "echo 'attempt to divide by zero' >&2\nexit 101\n")
    fake.chmod(0o755)
    prefs.binary_path = str(fake)
    with pytest.raises(RuntimeError, match=r"prismbake render failed \(crashed, exit 101\): thread 'main' panicked at"):
        bpy_module.ops.prismbake.preview()


def test_garbage_output_is_reported(bpy_module, scene, prefs, tmp_path):
    fake = tmp_path / "prismbake"
    fake.write_text("#!/bin/sh\necho 'done!'\n")
    fake.chmod(0o755)
    prefs.binary_path = str(fake)
    with pytest.raises(RuntimeError, match="printed no valid JSON"):
        bpy_module.ops.prismbake.bake()


def test_unwritable_output_is_a_readable_error(bpy_module, scene, tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("")
    bpy_module.context.scene.prismbake.prisms_path = str(blocker / "sub" / "x.prisms")
    with pytest.raises(RuntimeError, match=r"Bake Prism Table: Not a directory \(.*file/sub\)"):
        bpy_module.ops.prismbake.bake()


def test_object_without_uvs(bpy_module, scene):
    for uv in list(scene.data.uv_layers):
        scene.data.uv_layers.remove(uv)
    for op in ("preview", "bake", "validate", "turntable"):
        assert not getattr(bpy_module.ops.prismbake, op).poll()
        with pytest.raises(RuntimeError, match='mesh "Sphere" has no UV map'):
            getattr(bpy_module.ops.prismbake, op)()


def test_packed_image(bpy_module, scene):
    scene.active_material.node_tree.nodes["Image Texture"].image.pack()
    with pytest.raises(RuntimeError, match="is packed into the .blend: save it to a file first"):
        bpy_module.ops.prismbake.preview()


def test_not_a_mesh(bpy_module, scene):
    bpy_module.context.view_layer.objects.active = bpy_module.context.scene.camera
    with pytest.raises(RuntimeError, match="select a mesh object"):
        bpy_module.ops.prismbake.preview()

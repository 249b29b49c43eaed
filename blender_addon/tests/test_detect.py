"""detect.py on real Blender objects: what it finds, and what it says is missing."""
import os
import shutil

import pytest

from pbtest import MAP


def _node(sphere, idname):
    return next(n for n in sphere.active_material.node_tree.nodes if n.bl_idname == idname)


def test_material_displacement_node_is_found(addon, scene):
    info = addon.detect.detect(scene)
    assert info.ok, info.problems
    assert info.source == "material" and "Displacement" in info.where
    assert info.image_path == os.path.normpath(str(MAP))
    assert info.scale == pytest.approx(0.08) and info.midlevel == pytest.approx(0.5)
    assert info.space == "OBJECT" and info.world_scale == pytest.approx(0.08)
    assert info.uv_map == "UVMap" and info.wrap == "repeat"
    assert info.warnings == []


def test_object_space_scale_follows_the_object_and_world_space_does_not(bpy_module, addon, scene):
    scene.scale = (2.0, 2.0, 2.0)
    bpy_module.context.view_layer.update()  # matrix_world follows on the next depsgraph update
    assert addon.detect.detect(scene).world_scale == pytest.approx(0.16)
    _node(scene, "ShaderNodeDisplacement").space = "WORLD"
    assert addon.detect.detect(scene).world_scale == pytest.approx(0.08)


def test_non_uniform_scale_is_a_warning(bpy_module, addon, scene):
    scene.scale = (1.0, 2.0, 1.0)
    bpy_module.context.view_layer.update()
    info = addon.detect.detect(scene)
    assert info.ok and any("not uniform" in w for w in info.warnings)


def test_uv_map_node_picks_the_uv_set(bpy_module, addon, scene):
    scene.data.uv_layers.new(name="Second")
    tree = scene.active_material.node_tree
    uvnode = tree.nodes.new("ShaderNodeUVMap")
    uvnode.uv_map = "Second"
    tree.links.new(uvnode.outputs["UV"], _node(scene, "ShaderNodeTexImage").inputs["Vector"])
    info = addon.detect.detect(scene)
    assert info.ok and info.uv_map == "Second" and info.uv_set == 1
    uvnode.uv_map = "Nope"
    assert any('UV map "Nope" does not exist' in p for p in addon.detect.detect(scene).problems)


def test_displace_modifier_is_found(bpy_module, addon, scene):
    bpy = bpy_module
    scene.data.materials.clear()
    tex = bpy.data.textures.new("Height", type="IMAGE")
    tex.image = bpy.data.images.load(str(MAP), check_existing=True)
    mod = scene.modifiers.new("Displace", "DISPLACE")
    mod.texture = tex
    mod.texture_coords = "UV"
    mod.strength, mod.mid_level = 0.05, 0.25
    info = addon.detect.detect(scene)
    assert info.ok, info.problems
    assert info.source == "modifier" and info.scale == pytest.approx(0.05) and info.midlevel == pytest.approx(0.25)
    assert info.image_path == os.path.normpath(str(MAP)) and info.uv_map == "UVMap"
    mod.texture_coords = "LOCAL"
    assert any("set Coordinates to UV" in p for p in addon.detect.detect(scene).problems)
    mod.texture_coords = "UV"
    mod.direction = "Z"
    assert any("set Direction" in p for p in addon.detect.detect(scene).problems)


def test_nothing_found_says_what_to_add(addon, scene):
    scene.data.materials.clear()
    info = addon.detect.detect(scene)
    assert not info.ok and info.source == ""
    assert "no displacement found" in info.problems[0]


def test_no_uvs(addon, scene):
    for uv in list(scene.data.uv_layers):
        scene.data.uv_layers.remove(uv)
    info = addon.detect.detect(scene)
    assert not info.ok and any("has no UV map" in p and "Unwrap" in p for p in info.problems)


def test_packed_image_must_be_saved_first(addon, scene):
    _node(scene, "ShaderNodeTexImage").image.pack()
    info = addon.detect.detect(scene)
    assert not info.ok and any("is packed into the .blend: save it to a file first" in p for p in info.problems)


def test_generated_image_must_be_saved_first(bpy_module, addon, scene):
    _node(scene, "ShaderNodeTexImage").image = bpy_module.data.images.new("Painted", 64, 64)
    info = addon.detect.detect(scene)
    assert not info.ok and any('"Painted" is generated in Blender: save it to a file' in p for p in info.problems)


def test_missing_image_file(addon, scene, tmp_path):
    copy = tmp_path / "h.png"
    shutil.copy(MAP, copy)
    _node(scene, "ShaderNodeTexImage").image.filepath = str(copy)
    assert addon.detect.detect(scene).ok
    copy.unlink()
    info = addon.detect.detect(scene)
    assert any(f"image file {copy} does not exist" in p for p in info.problems)


def test_unsupported_format_and_missing_image(bpy_module, addon, scene, tmp_path):
    tex = _node(scene, "ShaderNodeTexImage")
    tex.image.filepath = str(tmp_path / "h.jpg")
    assert any("reads EXR, PNG and TIFF" in p for p in addon.detect.detect(scene).problems)
    tex.image = None
    assert any("has no image" in p for p in addon.detect.detect(scene).problems)


def test_height_not_from_an_image(addon, scene):
    tree = scene.active_material.node_tree
    noise = tree.nodes.new("ShaderNodeTexNoise")
    tree.links.new(noise.outputs["Fac"], _node(scene, "ShaderNodeDisplacement").inputs["Height"])
    info = addon.detect.detect(scene)
    assert any("needs an Image Texture node" in p for p in info.problems)


def test_srgb_map_and_bump_only_are_warnings(addon, scene):
    _node(scene, "ShaderNodeTexImage").image.colorspace_settings.name = "sRGB"
    mat = scene.active_material
    if hasattr(mat, "displacement_method"):
        mat.displacement_method = "BUMP"
    info = addon.detect.detect(scene)
    assert info.ok
    assert any("Non-Color" in w for w in info.warnings)
    if hasattr(mat, "displacement_method"):
        assert any("Bump Only" in w for w in info.warnings)


def test_poll_explains_the_first_problem(bpy_module, scene):
    for uv in list(scene.data.uv_layers):
        scene.data.uv_layers.remove(uv)
    with pytest.raises(RuntimeError, match="has no UV map"):
        bpy_module.ops.prismbake.preview()


def test_panels_draw_without_errors(bpy_module, addon, scene):
    """The panel code runs on real data (a layout stand-in records the labels)."""
    labels = []

    class Layout:
        def __getattr__(self, name):
            return lambda *a, **k: self if name in ("box", "column", "row") else None

        def label(self, text="", icon="NONE"):
            labels.append((text, icon))

    context = bpy_module.context
    addon.ui.draw_panel(Layout(), context)
    assert any("scales_256.png" in t for t, _ in labels)
    assert ("Ready", "CHECKMARK") in labels
    labels.clear()
    _node(scene, "ShaderNodeTexImage").image.pack()
    addon.ui.draw_panel(Layout(), context)
    assert any("packed" in t and icon == "ERROR" for t, icon in labels)

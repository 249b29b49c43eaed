"""export.py: the GLB the CLI gets, and the triangle -> polygon map that validate relies on."""
import numpy as np
import pytest

import glb


def _export(bpy, addon, obj, tmp_path, uv_map="UVMap"):
    return addon.export.export_glb(bpy.context, obj, uv_map, str(tmp_path / "x.glb"))


def _blender_to_gltf(points):
    """Blender Z-up to glTF Y-up, as the exporter does it: (x, y, z) -> (x, z, -y)."""
    p = np.asarray(points, dtype=np.float64)
    return np.stack([p[:, 0], p[:, 2], -p[:, 1]], axis=1)


def test_each_gltf_triangle_lies_on_the_polygon_the_map_names(bpy_module, addon, scene, tmp_path):
    bpy = bpy_module
    scene.location = (0.5, -1.0, 2.0)
    scene.rotation_euler = (0.3, 0.0, 0.7)
    bpy.context.view_layer.update()
    exp = _export(bpy, addon, scene, tmp_path)
    pos, tris, doc = glb.triangles(exp.path)
    node = next(n for n in doc["nodes"] if "mesh" in n)
    assert len(tris) == len(exp.tri_to_poly) == 960  # 32x16 sphere: 448 quads + 64 triangles
    # The node carries the object transform; compare in object space, rotated into glTF axes.
    me = scene.data
    world = scene.matrix_world
    for t, poly_index in enumerate(exp.tri_to_poly):
        poly_verts = [world @ me.vertices[v].co for v in me.polygons[poly_index].vertices]
        corners = _apply_node(node, pos[tris[t]])
        d = np.linalg.norm(corners[:, None, :] - _blender_to_gltf(poly_verts)[None, :, :], axis=2)
        assert d.min(axis=1).max() < 1e-4, f"triangle {t} is not on polygon {poly_index}"


def _apply_node(node, points):
    from mathutils import Matrix, Quaternion, Vector
    t = Vector(node.get("translation", [0, 0, 0]))
    x, y, z, w = node.get("rotation", [0, 0, 0, 1])
    s = node.get("scale", [1, 1, 1])
    m = Matrix.Translation(t) @ Quaternion((w, x, y, z)).to_matrix().to_4x4() @ Matrix.Diagonal((*s, 1))
    return np.array([(m @ Vector(p))[:] for p in points])


def test_ngons_map_to_their_polygon(bpy_module, addon, scene, tmp_path):
    bpy = bpy_module
    bpy.ops.mesh.primitive_circle_add(vertices=12, fill_type="NGON")
    disc = bpy.context.active_object
    disc.data.uv_layers.new(name="UVMap")
    exp = _export(bpy, addon, disc, tmp_path)
    assert exp.tri_to_poly == [0] * 10


def test_only_the_displacement_uv_map_is_exported_and_no_material(bpy_module, addon, scene, tmp_path):
    scene.data.uv_layers.new(name="Other")
    exp = _export(bpy_module, addon, scene, tmp_path, uv_map="Other")
    _, _, doc = glb.triangles(exp.path)
    attrs = doc["meshes"][0]["primitives"][0]["attributes"]
    assert "TEXCOORD_0" in attrs and "TEXCOORD_1" not in attrs
    assert len(doc["meshes"][0]["primitives"]) == 1 and "materials" not in doc


def test_scene_camera_goes_along(bpy_module, addon, scene, tmp_path):
    exp = _export(bpy_module, addon, scene, tmp_path)
    _, _, doc = glb.triangles(exp.path)
    assert exp.camera == "Camera"
    assert doc["cameras"][0]["type"] == "perspective"
    cam_node = next(n for n in doc["nodes"] if "camera" in n)
    # Camera at Blender (0, -6, 1) -> glTF (0, 1, 6).
    assert cam_node["translation"] == pytest.approx([0.0, 1.0, 6.0], abs=1e-5)


def test_displace_modifier_is_not_applied(bpy_module, addon, scene, tmp_path):
    bpy = bpy_module
    tex = bpy.data.textures.new("H", type="IMAGE")
    tex.image = scene.active_material.node_tree.nodes["Image Texture"].image
    mod = scene.modifiers.new("Displace", "DISPLACE")
    mod.texture, mod.texture_coords, mod.strength = tex, "UV", 0.5
    exp = _export(bpy, addon, scene, tmp_path)
    pos, _, _ = glb.triangles(exp.path)
    radius = np.linalg.norm(pos, axis=1)
    assert radius == pytest.approx(1.0, abs=1e-4)  # the base sphere, not the displaced one


def test_export_leaves_the_scene_as_it_was(bpy_module, addon, scene, tmp_path):
    bpy = bpy_module
    before = (set(bpy.data.objects.keys()), set(bpy.data.meshes.keys()),
              [o.name for o in bpy.context.selected_objects], bpy.context.view_layer.objects.active.name)
    _export(bpy, addon, scene, tmp_path)
    after = (set(bpy.data.objects.keys()), set(bpy.data.meshes.keys()),
             [o.name for o in bpy.context.selected_objects], bpy.context.view_layer.objects.active.name)
    assert before == after

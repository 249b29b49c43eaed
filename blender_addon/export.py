"""Write an object's base mesh (no modifiers, so no displacement) as a temporary GLB for the CLI.

The mesh is triangulated here, with bmesh, before the glTF exporter sees it, so that the
triangle order in the file is ours: `tri_to_poly[i]` is the polygon of the object's mesh that
glTF triangle `i` came from, which is how `validate`'s face indices are mapped back to
polygons to select in Edit Mode. Materials are not exported (one primitive, so the exporter
has no reason to regroup triangles; the CLI takes the map from its flags), only the UV map the
displacement uses is kept (it becomes TEXCOORD_0), and the scene camera goes along so the CLI
renders from the user's view. Blender's Z-up to glTF's Y-up is the exporter's job.
"""
from __future__ import annotations

import dataclasses
import os

import bmesh
import bpy

from .cli_bridge import BridgeError

_POLY_LAYER = "prismbake_polygon"


@dataclasses.dataclass
class Export:
    path: str
    tri_to_poly: list          # glTF triangle index -> polygon index of obj.data
    camera: str                # name of the exported camera, "" for none
    seconds: float = 0.0


def export_glb(context, obj, uv_map: str, path: str, camera=True) -> Export:
    import time
    start = time.perf_counter()
    if obj.mode == "EDIT":
        obj.update_from_editmode()
    mesh, tri_to_poly = triangulated_copy(obj.data, uv_map)
    tmp = bpy.data.objects.new(f"{obj.name} (prismbake export)", mesh)
    tmp.matrix_world = obj.matrix_world.copy()
    scene = context.scene
    scene.collection.objects.link(tmp)
    cam = scene.camera if camera else None
    saved = _save_selection(context)
    try:
        for o in context.view_layer.objects.selected:
            o.select_set(False)
        tmp.select_set(True)
        cam_name = ""
        if cam is not None and cam.type == "CAMERA" and cam.visible_get(view_layer=context.view_layer):
            cam.select_set(True)
            cam_name = cam.name
        context.view_layer.objects.active = tmp
        _run_gltf_exporter(path)
    finally:
        _restore_selection(context, saved)
        bpy.data.objects.remove(tmp)
        bpy.data.meshes.remove(mesh)
    if not os.path.isfile(path) or os.path.getsize(path) == 0:
        raise BridgeError(f"the glTF export of {obj.name} wrote nothing to {path}")
    return Export(path, tri_to_poly, cam_name, time.perf_counter() - start)


def triangulated_copy(source_mesh, uv_map: str):
    """A new mesh: `source_mesh` triangulated, only `uv_map` kept, no materials; + tri->poly map."""
    bm = bmesh.new()
    try:
        bm.from_mesh(source_mesh)
        layer = bm.faces.layers.int.new(_POLY_LAYER)
        for i, f in enumerate(bm.faces):
            f[layer] = i
            f.material_index = 0
        bmesh.ops.triangulate(bm, faces=bm.faces[:], quad_method="BEAUTY", ngon_method="BEAUTY")
        mesh = bpy.data.meshes.new(f"{source_mesh.name} (prismbake export)")
        bm.to_mesh(mesh)
        tri_to_poly = [f[layer] for f in bm.faces]
    finally:
        bm.free()
    for uv in [l for l in mesh.uv_layers if l.name != uv_map]:
        mesh.uv_layers.remove(uv)
    if _POLY_LAYER in mesh.attributes:
        mesh.attributes.remove(mesh.attributes[_POLY_LAYER])
    mesh.materials.clear()
    return mesh, tri_to_poly


def _run_gltf_exporter(path: str) -> None:
    wanted = dict(
        filepath=path, export_format="GLB", use_selection=True, export_apply=False,
        export_cameras=True, export_lights=False, export_yup=True, export_texcoords=True,
        export_normals=True, export_materials="NONE", export_animations=False,
        export_skins=False, export_morph=False, export_extras=False, export_attributes=False,
        export_loose_edges=False, export_loose_points=False,
    )
    # Options come and go between Blender versions: pass only the ones this exporter has.
    known = bpy.ops.export_scene.gltf.get_rna_type().properties.keys()
    kwargs = {k: v for k, v in wanted.items() if k in known}
    try:
        result = bpy.ops.export_scene.gltf(**kwargs)
    except (RuntimeError, AttributeError) as e:
        raise BridgeError(f"glTF export failed: {str(e).strip().splitlines()[-1]}") from None
    if "FINISHED" not in result:
        raise BridgeError(f"glTF export did not finish ({', '.join(result)})")


def _save_selection(context):
    return ([o.name for o in context.view_layer.objects.selected],
            context.view_layer.objects.active.name if context.view_layer.objects.active else None)


def _restore_selection(context, saved) -> None:
    names, active = saved
    objects = context.view_layer.objects
    for o in list(objects.selected):
        if o is not None:
            o.select_set(False)
    for n in names:
        if n in objects:
            objects[n].select_set(True)
    if active in objects:
        objects.active = objects[active]

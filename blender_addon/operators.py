"""The five operators: Preview, Turntable, Bake prism table, Validate, Export USD.

Each exports the active object's base mesh to a temporary GLB (export.py), asks cli_bridge
for the argument list, and shows what came back. Running and cancelling is jobs.JobOperator's.
"""
from __future__ import annotations

import dataclasses
import os
import shutil
import tempfile
import time

import bmesh
import bpy
from bpy.props import IntProperty, StringProperty

from . import cli_bridge, export, jobs, prefs


def _temp_dir(prefix: str) -> str:
    return tempfile.mkdtemp(prefix=prefix, dir=bpy.app.tempdir or None)


def _export(context, obj, info, folder: str) -> export.Export:
    return export.export_glb(context, obj, info.uv_map, os.path.join(folder, "export.glb"))


@dataclasses.dataclass
class PreviewRecord:
    image: str              # name of the Image datablock
    folder: str             # CLI output folder (kept until the next preview of the object)
    glb: str                # the export the CLI rendered
    files: list
    render_seconds: float   # the CLI's own figure
    total_seconds: float    # operator start -> image loaded
    argv: list


class PRISMBAKE_OT_preview(jobs.JobOperator, bpy.types.Operator):
    """Render the active object's displacement with prismbake and show it in an Image"""
    bl_idname = "prismbake.preview"
    bl_label = "Preview"

    def prepare(self, context, binary, info):
        obj = context.active_object
        self._folder = _temp_dir("prismbake-preview-")
        exp = _export(context, obj, info, self._folder)
        self._glb = exp.path
        return cli_bridge.render_args(binary, exp.path, info.displacement(),
                                      prefs.render_settings(context), self._folder)

    def finish(self, context, result):
        summary = cli_bridge.parse_render(result.json())
        png = summary.first("normal")
        if png is None or not os.path.isfile(png):
            raise cli_bridge.BridgeError(f"prismbake render wrote no normal image in {self._folder}")
        old = jobs.RESULTS.get(self._object_name, {}).get("preview")
        image = load_preview(png, f"prismbake preview: {self._object_name}", old.image if old else None)
        show_in_image_editors(context, image)
        if old is not None and old.folder != self._folder:
            shutil.rmtree(old.folder, ignore_errors=True)
        total = time.perf_counter() - self._t0
        jobs.remember(self._object_name, "preview", PreviewRecord(
            image.name, self._folder, self._glb, summary.files, summary.seconds, total, result.argv))
        self._folder = None  # kept: the record owns it now
        cov = f", {100 * summary.coverage:.1f}% covered" if summary.coverage is not None else ""
        self.report({"WARNING"} if summary.gpu_fallback else {"INFO"},
                    f"Preview of {self._object_name}: {image.size[0]}x{image.size[1]} in "
                    f"{total:.2f} s (render {summary.seconds:.2f} s{cov}){summary.device_note()}")
        return {"FINISHED"}

    def cleanup(self):
        folder = getattr(self, "_folder", None)
        if folder:
            shutil.rmtree(folder, ignore_errors=True)


def load_preview(path: str, name: str, previous: str = None):
    """Load `path` as the Image `name` (packed, so it outlives the temporary file); editors that
    showed the previous one (`previous`: its name, which Blender may have shortened) show the
    new one."""
    new = bpy.data.images.load(path, check_existing=False)
    new.pack()
    old = bpy.data.images.get(previous or name)
    if old is not None:
        old.user_remap(new)
        bpy.data.images.remove(old)
    new.name = name
    return new


def show_in_image_editors(context, image) -> int:
    shown = 0
    if bpy.app.background:
        return shown
    for window in context.window_manager.windows:
        for area in window.screen.areas:
            if area.type == "IMAGE_EDITOR":
                area.spaces.active.image = image
                shown += 1
    return shown


class PRISMBAKE_OT_turntable(jobs.JobOperator, bpy.types.Operator):
    """Render a turntable of the active object (one normal and one mask image per frame)"""
    bl_idname = "prismbake.turntable"
    bl_label = "Render Turntable"

    frames: IntProperty(name="Frames", description="Frames around the up axis; 0: the scene setting",
                        default=0, min=0, max=3600)
    directory: StringProperty(name="Folder", description="Output folder; empty: the scene setting",
                              default="", subtype="DIR_PATH")

    def prepare(self, context, binary, info):
        settings = context.scene.prismbake
        obj = context.active_object
        self._frames = self.frames or settings.turntable_frames
        self._out = jobs.blend_relative(context, self.directory or settings.turntable_dir,
                                        os.path.join("prismbake_turntable", jobs.safe_name(obj.name)))
        os.makedirs(self._out, exist_ok=True)
        self._since = time.time()
        self._tmp = _temp_dir("prismbake-turntable-")
        exp = _export(context, obj, info, self._tmp)
        return cli_bridge.render_args(binary, exp.path, info.displacement(),
                                      prefs.render_settings(context), self._out, turntable=self._frames)

    def progress(self):
        return cli_bridge.count_files(self._out, ".png", prefix="normal_", since=self._since), self._frames

    def finish(self, context, result):
        summary = cli_bridge.parse_render(result.json())
        jobs.remember(self._object_name, "turntable", {"folder": self._out, "frames": summary.frames,
                                                       "files": summary.files})
        self.report({"WARNING"} if summary.gpu_fallback else {"INFO"},
                    f"Turntable of {self._object_name}: {summary.frames} frames in "
                    f"{self._out} ({summary.seconds:.1f} s){summary.device_note()}")
        return {"FINISHED"}

    def cleanup(self):
        if getattr(self, "_tmp", None):
            shutil.rmtree(self._tmp, ignore_errors=True)


class PRISMBAKE_OT_bake(jobs.JobOperator, bpy.types.Operator):
    """Bake the active object's prism table (.prisms) next to the .blend or to the chosen path,
    with the base mesh it was baked from beside it (.base.glb)"""
    bl_idname = "prismbake.bake"
    bl_label = "Bake Prism Table"

    filepath: StringProperty(name="File", description="Output .prisms; empty: the scene setting",
                             default="", subtype="FILE_PATH")

    def prepare(self, context, binary, info):
        obj = context.active_object
        self._out = jobs.blend_relative(context, self.filepath or context.scene.prismbake.prisms_path,
                                        jobs.safe_name(obj.name) + ".prisms")
        os.makedirs(os.path.dirname(self._out), exist_ok=True)
        self._tmp = _temp_dir("prismbake-bake-")
        exp = _export(context, obj, info, self._tmp)
        # The table names the mesh it was baked from, and a render of the table reads that
        # mesh's camera: the export is kept beside the table (`Sphere.base.glb`), put in
        # place whole.
        base = os.path.splitext(self._out)[0] + ".base.glb"
        shutil.copyfile(exp.path, base + ".tmp")
        os.replace(base + ".tmp", base)
        return cli_bridge.bake_args(binary, base, info.displacement(), self._out)

    def finish(self, context, result):
        data = result.json()
        jobs.remember(self._object_name, "bake", {"path": self._out, "prisms": data.get("prisms"),
                                                  "bytes": data.get("bytes")})
        reused = " (unchanged inputs: reused)" if data.get("reused") else ""
        self.report({"INFO"}, f"Baked {data.get('prisms')} prisms to {self._out}{reused}")
        return {"FINISHED"}

    def cleanup(self):
        if getattr(self, "_tmp", None):
            shutil.rmtree(self._tmp, ignore_errors=True)


class PRISMBAKE_OT_export_usd(jobs.JobOperator, bpy.types.Operator):
    """Write the displaced asset as USD with prismbake export"""
    bl_idname = "prismbake.export_usd"
    bl_label = "Export USD"
    cli_command = "export"

    filepath: StringProperty(name="File", description="Output .usda/.usd/.usdc; empty: the scene setting",
                             default="", subtype="FILE_PATH")

    def prepare(self, context, binary, info):
        obj = context.active_object
        self._out = jobs.blend_relative(context, self.filepath or context.scene.prismbake.usd_path,
                                        jobs.safe_name(obj.name) + ".usda")
        os.makedirs(os.path.dirname(self._out), exist_ok=True)
        self._tmp = _temp_dir("prismbake-usd-")
        exp = _export(context, obj, info, self._tmp)
        return cli_bridge.export_usd_args(binary, exp.path, info.displacement(), self._out)

    def finish(self, context, result):
        if not os.path.isfile(self._out) or os.path.getsize(self._out) == 0:
            raise cli_bridge.BridgeError(f"prismbake export finished but wrote nothing to {self._out}")
        jobs.remember(self._object_name, "usd", {"path": self._out})
        self.report({"INFO"}, f"Exported {self._object_name} to {self._out}")
        return {"FINISHED"}

    def cleanup(self):
        if getattr(self, "_tmp", None):
            shutil.rmtree(self._tmp, ignore_errors=True)


class PRISMBAKE_OT_validate(jobs.JobOperator, bpy.types.Operator):
    """Check the active object for everything that breaks displacement; select the faces at fault"""
    bl_idname = "prismbake.validate"
    bl_label = "Validate"
    allowed_exit = (cli_bridge.EXIT_OK, cli_bridge.EXIT_PROBLEMS)

    def prepare(self, context, binary, info):
        obj = context.active_object
        self._tmp = _temp_dir("prismbake-validate-")
        self._export = _export(context, obj, info, self._tmp)
        settings = context.scene.prismbake
        return cli_bridge.validate_args(binary, self._export.path, info.displacement(),
                                        max_disp=settings.max_disp,
                                        max_seam_jump=settings.max_seam_jump)

    def finish(self, context, result):
        report = cli_bridge.parse_validate(result.json())
        tri_to_poly = self._export.tri_to_poly
        polys, outside = cli_bridge.triangles_to_polygons(report.faces, tri_to_poly)
        seams, seams_outside = cli_bridge.seam_edges_to_polygon_pairs(report.seam_edges, tri_to_poly)
        mapped = report.mesh_triangles in (None, len(tri_to_poly)) and not (outside or seams_outside)
        obj = context.view_layer.objects[self._object_name]
        edges = shared_edges(obj, seams) if mapped else []
        jobs.remember(self._object_name, "validate", {
            "problems": [dataclasses.asdict(p) for p in report.problems],
            "passed": report.passed, "polygons": polys if mapped else [],
            "seam_edges": edges})
        if not report.problems:
            self.report({"INFO"}, f"{self._object_name}: all {len(report.passed)} checks pass")
            return {"FINISHED"}
        for p in report.problems:
            self.report({"WARNING"}, f"{p.check}: {p.message}")
        if (polys or edges) and mapped:
            select_polygons(context, obj, polys, edges)
        elif polys or seams:
            self.report({"WARNING"}, "the report's face indices do not match the export; nothing selected")
        popup_problems(context, self._object_name, report,
                       len(polys) if mapped else 0, len(edges))
        return {"FINISHED"}

    def cleanup(self):
        if getattr(self, "_tmp", None):
            shutil.rmtree(self._tmp, ignore_errors=True)


def shared_edges(obj, polygon_pairs) -> list[int]:
    """Mesh edges shared by each pair of polygons (a UV seam edge between the two), in order."""
    me = obj.data
    index = {tuple(sorted(e.vertices)): e.index for e in me.edges}
    out = []
    for a, b in polygon_pairs:
        if a >= len(me.polygons) or b >= len(me.polygons):
            continue
        common = set(me.polygons[a].edge_keys) & set(me.polygons[b].edge_keys)
        for key in sorted(common):
            e = index.get(tuple(sorted(key)))
            if e is not None and e not in out:
                out.append(e)
    return out


def select_polygons(context, obj, polygons, edges=()) -> None:
    """Edit Mode on `obj` with exactly `polygons` (and the seam `edges`) selected, in face
    select mode (edge and face mode when edges are selected: an edge alone would not show)."""
    if context.mode != "OBJECT":
        bpy.ops.object.mode_set(mode="OBJECT")
    for o in list(context.view_layer.objects.selected):
        o.select_set(False)
    obj.select_set(True)
    context.view_layer.objects.active = obj
    bpy.ops.object.mode_set(mode="EDIT")
    context.tool_settings.mesh_select_mode = (False, bool(edges), True)
    bm = bmesh.from_edit_mesh(obj.data)
    bm.faces.ensure_lookup_table()
    bm.edges.ensure_lookup_table()
    for f in bm.faces:
        f.select_set(False)
    for e in bm.edges:
        e.select_set(False)
    for i in polygons:
        bm.faces[i].select_set(True)
    for i in edges:
        bm.edges[i].select_set(True)
    bm.select_flush_mode()
    bmesh.update_edit_mesh(obj.data)


def popup_problems(context, name, report, selected: int, seam_edges: int = 0) -> None:
    if bpy.app.background or context.window is None:  # bpy-as-a-module has a window, no screen
        return

    def draw(menu, _context):
        col = menu.layout.column()
        for p in report.problems:
            col.label(text=f"{p.check}: {p.message}", icon="ERROR")
        if selected:
            col.label(text=f"{selected} faces selected in Edit Mode", icon="RESTRICT_SELECT_OFF")
        if seam_edges:
            col.label(text=f"{seam_edges} worst seam edges selected in Edit Mode",
                      icon="RESTRICT_SELECT_OFF")

    context.window_manager.popup_menu(draw, title=f"prismbake validate: {name}", icon="ERROR")


CLASSES = (PRISMBAKE_OT_preview, PRISMBAKE_OT_turntable, PRISMBAKE_OT_bake,
           PRISMBAKE_OT_validate, PRISMBAKE_OT_export_usd)

"""Panels: Properties > Object > prismbake, and the 3D View sidebar's "prismbake" tab.

Both draw the same thing: what displacement was found (detect.py), what is missing, the
operator buttons (greyed with the reason when they cannot run), outputs, last results.
"""
from __future__ import annotations

import bpy

from . import cli_bridge, detect, jobs, operators, prefs


def draw_panel(layout, context) -> None:
    obj = context.active_object
    binary, why = cli_bridge.find_binary(prefs.get(context).binary_path)
    if binary is None:
        layout.label(text=why, icon="ERROR")
    if obj is None or obj.type != "MESH":
        layout.label(text="Select a mesh object", icon="INFO")
        return
    info = detect.detect(obj)
    box = layout.box()
    if info.source:
        for line in info.summary_lines():
            box.label(text=line)
    for p in info.problems:
        box.label(text=p, icon="ERROR")
    for w in info.warnings:
        box.label(text=w, icon="INFO")
    if info.ok and not info.warnings:
        box.label(text="Ready", icon="CHECKMARK")

    col = layout.column(align=True)
    col.operator(operators.PRISMBAKE_OT_preview.bl_idname, icon="RENDER_STILL")
    col.operator(operators.PRISMBAKE_OT_validate.bl_idname, icon="CHECKBOX_HLT")
    settings = context.scene.prismbake
    col = layout.column(align=True)
    col.prop(settings, "turntable_frames")
    col.prop(settings, "turntable_dir")
    col.operator(operators.PRISMBAKE_OT_turntable.bl_idname, icon="RENDER_ANIMATION")
    col = layout.column(align=True)
    col.prop(settings, "prisms_path")
    col.operator(operators.PRISMBAKE_OT_bake.bl_idname, icon="MOD_DISPLACE")
    col = layout.column(align=True)
    col.prop(settings, "usd_path")
    col.operator(operators.PRISMBAKE_OT_export_usd.bl_idname, icon="EXPORT")
    layout.prop(settings, "max_disp")
    layout.prop(settings, "max_seam_jump")
    _draw_results(layout, jobs.RESULTS.get(obj.name, {}))


def _draw_results(layout, results: dict) -> None:
    if not results:
        return
    box = layout.box()
    if "error" in results:
        box.label(text=results["error"], icon="ERROR")
    preview = results.get("preview")
    if preview is not None:
        box.label(text=f"Preview: {preview.total_seconds:.2f} s (render {preview.render_seconds:.2f} s)",
                  icon="IMAGE_DATA")
    validate = results.get("validate")
    if validate is not None:
        if not validate["problems"]:
            box.label(text=f"Validate: {len(validate['passed'])} checks pass", icon="CHECKMARK")
        for p in validate["problems"]:
            box.label(text=f"{p['check']}: {p['message']}", icon="ERROR")
    for key, label in (("bake", "Prism table"), ("usd", "USD"), ("turntable", "Turntable")):
        if key in results:
            r = results[key]
            box.label(text=f"{label}: {r.get('path') or r.get('folder')}", icon="FILE")


class PRISMBAKE_PT_object(bpy.types.Panel):
    bl_label = "prismbake"
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "object"

    @classmethod
    def poll(cls, context):
        return context.active_object is not None

    def draw(self, context):
        draw_panel(self.layout, context)


class PRISMBAKE_PT_sidebar(bpy.types.Panel):
    bl_label = "prismbake"
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "prismbake"

    def draw(self, context):
        draw_panel(self.layout, context)


CLASSES = (PRISMBAKE_PT_object, PRISMBAKE_PT_sidebar)

"""Add-on preferences (the binary and render defaults) and per-scene output settings."""
from __future__ import annotations

import bpy
from bpy.props import EnumProperty, IntProperty, FloatProperty, StringProperty

from . import cli_bridge


class PrismbakePreferences(bpy.types.AddonPreferences):
    # An extension's package is "bl_ext.<repository>.prismbake"; a legacy add-on's "prismbake".
    bl_idname = __package__

    binary_path: StringProperty(
        name="prismbake binary",
        description="Path of the prismbake executable; empty: the first `prismbake` on PATH",
        default="", subtype="FILE_PATH")
    method: EnumProperty(
        name="Method",
        description="Intersection method the CLI uses for previews and turntables",
        items=[("pdm", "PDM", "Projective Displacement Mapping: fast, no tessellation"),
               ("reference", "Reference", "Exact tessellated reference: slow, ground truth")],
        default="pdm")
    device: EnumProperty(
        name="Device",
        description="Where the CLI renders",
        items=[("cpu", "CPU", "Render on the CPU (all cores)"),
               ("gpu", "GPU", "Render with wgpu on a GPU"),
               ("auto", "Auto", "GPU when one is available, else CPU")],
        default="cpu")
    resolution: IntProperty(
        name="Resolution",
        description="Width and height in pixels of previews and turntable frames",
        default=256, min=16, max=8192, soft_max=2048)
    samples: IntProperty(
        name="Samples",
        description="Samples per pixel (jittered inside the pixel when more than 1)",
        default=1, min=1, max=4096, soft_max=64)
    timeout: FloatProperty(
        name="Timeout",
        description="Longest a job run from a script (not the interactive, cancellable one) may take",
        default=600.0, min=1.0, max=86400.0, unit="TIME_ABSOLUTE")

    def draw(self, context):
        layout = self.layout
        layout.prop(self, "binary_path")
        path, why = cli_bridge.find_binary(self.binary_path)
        row = layout.row()
        row.label(text=f"Using {path}" if path else why, icon="CHECKMARK" if path else "ERROR")
        col = layout.column()
        col.prop(self, "method")
        col.prop(self, "device")
        col.prop(self, "resolution")
        col.prop(self, "samples")
        col.prop(self, "timeout")


def get(context=None) -> PrismbakePreferences:
    context = context or bpy.context
    return context.preferences.addons[__package__].preferences


def render_settings(context, aovs=("normal", "mask")) -> cli_bridge.RenderSettings:
    p = get(context)
    return cli_bridge.RenderSettings(p.method, p.device, p.resolution, p.samples, tuple(aovs))


class PrismbakeSceneSettings(bpy.types.PropertyGroup):
    turntable_frames: IntProperty(
        name="Frames", description="Frames of the turntable around the up axis",
        default=24, min=1, max=3600)
    turntable_dir: StringProperty(
        name="Turntable folder",
        description="Folder for turntable frames; empty: prismbake_turntable/<object> next to the .blend",
        default="", subtype="DIR_PATH")
    prisms_path: StringProperty(
        name="Prism table",
        description="Where Bake writes the .prisms file; empty: <object>.prisms next to the .blend",
        default="", subtype="FILE_PATH")
    usd_path: StringProperty(
        name="USD file",
        description="Where Export USD writes the asset; empty: <object>.usda next to the .blend",
        default="", subtype="FILE_PATH")
    max_disp: FloatProperty(
        name="Max displacement",
        description="Validate fails when |displacement| can exceed this (world units); 0: no limit",
        default=0.0, min=0.0, soft_max=10.0, unit="LENGTH")
    max_seam_jump: FloatProperty(
        name="Max seam jump",
        description="Validate fails when the height map jumps across a UV seam by more than this "
                    "fraction of the displacement scale (renders stitch seams either way)",
        default=0.02, min=0.0, soft_max=1.0)


CLASSES = (PrismbakePreferences, PrismbakeSceneSettings)

"""prismbake for Blender: preview, validate, bake and export displacement with the prismbake CLI.

Layers (the glTF-Blender-IO split): `cli_bridge` (no bpy: arguments, subprocess, JSON),
`detect` (reads the object, returns plain data), `export` (temporary GLB), `jobs` (modal
operator base), `operators`, `ui`, `prefs`. See README.md in this folder.
"""
import bpy

from . import jobs, operators, prefs, ui

_CLASSES = (*prefs.CLASSES, *operators.CLASSES, *ui.CLASSES)


def register():
    for cls in _CLASSES:
        bpy.utils.register_class(cls)
    bpy.types.Scene.prismbake = bpy.props.PointerProperty(type=prefs.PrismbakeSceneSettings)


def unregister():
    running = jobs.RUNNING.pop("job", None)
    if running is not None:
        running.cancel()
    del bpy.types.Scene.prismbake
    for cls in reversed(_CLASSES):
        bpy.utils.unregister_class(cls)

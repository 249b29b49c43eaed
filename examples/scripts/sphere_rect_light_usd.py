"""The example sphere exported to USD by Blender, with a normalized RectLight added by usd-core:
the lit USD asset of docs/materials.md's "A rect light" comparisons against Cycles.

    .venv/bin/python examples/scripts/sphere_rect_light_usd.py OUT_DIR [--at 2.5,-2,2.5] [--rig]
    .venv/bin/python examples/scripts/compare_cycles_beauty.py OUT_DIR/sphere.usda ...

Writes OUT_DIR/sphere.usda (Z-up, as Blender exports it, with the glTF's camera), the height
map and its sidecar. The light: 1.5 x 1, intensity 40, colour (1, 0.8, 0.6), at `--at`,
aimed at the origin (its -Z towards the sphere). `--rig` adds a fill, a rim and an under light
(a sphere light in front on the left, a disk behind and above, a point below; a lookdev rig
of four lights, for the light picking's noise). Needs bpy==5.0.1 and usd-core
(tests/python/requirements.txt).
"""
import argparse
import pathlib
import shutil

import bpy
from pxr import Gf, Usd, UsdGeom, UsdLux

ROOT = pathlib.Path(__file__).resolve().parents[2]


def aim(light, at):
    """Put `light` at `at` ("x,y,z"), its -Z towards the origin and its X level."""
    pos = Gf.Vec3d(*map(float, at.split(",")))
    z = pos.GetNormalized()
    x = Gf.Cross(Gf.Vec3d(0, 0, 1), z).GetNormalized()
    y = Gf.Cross(z, x)
    m = Gf.Matrix4d(*x, 0, *y, 0, *z, 0, *pos, 1)
    UsdGeom.Xformable(light.GetPrim()).AddTransformOp().Set(m)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("out")
    ap.add_argument("--at", default="2.5,-2,2.5", help="the light's position, x,y,z (Z up)")
    ap.add_argument("--rig", action="store_true", help="add a fill, a rim and an under light")
    a = ap.parse_args()
    out = pathlib.Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.import_scene.gltf(filepath=str(ROOT / "examples/sphere/sphere.glb"))
    usd = out / "sphere.usda"
    bpy.ops.wm.usd_export(filepath=str(usd), export_cameras=True, export_lights=True,
                          export_materials=False)
    stage = Usd.Stage.Open(str(usd))
    light = UsdLux.RectLight.Define(stage, "/RectKey")
    light.CreateWidthAttr(1.5)
    light.CreateHeightAttr(1.0)
    light.CreateIntensityAttr(40.0)
    light.CreateNormalizeAttr(True)
    light.CreateColorAttr(Gf.Vec3f(1.0, 0.8, 0.6))
    aim(light, a.at)
    if a.rig:
        fill = UsdLux.SphereLight.Define(stage, "/Fill")
        fill.CreateRadiusAttr(0.3)
        fill.CreateIntensityAttr(100.0)
        fill.CreateNormalizeAttr(True)
        fill.CreateColorAttr(Gf.Vec3f(0.6, 0.8, 1.0))
        aim(fill, "-3,-2,0.5")
        rim = UsdLux.DiskLight.Define(stage, "/Rim")
        rim.CreateRadiusAttr(0.5)
        rim.CreateIntensityAttr(60.0)
        rim.CreateNormalizeAttr(True)
        aim(rim, "0.5,3,2")
        under = UsdLux.SphereLight.Define(stage, "/Under")
        under.CreateTreatAsPointAttr(True)
        under.CreateIntensityAttr(30.0)
        under.CreateNormalizeAttr(True)
        under.CreateColorAttr(Gf.Vec3f(1.0, 0.6, 0.4))
        aim(under, "0.3,-0.5,-2.2")
    stage.Save()
    shutil.copy(ROOT / "examples/maps/rock_1024.png", out / "rock_1024.png")
    (out / "sphere.prismbake.toml").write_text(
        'disp = "rock_1024.png"\nscale = 0.08\nmidlevel = 0.5\nwrap = "repeat"\n')
    print(usd)


if __name__ == "__main__":
    main()

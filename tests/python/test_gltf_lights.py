"""A glTF's `KHR_lights_punctual` directional light is the beauty's key light, as Blender's own
glTF importer makes it a sun: the same direction, strength (lux / 683, W/m²) in the same colour,
and width."""
import json
import textwrap

import numpy as np


BLENDER = textwrap.dedent(
    """
    import json, math, sys, bpy
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.import_scene.gltf(filepath=sys.argv[1])
    sun = next(o for o in bpy.context.scene.objects if o.type == "LIGHT")
    print("RESULT " + json.dumps({"type": sun.data.type, "energy": sun.data.energy,
                                  "color": list(sun.data.color),
                                  "angle": math.degrees(sun.data.angle),
                                  "toward": list(sun.matrix_world.col[2][:3])}))
    """
)


def test_a_directional_light_is_the_key_light_as_blender_imports_it(run, blender, tmp_path, edited_sphere):
    # Turned 40° about +Y after 30° down about +X: azimuth 40°, elevation 30°.
    q = (np.array([0, np.sin(np.radians(20)), 0, np.cos(np.radians(20))]),
         np.array([np.sin(np.radians(-15)), 0, 0, np.cos(np.radians(-15))]))
    (x1, y1, z1, w1), (x2, y2, z2, w2) = q
    rotation = [w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2, w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
                w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2, w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2]
    def add_a_sun(doc):
        doc.setdefault("extensionsUsed", []).append("KHR_lights_punctual")
        doc.setdefault("extensions", {})["KHR_lights_punctual"] = {
            "lights": [{"type": "directional", "intensity": 2049.0, "color": [1.0, 0.6, 0.3], "name": "Sun"}]}
        doc["nodes"].append({"name": "SunNode", "rotation": rotation,
                             "extensions": {"KHR_lights_punctual": {"light": 0}}})
        doc["scenes"][doc.get("scene", 0)]["nodes"].append(len(doc["nodes"]) - 1)
    asset = edited_sphere("sunny", add_a_sun)
    proc = run("render", asset, "--aov", "beauty", "--res", "8x8", "--spp", "1", "--json",
               "-o", tmp_path / "out", check=0)
    summary = json.loads(proc.stdout)
    key = summary["key_light"]
    assert key.startswith("the file's directional light 'SunNode' ("), key
    az = float(key.split("azimuth ")[1].split("°")[0])
    el = float(key.split("elevation ")[1].split("°")[0])
    irradiance = float(key.split("irradiance ")[1].split(",")[0])
    colour = np.array([float(c) for c in key.split("colour (")[1].split(")")[0].split(",")])
    assert abs(az - 40.0) < 0.1 and abs(el - 30.0) < 0.1, key
    assert summary["beauty_rays"]["key_shadow_rays"] > 0, summary

    theirs = blender(BLENDER, asset)
    assert theirs["type"] == "SUN", theirs
    # What each casts: our irradiance (the light's luminance) times our colour of unit luminance,
    # Blender's strength times its colour.
    luminance = 0.2126 * 1.0 + 0.7152 * 0.6 + 0.0722 * 0.3
    assert abs(irradiance - 3.0 * luminance) < 1e-3, key
    assert np.allclose(irradiance * colour, theirs["energy"] * np.array(theirs["color"]), rtol=2e-3), (key, theirs)
    assert f"{theirs['angle']:.3f}" == "0.526" and "0.526° across" in key, (key, theirs)
    a, e = np.radians(az), np.radians(el)
    ours = np.array([np.sin(a) * np.cos(e), np.sin(e), np.cos(a) * np.cos(e)])
    toward = np.array(theirs["toward"]) / np.linalg.norm(theirs["toward"])
    # Blender is Z-up: glTF (x, y, z) is Blender (x, -z, y).
    assert np.allclose([ours[0], -ours[2], ours[1]], toward, atol=2e-3), (key, theirs)


BLENDER_LOCAL = textwrap.dedent(
    """
    import json, math, sys, bpy
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.import_scene.gltf(filepath=sys.argv[1])
    out = {}
    for o in bpy.context.scene.objects:
        if o.type == "LIGHT":
            d = o.data
            out[o.name] = {"type": d.type, "energy": d.energy, "radius": d.shadow_soft_size,
                           "color": list(d.color), "at": list(o.matrix_world.col[3][:3]),
                           "down": [-x for x in o.matrix_world.col[2][:3]],
                           "spot_size": math.degrees(getattr(d, "spot_size", 0.0))}
    print("RESULT " + json.dumps(out))
    """
)


def test_point_and_spot_lights_light_as_blender_imports_them(run, blender, tmp_path, edited_sphere):
    """A glTF point light and a spot light beside the sphere light the beauty where Blender's
    importer puts its lamps: at the same places, of the same intensity (candela / 683 W/sr
    each, Blender's 4π times that in watts), a spot's cone as wide as Blender's spot size."""
    down = [np.sin(np.radians(-22.5)), 0, 0, np.cos(np.radians(-22.5))]  # 45° about −X: aimed down at the sphere

    def add_lights(doc):
        doc.setdefault("extensionsUsed", []).append("KHR_lights_punctual")
        doc.setdefault("extensions", {})["KHR_lights_punctual"] = {"lights": [
            {"type": "point", "intensity": 500.0, "color": [1.0, 0.8, 0.6], "name": "Bulb"},
            {"type": "spot", "intensity": 900.0, "name": "Cone",
             "spot": {"innerConeAngle": 0.3, "outerConeAngle": 0.6}}]}
        first = len(doc["nodes"])
        doc["nodes"] += [
            {"name": "BulbNode", "translation": [1.5, 2.0, 0.5],
             "extensions": {"KHR_lights_punctual": {"light": 0}}},
            {"name": "ConeNode", "translation": [0.0, 2.5, 2.5], "rotation": down,
             "extensions": {"KHR_lights_punctual": {"light": 1}}},
        ]
        doc["scenes"][doc.get("scene", 0)]["nodes"] += [first, first + 1]
    asset = edited_sphere("bulbs", add_lights)
    proc = run("render", asset, "--aov", "beauty", "--res", "8x8", "--spp", "1", "--json",
               "-o", tmp_path / "out", check=0)
    lights = json.loads(proc.stdout)["lights"]
    assert len(lights) == 2 and lights[0].startswith("point 'BulbNode' at (1.500, 2.000, 0.500)"), lights
    assert lights[1].startswith("spot 'ConeNode' at (0.000, 2.500, 2.500)"), lights

    theirs = blender(BLENDER_LOCAL, asset)
    bulb, cone = theirs["BulbNode"], theirs["ConeNode"]
    assert bulb["type"] == "POINT" and cone["type"] == "SPOT", theirs
    # Blender is Z-up: glTF (x, y, z) is Blender (x, -z, y).
    assert np.allclose(bulb["at"], [1.5, -0.5, 2.0], atol=1e-5), bulb
    assert np.allclose(cone["at"], [0.0, -2.5, 2.5], atol=1e-5), cone
    # Intensity: ours is the light's luminance in W/sr; Blender's watts over 4π, times its
    # colour's luminance.
    lum = lambda c: 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]
    ours = [float(l.split("intensity ")[1].split(",")[0]) for l in lights]
    for mine, lamp in zip(ours, (bulb, cone)):
        assert abs(mine - lamp["energy"] / (4 * np.pi) * lum(lamp["color"])) < 1e-3 * mine, (mine, lamp)
    # The spot's cone: ours from 0.3 to 0.6 rad about its axis; Blender's spot size is the
    # outer cone's full width, its axis the lamp's −Z.
    outer = float(lights[1].split(" to ")[1].split("°")[0])
    assert abs(outer - np.degrees(0.6)) < 0.05 and abs(cone["spot_size"] - 2 * outer) < 0.1, (lights[1], cone)
    axis = np.array([float(x) for x in lights[1].split("about (")[1].split(")")[0].split(",")])
    assert np.allclose([axis[0], -axis[2], axis[1]], cone["down"], atol=2e-3), (axis, cone)
    assert bulb["radius"] == 0.0, bulb

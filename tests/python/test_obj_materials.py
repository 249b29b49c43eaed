"""An `.mtl` reads as Blender's OBJ importer reads it: the real bpy imports the same files, and
`prismbake inspect --json` must give each material the roughness, metallic, reflectance (F0, from
the Principled BSDF's IOR and Specular IOR Level as Cycles combines them), clearcoat and emission
that Blender's Principled BSDF gets, and the alpha that cuts the surface away."""
import json
import struct
import textwrap
import zlib

import pytest

# Classic `illum`/`Ka`/`Ks`/`Ns`/`Ni` entries as 3ds Max, Maya and Blender's own exporter write
# them, the PBR extension's values over them, and maps in the values' places.
ENTRIES = {
    "plain": "Kd 0.8 0.2 0.1",
    "max_default": "Ns 10\nNi 1.5\nd 1\nTr 0\nTf 1 1 1\nillum 2\nKa 0.588 0.588 0.588\n"
                   "Kd 0.588 0.588 0.588\nKs 0 0 0\nKe 0 0 0",
    "shiny": "Ns 900\nKd 0.8 0.8 0.8\nKs 1 1 1\nNi 1.5\nillum 2",
    "highlight_only": "Kd 0.5 0.5 0.5\nillum 2",
    "over_1000": "Kd 0.5 0.5 0.5\nNs 1500\nKs 2 0.5 0.5",
    "negative_ns": "Kd 0.5 0.5 0.5\nNs -5\nillum 1",
    "blender_export": "Ns 360\nKa 0.3 0.3 0.3\nKd 0.8 0.8 0.8\nKs 0.7 0.7 0.7\nKe 0 0 0\n"
                      "Ni 1.45\nd 1\nillum 3",
    "mirror": "Kd 0.9 0.9 0.9\nillum 3",
    "reflection_ka": "Kd 0.9 0.9 0.9\nKa 0.4 0.5 0.6\nillum 8",
    "ka_no_reflection": "Kd 0.9 0.9 0.9\nKa 1 1 1\nillum 2\nKs 0.5 0.5 0.5\nNs 250",
    "refraction": "Kd 0.9 0.9 0.9\nillum 6\nKs 0.5 0.5 0.5",
    "glass": "Kd 0.9 0.9 0.9\nillum 4\nKs 0.5 0.5 0.5",
    "index_below_1": "Kd 0.9 0.9 0.9\nNi 0.5\nKs 0.5 0.5 0.5",
    "index_0": "Kd 0.9 0.9 0.9\nNi 0\nKs 1 1 1",
    "pbr": "Kd 0.8 0.8 0.8\nNs 1000\nKs 0.5 0.5 0.5\nPr 0.3\nPm 0.7\nillum 3\nKa 0.1 0.1 0.1",
    "coat": "Kd 0.8 0.8 0.8\nPc 0.8\nPcr 0.1\nKs 0.5 0.5 0.5",
    "glow": "Kd 0.8 0.8 0.8\nKe 2 1 0",
    "dissolved": "Kd 0.8 0.8 0.8\nd 0.4\nTr 0.1",
    "alpha_map": "Kd 0.8 0.8 0.8\nd 0.4\nmap_d grey.png",
    "specular_after_index": "illum 2\nKs 0.25 0.25 0.25\nNi 2\nKd 0.8 0.8 0.8",
    "roughness_map": "Kd 0.8 0.8 0.8\nNs 500\nmap_Ns grey.png",
    "metallic_map": "Kd 0.8 0.8 0.8\nillum 3\nrefl grey.png",
}

BLENDER = textwrap.dedent(
    """
    import json, sys, bpy
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.wm.obj_import(filepath=sys.argv[1])
    out = {}
    for m in bpy.data.materials:
        if not m.node_tree:
            continue
        n = next(x for x in m.node_tree.nodes if x.type == "BSDF_PRINCIPLED")
        value = lambda k: (None if n.inputs[k].is_linked else
                           (list(n.inputs[k].default_value)[:3]
                            if hasattr(n.inputs[k].default_value, "__len__")
                            else n.inputs[k].default_value))
        out[m.name] = {k: value(k) for k in ("Base Color", "Roughness", "Metallic", "IOR",
                                             "Specular IOR Level", "Coat Weight",
                                             "Coat Roughness", "Emission Color",
                                             "Emission Strength", "Alpha")}
    print("RESULT " + json.dumps(out))
    """
)


def grey_png(path):
    """A 2x2 grey 8-bit PNG."""
    raw = b"".join(b"\x00" + bytes([100, 100]) for _ in range(2))
    chunk = lambda t, d: (struct.pack(">I", len(d)) + t + d
                          + struct.pack(">I", zlib.crc32(t + d) & 0xFFFFFFFF))
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", 2, 2, 8, 0, 0, 0, 0))
                     + chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b""))


def test_an_mtl_reads_as_blenders_importer_reads_it(run, blender, tmp_path):
    grey_png(tmp_path / "grey.png")
    obj = "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\n"
    obj += "".join(f"usemtl {name}\nf 1/1 2/2 3/3\n" for name in ENTRIES)
    (tmp_path / "m.obj").write_text(obj)
    (tmp_path / "m.mtl").write_text("".join(f"newmtl {k}\n{v}\n\n" for k, v in ENTRIES.items()))

    ours = {m["name"]: m for m in json.loads(run("inspect", tmp_path / "m.obj", "--json",
                                                 check=0).stdout)["materials"]}
    theirs = blender(BLENDER, tmp_path / "m.obj")
    assert set(ours) == set(theirs) == set(ENTRIES), (sorted(ours), sorted(theirs))
    close = lambda a, b: abs(a - b) < 1e-4
    for name in ENTRIES:
        o, t = ours[name], theirs[name]
        why = f"{name}: ours {o}, Blender's {t}"
        assert all(close(a, b) for a, b in zip(o["base_color"], t["Base Color"])), why
        if t["Roughness"] is None:
            assert "roughness_texture" in o and o["roughness"] == 1.0, why
        else:
            assert "roughness_texture" not in o and close(o["roughness"], t["Roughness"]), why
        if t["Metallic"] is None:
            assert "metallic_texture" in o and o["metallic"] == 1.0, why
        else:
            assert "metallic_texture" not in o and close(o["metallic"], t["Metallic"]), why
        # Cycles: the index's F0, times twice the Specular IOR Level.
        ior = t["IOR"]
        f0 = min(((ior - 1) / (ior + 1)) ** 2 * 2 * t["Specular IOR Level"], 1.0)
        assert close(o["specular"], f0), why
        coat = o.get("clearcoat", [0.0, None])
        assert close(coat[0], t["Coat Weight"]), why
        if t["Coat Weight"] > 0:
            assert close(coat[1], t["Coat Roughness"]), why
        # The alpha (Blender: `d`, not `Tr`; `map_d`'s alpha channel in its place) lets rays
        # through.
        if t["Alpha"] is None:
            alpha = "blend, alpha 1 x texture grey.png, alpha channel"
        else:
            alpha = None if t["Alpha"] >= 1 else f"blend, alpha {t['Alpha']:.1f}"
        assert o.get("alpha") == alpha, why
        glow = [c * t["Emission Strength"] for c in t["Emission Color"]]
        assert all(close(a, b) for a, b in zip(o.get("emission", [0.0] * 3), glow)), why
    # The cases do differ: a plain Kd is a rough Lambert without specular, a Blender export
    # keeps its roughness, metalness and specular level.
    assert (ours["plain"]["roughness"], ours["plain"]["specular"]) == (1.0, 0.0)
    assert close(ours["blender_export"]["roughness"], 0.4)
    assert close(ours["blender_export"]["metallic"], 0.3)


EXPORT = textwrap.dedent(
    """
    import sys, bpy
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.mesh.primitive_plane_add()
    m = bpy.data.materials.new("Painted")
    m.use_nodes = True
    n = m.node_tree.nodes["Principled BSDF"]
    for k, v in (("Roughness", 0.4), ("Metallic", 0.3), ("Specular IOR Level", 0.7),
                 ("IOR", 1.45), ("Coat Weight", 0.2), ("Coat Roughness", 0.1)):
        n.inputs[k].default_value = v
    bpy.context.object.data.materials.append(m)
    bpy.ops.wm.obj_export(filepath=sys.argv[1] + "/classic.obj")
    bpy.ops.wm.obj_export(filepath=sys.argv[1] + "/pbr.obj", export_pbr_extensions=True)
    print("RESULT {}")
    """
)


def test_blenders_obj_export_reads_back_with_its_values(run, blender, tmp_path):
    """Blender's OBJ exporter writes a Principled BSDF as Ns, Ka, Ks, Ni and illum (and, with
    its PBR option, Pr, Pm, Pc, Pcr): both files read back with the roughness, metallic and
    reflectance it had (the classic file has no coat)."""
    blender(EXPORT, tmp_path)
    f0 = ((1.45 - 1) / (1.45 + 1)) ** 2 * 2 * 0.7
    for name, coat in (("classic", None), ("pbr", [0.2, 0.1])):
        (m,) = json.loads(run("inspect", tmp_path / f"{name}.obj", "--json", check=0).stdout)["materials"]
        assert abs(m["roughness"] - 0.4) < 1e-5 and abs(m["metallic"] - 0.3) < 1e-5, (name, m)
        assert abs(m["specular"] - f0) < 1e-5, (name, m)
        assert m.get("clearcoat") == (coat and [pytest.approx(c) for c in coat]), (name, m)

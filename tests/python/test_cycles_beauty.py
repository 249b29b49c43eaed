"""The beauty against Blender Cycles (the real bpy wheel): the example sphere, displaced, under
an HDRI whose colour changes around the horizon, in a Principled BSDF / the same material
flags. The asset's mean colour must agree within 5% per channel; the environment turned by a
quarter (`--env-rotate 90`) must not, so a turned or mirrored environment mapping fails here.
Through an orthographic glTF camera, which Blender imports as its own orthographic camera, the
silhouettes must agree as closely as through the perspective one, and a pinhole's must not.
`examples/scripts/compare_cycles_beauty.py` is the script; docs/materials.md has the figures at
full size."""
import json
import pathlib
import struct
import subprocess
import sys

ROOT = pathlib.Path(__file__).resolve().parents[2]
SCRIPT = ROOT / "examples" / "scripts" / "compare_cycles_beauty.py"


def compare(prismbake, tmp_path, *extra, asset=ROOT / "examples" / "sphere" / "sphere.glb"):
    out = subprocess.run([sys.executable, str(SCRIPT), str(asset),
                          "--res", "48", "--spp", "32", "--prismbake", prismbake,
                          "--keep", str(tmp_path / "_".join(extra or ("plain",))), *extra],
                         capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr[-3000:]
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_the_beauty_agrees_with_cycles_under_the_same_hdri(prismbake, tmp_path):
    same = compare(prismbake, tmp_path)
    assert same["asset_pixels"] > 500, same
    for ratio in same["asset_mean_ratio"]:
        assert abs(ratio - 1) < 0.05, same
    turned = compare(prismbake, tmp_path, "--env-rotate", "90")
    assert max(abs(r - 1) for r in turned["asset_mean_ratio"]) > 0.15, turned


def orthographic_sphere(tmp_path, ymag):
    """The example sphere with its camera made orthographic (`ymag`: half the view's height),
    and a sidecar naming the example's map."""
    glb = (ROOT / "examples" / "sphere" / "sphere.glb").read_bytes()
    n = struct.unpack("<I", glb[12:16])[0]
    doc = json.loads(glb[20:20 + n])
    doc["cameras"][0] = {"name": "Camera", "type": "orthographic",
                         "orthographic": {"xmag": ymag, "ymag": ymag, "znear": 0.05, "zfar": 100.0}}
    text = json.dumps(doc).encode()
    text += b" " * (-len(text) % 4)
    rest = glb[20 + n:]
    out = tmp_path / "ortho.glb"
    out.write_bytes(struct.pack("<III", 0x46546C67, 2, 20 + len(text) + len(rest))
                    + struct.pack("<II", len(text), 0x4E4F534A) + text + rest)
    side = (ROOT / "examples" / "sphere" / "sphere.prismbake.toml").read_text()
    side = side.replace('"../maps/', '"' + str(ROOT / "examples" / "maps") + "/")
    (tmp_path / "ortho.prismbake.toml").write_text(side)
    return out


def test_an_orthographic_camera_frames_the_asset_as_in_cycles(prismbake, tmp_path):
    asset = orthographic_sphere(tmp_path, 1.3)
    same = compare(prismbake, tmp_path, asset=asset)
    assert same["mask_mismatch"] < 0.01, same
    for ratio in same["asset_mean_ratio"]:
        assert abs(ratio - 1) < 0.05, same
    pinhole = compare(prismbake, tmp_path, "--extra", "--fov 40", asset=asset)
    assert pinhole["mask_mismatch"] > 0.05, pinhole

"""Fixtures for the add-on tests: the real bpy wheel, the real prismbake binary.

The extension is enabled the way a developer installs a working copy: a user extensions
repository (a temporary folder) gets a symlink `prismbake -> blender_addon/`, and
`addon_utils.enable("bl_ext.<repo>.prismbake")` loads it, so the tests run the source tree
itself under the package name Blender gives an installed extension. (test_install.py also
installs a zip of the folder with `bpy.ops.extensions.package_install_files`, the
"Install from Disk" path.) test.sh sets HOME to a fresh folder, so no user settings leak in.
"""
import os
import pathlib
import sys
import tempfile

import pytest

sys.path.insert(0, str(pathlib.Path(__file__).parent))  # pbtest.py, glb.py

from pbtest import ADDON, MAP, PACKAGE, REPO_MODULE, ROOT  # noqa: E402


@pytest.fixture(scope="session")
def prismbake_bin():
    path = os.environ.get("PRISMBAKE_BIN", str(ROOT / "target" / "debug" / "prismbake"))
    assert os.path.isfile(path), f"{path} is missing: run `cargo build` first"
    return path


@pytest.fixture(scope="session")
def bpy_module():
    import bpy
    return bpy


@pytest.fixture(scope="session")
def addon(bpy_module):
    """The enabled extension's package (its modules: addon.cli_bridge, addon.operators, ...)."""
    import addon_utils
    bpy = bpy_module
    repo_dir = tempfile.mkdtemp(prefix="prismbake-extensions-")
    os.symlink(ADDON, os.path.join(repo_dir, "prismbake"))
    bpy.context.preferences.extensions.repos.new(
        name="prismbake tests", module=REPO_MODULE, custom_directory=repo_dir, source="USER")
    module = addon_utils.enable(PACKAGE, default_set=True, handle_error=_raise)
    assert module is not None, f"{PACKAGE} did not enable"
    yield module
    addon_utils.disable(PACKAGE, default_set=True, handle_error=_raise)


def _raise(exc):
    raise exc


@pytest.fixture
def prefs(addon, bpy_module, prismbake_bin):
    p = bpy_module.context.preferences.addons[PACKAGE].preferences
    saved = {k: getattr(p, k) for k in ("binary_path", "method", "device", "resolution", "samples")}
    p.binary_path = prismbake_bin
    p.resolution = 64
    p.device = "cpu"
    yield p
    for k, v in saved.items():
        setattr(p, k, v)


@pytest.fixture
def scene(bpy_module, addon, prefs, tmp_path):
    """An empty scene, then: a UV sphere displaced through its material's Displacement node by
    an image texture, and a camera looking at it. Returns the sphere."""
    bpy = bpy_module
    clear_data(bpy)
    bpy.ops.mesh.primitive_uv_sphere_add(segments=32, ring_count=16, radius=1.0)
    sphere = bpy.context.active_object
    sphere.name = "Sphere"
    mat = bpy.data.materials.new("Displaced")
    if bpy.app.version < (5, 0, 0):  # always node-based from 5.0, where use_nodes is deprecated
        mat.use_nodes = True
    if hasattr(mat, "displacement_method"):  # on the material since 4.1 (was mat.cycles)
        mat.displacement_method = "DISPLACEMENT"
    tree = mat.node_tree
    out = next(n for n in tree.nodes if n.bl_idname == "ShaderNodeOutputMaterial")
    disp = tree.nodes.new("ShaderNodeDisplacement")
    disp.inputs["Scale"].default_value = 0.08
    disp.inputs["Midlevel"].default_value = 0.5
    tex = tree.nodes.new("ShaderNodeTexImage")
    tex.image = bpy.data.images.load(str(MAP))
    tex.image.colorspace_settings.name = "Non-Color"
    tree.links.new(tex.outputs["Color"], disp.inputs["Height"])
    tree.links.new(disp.outputs["Displacement"], out.inputs["Displacement"])
    sphere.data.materials.append(mat)
    bpy.ops.object.camera_add(location=(0.0, -6.0, 1.0), rotation=(1.4, 0.0, 0.0))
    bpy.context.scene.camera = bpy.context.active_object
    for o in bpy.context.view_layer.objects.selected:
        o.select_set(False)
    sphere.select_set(True)
    bpy.context.view_layer.objects.active = sphere
    scene = bpy.context.scene
    scene.prismbake.turntable_dir = str(tmp_path / "turntable")
    scene.prismbake.prisms_path = str(tmp_path / "sphere.prisms")
    scene.prismbake.usd_path = str(tmp_path / "sphere.usda")
    scene.prismbake.max_disp = 0.0
    scene.prismbake.max_seam_jump = 0.02
    addon.jobs.RESULTS.clear()
    addon.jobs.RUNNING.clear()
    yield sphere
    if bpy.context.mode != "OBJECT":
        bpy.ops.object.mode_set(mode="OBJECT")


def clear_data(bpy):
    if bpy.context.mode != "OBJECT" and bpy.context.active_object is not None:
        bpy.ops.object.mode_set(mode="OBJECT")
    for coll in (bpy.data.objects, bpy.data.meshes, bpy.data.materials, bpy.data.images,
                 bpy.data.cameras, bpy.data.textures):
        for block in list(coll):
            coll.remove(block)


@pytest.fixture
def read_png():
    """A PNG as a float array (h, w, channels) in [0, 1], top row first, read by Blender."""
    import bpy
    import numpy as np

    def _read(path):
        img = bpy.data.images.load(str(path), check_existing=False)
        try:
            w, h = img.size
            px = np.empty(w * h * 4, dtype=np.float32)
            img.pixels.foreach_get(px)
            return px.reshape(h, w, 4)[::-1]
        finally:
            bpy.data.images.remove(img)
    return _read

"""The extension installs, enables and registers the way a user gets it; preferences are complete."""
import os
import tempfile
import zipfile

import pytest

from pbtest import ADDON, PACKAGE


def test_enabled_from_a_user_extensions_repository(bpy_module, addon):
    bpy = bpy_module
    assert PACKAGE in bpy.context.preferences.addons
    assert addon.__name__ == PACKAGE
    for op in ("preview", "turntable", "bake", "validate", "export_usd"):
        assert hasattr(bpy.ops.prismbake, op), op
    assert hasattr(bpy.types, "PRISMBAKE_PT_object") and hasattr(bpy.types, "PRISMBAKE_PT_sidebar")
    assert bpy.types.PRISMBAKE_PT_sidebar.bl_category == "prismbake"
    assert hasattr(bpy.context.scene, "prismbake")


def test_manifest_is_a_valid_extension(addon):
    import tomllib
    m = tomllib.loads((ADDON / "blender_manifest.toml").read_text())
    assert m["schema_version"] == "1.0.0" and m["id"] == "prismbake" and m["type"] == "add-on"
    assert m["blender_version_min"] == "4.2.0"


def test_install_from_disk_as_a_zip(bpy_module, addon):
    """What a user does with Edit > Preferences > Get Extensions > Install from Disk."""
    bpy = bpy_module
    folder = tempfile.mkdtemp(prefix="prismbake-zip-")
    path = os.path.join(folder, "prismbake-0.1.0.zip")
    with zipfile.ZipFile(path, "w") as z:
        for name in sorted(os.listdir(ADDON)):
            if name.endswith(".py") or name == "blender_manifest.toml":
                z.write(ADDON / name, name)
    repo = bpy.context.preferences.extensions.repos.new(
        name="zip install", module="prismbake_zip", custom_directory=tempfile.mkdtemp(), source="USER")
    try:
        # A second copy may not be enabled next to the one under test (same classes):
        # install only, then check what landed and that Blender lists it as an extension.
        result = bpy.ops.extensions.package_install_files(filepath=path, repo="prismbake_zip",
                                                          enable_on_install=False)
        assert result == {"FINISHED"}
        installed = os.path.join(repo.directory, "prismbake")
        assert os.path.isfile(os.path.join(installed, "blender_manifest.toml"))
        assert os.path.isfile(os.path.join(installed, "cli_bridge.py"))
        import addon_utils
        assert "bl_ext.prismbake_zip.prismbake" in {m.__name__ for m in addon_utils.modules(refresh=True)}
    finally:
        bpy.context.preferences.extensions.repos.remove(repo)


def test_every_preference_has_name_description_default_and_bounds(bpy_module, addon):
    rna = addon.prefs.PrismbakePreferences.bl_rna.properties
    settings = addon.prefs.PrismbakeSceneSettings.bl_rna.properties
    for props in (rna, settings):
        for p in props:
            if p.identifier in ("rna_type", "bl_idname", "name"):
                continue
            assert p.name and p.description, p.identifier
            if p.type in ("INT", "FLOAT"):
                assert p.hard_min < p.hard_max and p.hard_min <= p.default <= p.hard_max, p.identifier
    assert rna["binary_path"].default == "" and rna["binary_path"].subtype == "FILE_PATH"
    assert rna["method"].default == "pdm" and {i.identifier for i in rna["method"].enum_items} == {"pdm", "reference"}
    assert {i.identifier for i in rna["device"].enum_items} == {"cpu", "gpu", "auto"}
    assert (rna["resolution"].hard_min, rna["resolution"].hard_max) == (16, 8192)
    assert rna["samples"].hard_min == 1


def test_binary_found_on_path_when_no_path_is_set(bpy_module, addon, prefs, prismbake_bin, monkeypatch, scene):
    prefs.binary_path = ""
    monkeypatch.setenv("PATH", os.path.dirname(prismbake_bin))
    assert bpy_module.ops.prismbake.preview.poll()
    monkeypatch.setenv("PATH", "/nonexistent")
    assert not bpy_module.ops.prismbake.preview.poll()


@pytest.mark.parametrize("op", ["preview", "turntable", "bake", "validate", "export_usd"])
def test_missing_binary_greys_every_operator_and_says_why(bpy_module, prefs, scene, op):
    prefs.binary_path = "/nonexistent/prismbake"
    operator = getattr(bpy_module.ops.prismbake, op)
    assert not operator.poll()
    with pytest.raises(RuntimeError, match="prismbake binary not found at /nonexistent/prismbake"):
        operator()

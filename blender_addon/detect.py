"""Find the displacement on a Blender object and say what keeps it from being rendered.

Input: a Blender object (read through attributes only, so any object shaped like bpy's works);
output: a plain `DisplacementInfo` (strings and numbers) that the panel shows and the
operators turn into CLI flags. Two sources are recognised, in this order:
  1. the material's Displacement node feeding the active Material Output
     (Image Texture -> Height; Scale and Midlevel sockets; `node.space`);
  2. a Displace modifier with an image texture and UV coordinates.
`problems` block the operators; `warnings` are shown but do not.
"""
from __future__ import annotations

import dataclasses
import os

from . import cli_bridge

MAP_EXTENSIONS = (".exr", ".png", ".tif", ".tiff")


@dataclasses.dataclass
class DisplacementInfo:
    object_name: str
    source: str = ""            # "material" | "modifier" | "" when none was found
    where: str = ""             # e.g. 'material "Rock" node "Displacement"'
    image_name: str = ""
    image_path: str = ""        # absolute path of the file the CLI will read
    scale: float = 1.0          # as set in Blender (Scale socket / strength)
    midlevel: float = 0.5
    space: str = ""             # OBJECT | WORLD (node.space), LOCAL for the modifier
    world_scale: float = 1.0    # scale in world units, what the CLI gets
    uv_map: str = ""
    uv_set: int = 0             # index among the mesh's UV maps (the export keeps only this one)
    wrap: str = "repeat"
    problems: list = dataclasses.field(default_factory=list)
    warnings: list = dataclasses.field(default_factory=list)

    @property
    def ok(self) -> bool:
        return bool(self.source) and not self.problems

    def displacement(self, uv_set: int = 0) -> cli_bridge.Displacement:
        """CLI flags; `uv_set` is the UV set in the exported file (0: the export keeps one)."""
        return cli_bridge.Displacement(self.image_path, self.world_scale, self.midlevel,
                                       uv_set=uv_set, wrap=self.wrap)

    def summary_lines(self) -> list:
        if not self.source:
            return []
        return [self.where,
                f"image: {self.image_name or '-'}" + (f" ({self.image_path})" if self.image_path else ""),
                f"scale {self.scale:g}, midlevel {self.midlevel:g}, space {self.space or '-'}"
                + (f" -> {self.world_scale:g} world units" if self.world_scale != self.scale else ""),
                f"UV map: {self.uv_map or '-'}, wrap {self.wrap}"]


def _abspath(path: str, library=None) -> str:
    if not path.startswith("//"):
        return os.path.abspath(os.path.expanduser(path))
    import bpy  # only for blend-relative paths: everything else here is plain attribute access
    return bpy.path.abspath(path, library=library)


def detect(obj) -> DisplacementInfo:
    info = DisplacementInfo(object_name=getattr(obj, "name", "?"))
    if obj is None or getattr(obj, "type", "") != "MESH":
        info.problems.append("the active object is not a mesh")
        return info
    node_hit = _from_material(obj, info)
    modifiers = [m for m in obj.modifiers if m.type == "DISPLACE" and (m.show_viewport or m.show_render)]
    if node_hit:
        if modifiers:
            info.warnings.append(f'Displace modifier "{modifiers[0].name}" is ignored: the material\'s '
                                 f"Displacement node is used")
    elif modifiers:
        _from_modifier(obj, modifiers[0], info)
        if len(modifiers) > 1:
            info.warnings.append(f"{len(modifiers)} Displace modifiers: only \"{modifiers[0].name}\" is used")
    if not info.source:
        info.problems.append("no displacement found: add an Image Texture -> Displacement node to the "
                             "material output, or a Displace modifier with an image texture")
        return info
    _check_uvs(obj, info)
    _apply_object_scale(obj, info)
    return _check_image_file(info)


# --- material ------------------------------------------------------------------------------

def _from_material(obj, info: DisplacementInfo) -> bool:
    for slot in getattr(obj, "material_slots", []):
        mat = slot.material
        if mat is None or mat.node_tree is None or not _uses_nodes(mat):
            continue
        out = _active_output(mat.node_tree)
        if out is None or not out.inputs["Displacement"].is_linked:
            continue
        disp = _upstream(out.inputs["Displacement"])
        if disp is None or disp.bl_idname != "ShaderNodeDisplacement":
            what = disp.bl_idname if disp is not None else "nothing"
            info.source = "material"
            info.where = f'material "{mat.name}"'
            info.problems.append(f'material "{mat.name}": the output\'s Displacement comes from {what}, '
                                 f"not a Displacement node (vector displacement is not supported)")
            return True
        info.source = "material"
        info.where = f'material "{mat.name}", node "{disp.name}"'
        info.space = disp.space
        info.scale = _socket_value(disp, "Scale", info)
        info.midlevel = _socket_value(disp, "Midlevel", info)
        if disp.inputs["Normal"].is_linked:
            info.warnings.append("the Displacement node's Normal input is linked: prismbake uses the "
                                 "interpolated vertex normal")
        _displacement_method(mat, info)
        tex = _upstream(disp.inputs["Height"]) if disp.inputs["Height"].is_linked else None
        if tex is None:
            info.problems.append(f'material "{mat.name}": nothing feeds the Displacement node\'s Height: '
                                 f"connect an Image Texture")
            return True
        if tex.bl_idname != "ShaderNodeTexImage":
            info.problems.append(f'material "{mat.name}": Height comes from "{tex.name}" ({tex.bl_idname}); '
                                 f"prismbake needs an Image Texture node there")
            return True
        info.wrap = "clamp" if tex.extension in ("EXTEND", "CLIP") else "repeat"
        if tex.extension not in ("REPEAT", "EXTEND"):
            info.warnings.append(f'image node extension {tex.extension} is read as "{info.wrap}"')
        _image_into(tex.image, info, f'Image Texture "{tex.name}"')
        info.uv_map = _node_uv_map(tex, info)
        return True
    return False


def _uses_nodes(mat) -> bool:
    # Blender 5.0 materials always use their node tree (`use_nodes` is deprecated there);
    # before, a material could carry a node tree it did not use.
    import bpy
    if bpy.app.version >= (5, 0, 0):
        return True
    return bool(mat.use_nodes)


def _active_output(tree):
    outs = [n for n in tree.nodes if n.bl_idname == "ShaderNodeOutputMaterial"]
    for n in outs:
        if n.is_active_output and n.target in ("ALL", "CYCLES"):
            return n
    for n in outs:
        if n.target in ("ALL", "CYCLES"):
            return n
    return outs[0] if outs else None


def _upstream(socket):
    """The node feeding `socket`, through reroutes."""
    node = socket.links[0].from_node if socket.links else None
    while node is not None and node.bl_idname == "NodeReroute":
        node = node.inputs[0].links[0].from_node if node.inputs[0].links else None
    return node


def _socket_value(node, name: str, info: DisplacementInfo) -> float:
    sock = node.inputs[name]
    if sock.is_linked:
        info.warnings.append(f'the Displacement node\'s {name} is linked to a node: its unlinked value '
                             f"{sock.default_value:g} is used")
    return float(sock.default_value)


def _displacement_method(mat, info: DisplacementInfo) -> None:
    # Blender 4.1 moved the setting from `material.cycles` to the material itself.
    method = getattr(mat, "displacement_method", None)
    if method is None and hasattr(mat, "cycles"):
        method = getattr(mat.cycles, "displacement_method", None)
    if method == "BUMP":
        info.warnings.append(f'material "{mat.name}" displaces as Bump Only in Cycles; prismbake moves '
                             f"the surface (set Displacement to \"Displacement Only\" to compare)")


def _node_uv_map(tex, info: DisplacementInfo) -> str:
    vec = tex.inputs["Vector"]
    if not vec.is_linked:
        return ""
    src = _upstream(vec)
    link = vec.links[0]
    if src is not None and src.bl_idname == "ShaderNodeUVMap":
        return src.uv_map
    if src is not None and src.bl_idname == "ShaderNodeTexCoord" and link.from_socket.name == "UV":
        return ""
    name = src.name if src is not None else "?"
    info.warnings.append(f'the image\'s Vector input comes from "{name}": prismbake samples the UV map '
                         f"directly (mapping nodes are ignored)")
    return ""


# --- modifier ------------------------------------------------------------------------------

def _from_modifier(obj, mod, info: DisplacementInfo) -> None:
    info.source = "modifier"
    info.where = f'Displace modifier "{mod.name}"'
    info.scale = float(mod.strength)
    info.midlevel = float(mod.mid_level)
    info.space = "LOCAL"
    if mod.direction != "NORMAL":
        info.problems.append(f'Displace modifier "{mod.name}" moves along {mod.direction}: set Direction '
                             f"to Normal (prismbake displaces along the vertex normal)")
    if mod.texture_coords != "UV":
        info.problems.append(f'Displace modifier "{mod.name}" uses {mod.texture_coords} coordinates: '
                             f"set Coordinates to UV")
    info.uv_map = mod.uv_layer
    if getattr(mod, "vertex_group", ""):
        info.warnings.append(f'the vertex group "{mod.vertex_group}" of the modifier is ignored')
    tex = mod.texture
    if tex is None:
        info.problems.append(f'Displace modifier "{mod.name}" has no texture: add an Image texture')
        return
    if tex.type != "IMAGE":
        info.problems.append(f'Displace modifier "{mod.name}": texture "{tex.name}" is {tex.type}, '
                             f"not an image")
        return
    info.wrap = "clamp" if tex.extension in ("EXTEND", "CLIP", "CLIP_CUBE") else "repeat"
    _image_into(tex.image, info, f'texture "{tex.name}"')


# --- shared checks -------------------------------------------------------------------------

def _image_into(image, info: DisplacementInfo, holder: str) -> None:
    if image is None:
        info.problems.append(f"{holder} has no image: open a height map in it")
        return
    info.image_name = image.name
    if image.source == "GENERATED":
        info.problems.append(f'image "{image.name}" is generated in Blender: save it to a file first '
                             f"(Image > Save As)")
    elif image.source != "FILE":
        info.problems.append(f'image "{image.name}" is a {image.source.lower()} image: prismbake needs '
                             f"a single file")
    if image.packed_file is not None:
        info.problems.append(f'image "{image.name}" is packed into the .blend: save it to a file first '
                             f"(Image > Unpack or Save As)")
    if getattr(image, "is_dirty", False):
        info.warnings.append(f'image "{image.name}" has unsaved changes: prismbake reads the file on disk')
    cs = getattr(getattr(image, "colorspace_settings", None), "name", "")
    if cs == "sRGB" and image.source == "FILE":
        info.warnings.append(f'image "{image.name}" is in sRGB colour space: prismbake reads raw values; '
                             f"set Color Space to Non-Color so Blender agrees")
    if image.filepath:
        info.image_path = os.path.normpath(_abspath(image.filepath, library=getattr(image, "library", None)))


def _check_uvs(obj, info: DisplacementInfo) -> None:
    layers = list(obj.data.uv_layers)
    if not layers:
        info.problems.append(f'mesh "{obj.data.name}" has no UV map: unwrap it (Edit Mode > U > Unwrap)')
        return
    if info.uv_map:
        names = [l.name for l in layers]
        if info.uv_map not in names:
            info.problems.append(f'UV map "{info.uv_map}" does not exist on mesh "{obj.data.name}"')
            return
        info.uv_set = names.index(info.uv_map)
    else:
        render = [i for i, l in enumerate(layers) if l.active_render]
        info.uv_set = render[0] if render else 0
        info.uv_map = layers[info.uv_set].name


def _apply_object_scale(obj, info: DisplacementInfo) -> None:
    """World-unit scale: OBJECT-space (node) and modifier displacement scale with the object."""
    if info.space == "WORLD":
        info.world_scale = info.scale
        return
    sx, sy, sz = (abs(float(v)) for v in obj.matrix_world.to_scale())
    mean = (sx + sy + sz) / 3.0
    if max(sx, sy, sz) - min(sx, sy, sz) > 1e-4 * max(mean, 1e-12):
        info.warnings.append(f"object scale ({sx:g}, {sy:g}, {sz:g}) is not uniform: displacement uses "
                             f"the mean {mean:g}; apply the scale (Ctrl+A) for an exact match")
    info.world_scale = info.scale * mean


def _check_image_file(info: DisplacementInfo) -> DisplacementInfo:
    path = info.image_path
    if not path:
        if info.image_name and not any("generated" in p or "packed" in p for p in info.problems):
            info.problems.append(f'image "{info.image_name}" has no file path: save it to a file')
        return info
    if not os.path.splitext(path)[1].lower() in MAP_EXTENSIONS:
        info.problems.append(f"{os.path.basename(path)}: prismbake reads EXR, PNG and TIFF height maps; "
                             f"save the image in one of those formats")
    elif not os.path.isfile(path) and not any("packed" in p or "generated" in p for p in info.problems):
        info.problems.append(f'image file {path} does not exist: fix the image path or save the image')
    return info

"""Reading a material's diffuse reflectance and emission from its Cycles node tree.

Units follow Cycles (blender-facts §1): an Emission shader or a Principled BSDF emits radiance L = S*C from both
faces, so the exitance sent to the solver is pi*S*C with the two-sided flag. Whatever cannot be read falls back to
a 0.8 grey non-emitter (what Cycles shows for an object without material) and says so in a warning.
"""
import contextlib
import math

import numpy as np

from . import compat

DEFAULT_ALBEDO = (0.8, 0.8, 0.8)
# The solver needs albedo < 1 to converge; an albedo of exactly 1 is a modelling shortcut, not a physical value.
MAX_ALBEDO = 0.999


class MaterialInfo:
    __slots__ = ("albedo", "radiance", "notes", "warnings")

    def __init__(self, albedo=DEFAULT_ALBEDO, radiance=(0.0, 0.0, 0.0)):
        self.albedo = tuple(float(x) for x in albedo)
        self.radiance = tuple(float(x) for x in radiance)     # emitted radiance L_e = S*C, per side
        self.notes = []
        self.warnings = []

    @property
    def emits(self):
        return max(self.radiance) > 0.0


def _srgb_to_linear(c):
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def image_average(image):
    """Mean linear RGB of an image (its pixels, with sRGB decoded when the image stores display values)."""
    return tuple(float(x) for x in image_rgb(image).reshape(-1, 3).mean(axis=0))


def image_rgb(image):
    """Linear RGB pixels of an image, (height, width, 3) float32, rows from the bottom (sRGB decoded when
    the image stores display values)."""
    if image is None:
        raise ValueError("no image")
    w, h = image.size
    n = w * h * image.channels
    if n == 0:
        raise ValueError(f"image '{image.name}' has no pixels (missing file?)")
    px = np.empty(n, np.float32)
    image.pixels.foreach_get(px)
    px = px.reshape(-1, image.channels)
    rgb = px[:, :3] if image.channels >= 3 else np.repeat(px[:, :1], 3, axis=1)
    # Byte images hand out their stored (display-encoded) values; float buffers are already scene-linear.
    cs = image.colorspace_settings
    if not image.is_float and not cs.is_data and cs.name.lower().startswith("srgb"):
        rgb = _srgb_to_linear(rgb.astype(np.float64))
    return np.ascontiguousarray(rgb.reshape(h, w, 3), np.float32)


def _follow(socket):
    """The node and output socket feeding `socket`, skipping reroutes; None when unlinked or muted."""
    if not socket.is_linked:
        return None, None
    link = socket.links[0]
    node, out = link.from_node, link.from_socket
    while node.type == "REROUTE":
        if not node.inputs[0].is_linked:
            return None, None
        link = node.inputs[0].links[0]
        node, out = link.from_node, link.from_socket
    if not link.is_valid or node.mute:
        return None, None
    return node, out


def _color(socket, info, what):
    """RGB value of a colour input: its own value, an RGB node, or the average of an image texture."""
    node, _ = _follow(socket)
    if node is None:
        if socket.is_linked:
            info.warnings.append(f"{what} is linked through a muted or invalid node; using its own value")
        v = socket.default_value
        return (float(v[0]), float(v[1]), float(v[2]))
    if node.type == "RGB":
        v = node.outputs[0].default_value
        return (float(v[0]), float(v[1]), float(v[2]))
    if node.type == "TEX_IMAGE":
        try:
            avg = image_average(node.image)
        except Exception as e:  # a missing file or an empty image: fall back, but say so
            info.warnings.append(f"{what} uses image texture '{node.name}' that cannot be read ({e}); "
                                 f"using 0.8 grey")
            return DEFAULT_ALBEDO
        info.notes.append(f"{what} is the average of image '{node.image.name}' "
                          f"({avg[0]:.4g}, {avg[1]:.4g}, {avg[2]:.4g})")
        return avg
    info.warnings.append(f"{what} is driven by a '{node.bl_idname}' node that Penumbra cannot evaluate; "
                         f"using 0.8 grey")
    return DEFAULT_ALBEDO


def _scalar(socket, info, what):
    if socket.is_linked:
        info.warnings.append(f"{what} is linked to a node; using its unlinked value {socket.default_value:g}")
    return float(socket.default_value)


def _shader(node, info, depth=0):
    """(albedo, radiance) of a shader node, recursing through Mix and Add shaders."""
    if depth > 32:
        raise ValueError("shader nodes nested too deeply")
    t = node.type
    if t == "BSDF_DIFFUSE":
        return _color(node.inputs["Color"], info, "Diffuse BSDF Color"), (0.0, 0.0, 0.0)
    if t == "BSDF_PRINCIPLED":
        base = _color(node.inputs["Base Color"], info, "Principled Base Color")
        ec = _color_or_zero(compat.principled(node, "Emission"), info, "Principled Emission")
        s = _scalar(node.inputs["Emission Strength"], info, "Principled Emission Strength")
        metallic = node.inputs["Metallic"]
        transmission = compat.principled(node, "Transmission")
        if metallic.is_linked or metallic.default_value > 0 or transmission.is_linked or \
                transmission.default_value > 0:
            info.notes.append("Principled BSDF with metallic or transmission is treated as its diffuse part")
        alpha = node.inputs["Alpha"]
        if alpha.is_linked or alpha.default_value < 1.0:
            what = "linked to a node" if alpha.is_linked else f"{alpha.default_value:g}"
            info.warnings.append(f"Principled Alpha ({what}) is treated as opaque: Cycles lets light through "
                                 f"where alpha is below 1, so this surface's shadow is darker than in a render")
        return base, tuple(c * s for c in ec)
    if t == "EMISSION":
        ec = _color_or_zero(node.inputs["Color"], info, "Emission Color")
        s = _scalar(node.inputs["Strength"], info, "Emission Strength")
        return (0.0, 0.0, 0.0), tuple(c * s for c in ec)
    if t in ("ADD_SHADER", "MIX_SHADER"):
        if t == "ADD_SHADER":
            weights, shaders = (1.0, 1.0), (node.inputs[0], node.inputs[1])
        else:
            fac = min(max(_scalar(node.inputs["Fac"], info, "Mix Shader Fac"), 0.0), 1.0)
            weights, shaders = (1.0 - fac, fac), (node.inputs[1], node.inputs[2])
        albedo, rad = [0.0] * 3, [0.0] * 3
        for w, sock in zip(weights, shaders):
            sub, _ = _follow(sock)
            if sub is None or w == 0.0:
                continue
            a, r = _shader(sub, info, depth + 1)
            for c in range(3):
                albedo[c] += w * a[c]
                rad[c] += w * r[c]
        return tuple(albedo), tuple(rad)
    if t in ("BSDF_TRANSPARENT", "HOLDOUT"):
        info.warnings.append(f"'{node.bl_idname}' is not diffuse; treated as black")
        return (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)
    raise ValueError(f"shader '{node.bl_idname}' is not supported")


def _color_or_zero(socket, info, what):
    node, _ = _follow(socket)
    if node is None or node.type in ("RGB", "TEX_IMAGE"):
        return _color(socket, info, what)
    info.warnings.append(f"{what} is driven by a '{node.bl_idname}' node that Penumbra cannot evaluate; "
                         f"treated as no emission")
    return (0.0, 0.0, 0.0)


def parse_material(mat):
    """MaterialInfo for a material (None = no material: Cycles renders it 0.8 grey)."""
    if mat is None:
        return MaterialInfo()
    if not compat.uses_nodes(mat):
        info = MaterialInfo(tuple(mat.diffuse_color)[:3])
        return _clamped(info)
    info = MaterialInfo()
    out = mat.node_tree.get_output_node("CYCLES")
    if out is None:
        info.warnings.append("no material output node for Cycles; using 0.8 grey")
        return info
    node, _ = _follow(out.inputs["Surface"])
    if node is None:
        info.warnings.append("nothing is connected to the Surface output; using 0.8 grey")
        return info
    try:
        albedo, rad = _shader(node, info)
    except ValueError as e:
        info.warnings.append(f"{e}; using 0.8 grey")
        return info
    info.albedo = tuple(float(a) for a in albedo)
    if any(float(r) < 0 for r in rad):
        info.warnings.append(f"negative emission ({rad[0]:.4g}, {rad[1]:.4g}, {rad[2]:.4g}) is treated as 0; "
                             f"the solver cannot take light away")
    info.radiance = tuple(max(float(r), 0.0) for r in rad)
    if not all(math.isfinite(x) for x in info.albedo + info.radiance):
        info.warnings.append("non-finite colour or strength; using 0.8 grey")
        return MaterialInfo()
    return _clamped(info)


def _clamped(info):
    a = info.albedo
    c = tuple(min(max(x, 0.0), MAX_ALBEDO) for x in a)
    if any(abs(x - y) > 1e-7 for x, y in zip(a, c)):
        info.warnings.append(f"albedo ({a[0]:.4g}, {a[1]:.4g}, {a[2]:.4g}) clamped to [0, {MAX_ALBEDO}]")
    info.albedo = c
    return info


def _input(node, *names):
    """The first of `names` that the node has (sockets renamed between Blender versions)."""
    for n in names:
        if n in node.inputs:
            return node.inputs[n]
    return None


def _varies(socket):
    """Whether a node (other than a constant RGB node) drives this input, so it can change across the surface."""
    if socket is None:
        return False
    node, _ = _follow(socket)
    return node is not None and node.type != "RGB"


def albedo_varies(mat):
    """Whether the diffuse colour of `mat` can change across a surface: a texture, procedural or any other
    node on the diffuse colour (Diffuse Color, Principled Base Color, Metallic or Transmission) or on the
    factor of a Mix Shader on the way to the output. Such a material's albedo is followed per texel by
    baking it (albedo.py); a constant one is what parse_material reads."""
    if mat is None or not compat.uses_nodes(mat):
        return False
    out = mat.node_tree.get_output_node("CYCLES")
    if out is None:
        return False

    def walk(node, depth):
        if node is None or depth > 32:
            return False
        if node.type == "BSDF_DIFFUSE":
            return _varies(node.inputs["Color"])
        if node.type == "BSDF_PRINCIPLED":
            return any(_varies(_input(node, *names)) for names in
                       (("Base Color",), ("Metallic",), ("Transmission Weight", "Transmission")))
        if node.type == "MIX_SHADER":
            return _varies(node.inputs["Fac"]) or any(walk(_follow(s)[0], depth + 1) for s in node.inputs[1:3])
        if node.type == "ADD_SHADER":
            return any(walk(_follow(s)[0], depth + 1) for s in node.inputs[0:2])
        return False
    return walk(_follow(out.inputs["Surface"])[0], 0)


def albedo_input(node_tree):
    """The colour input of the one diffuse shader (Diffuse BSDF or Principled BSDF) that feeds the Cycles
    output of `node_tree` directly, or None when the surface is anything else (mixed shaders, emission)."""
    out = node_tree.get_output_node("CYCLES")
    if out is None:
        return None
    node, _ = _follow(out.inputs["Surface"])
    if node is None:
        return None
    if node.type == "BSDF_DIFFUSE":
        return node.inputs["Color"]
    if node.type == "BSDF_PRINCIPLED":
        return node.inputs["Base Color"]
    return None


def emission_input(node_tree):
    """(colour, strength) inputs of the one emitting shader (Emission, or Principled BSDF's emission) that feeds
    the Cycles output of `node_tree` directly, or (None, None)."""
    out = node_tree.get_output_node("CYCLES")
    node = _follow(out.inputs["Surface"])[0] if out is not None else None
    if node is None:
        return None, None
    if node.type == "EMISSION":
        return node.inputs["Color"], node.inputs["Strength"]
    if node.type == "BSDF_PRINCIPLED":
        return _input(node, "Emission Color", "Emission"), _input(node, "Emission Strength")
    return None, None


def emission_varies(mat):
    """Whether the emission colour of `mat` comes from a node other than an RGB node (an emission texture)."""
    if mat is None or not compat.uses_nodes(mat):
        return False
    return _varies(emission_input(mat.node_tree)[0])


def bake_batches(uv_of, materials_of):
    """Objects grouped for Cycles bake calls: one call bakes every selected object at once (one scene sync),
    but each material's active Image Texture node is the target, so objects in one call must share the UV
    map name and no material. `uv_of`: {object name: UV map name}, in bake order; `materials_of(name)`: the
    set of its material names. Returns lists of object names, the first fit kept in that order."""
    batches = []
    for name, uv_name in uv_of.items():
        mats = set(materials_of(name))
        for b in batches:
            if b["uv"] == uv_name and not (b["mats"] & mats):
                b["names"].append(name)
                b["mats"] |= mats
                break
        else:
            batches.append({"uv": uv_name, "names": [name], "mats": mats})
    return [b["names"] for b in batches]


@contextlib.contextmanager
def bake_targets(prefix, sizes, materials_of):
    """Float images for one Cycles bake into IMAGE_TEXTURES: {object name: image}, each made the active Image
    Texture node of every material `materials_of(name)` gives (the bake writes into that node). `sizes`:
    {object name: (width, height)}. The nodes and images are removed on leaving, whatever happened, and each
    material's active node is given back."""
    import bpy
    made = []          # (node tree, image node, the tree's active node before)
    images = {}
    try:
        for name, (w, h) in sizes.items():
            img = bpy.data.images.new(prefix + name, w, h, alpha=False, float_buffer=True)
            images[name] = img
            for mat in materials_of(name):
                nt = mat.node_tree
                node = nt.nodes.new("ShaderNodeTexImage")
                node.image = img
                made.append((nt, node, nt.nodes.active))
                nt.nodes.active = node
        yield images
    finally:
        for nt, node, prev in reversed(made):
            nt.nodes.remove(node)
            if prev is not None:
                nt.nodes.active = prev
        for img in images.values():
            bpy.data.images.remove(img)


def image_rgba(img):
    """An image's pixels as (height, width, 4) float32, rows bottom to top."""
    w, h = img.size
    px = np.empty(w * h * 4, np.float32)
    img.pixels.foreach_get(px)
    return px.reshape(h, w, 4)

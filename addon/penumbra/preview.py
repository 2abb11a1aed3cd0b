"""Showing a bake in renders: each material slot of a baked object is switched to a material that emits the
lightmap (plus the slot's own emission), and switched back exactly.

The preview materials go into object-linked slots, so the mesh's own material list is never touched; what the
slots held before (link type and object-level material) is stored on the object so that switching off works
after a save and reload too.
"""
import bpy

from . import compat
from .materials import albedo_input, emission_input, emission_varies, parse_material
from .writeback import ATTRIBUTE, TILE_PROP, baked_state

STATE = "penumbra_preview"


def _object_level_material(slot):
    """The material in the object's own slot, whichever link the slot shows."""
    if slot.link == "OBJECT":
        return slot.material
    slot.link = "OBJECT"
    try:
        return slot.material
    finally:
        slot.link = "DATA"


def _linked_source(sock):
    """The output socket feeding `sock`, when a valid link from an unmuted node does."""
    if sock is None or not sock.is_linked:
        return None
    link = sock.links[0]
    return link.from_socket if link.is_valid and not link.from_node.mute else None


def _copied_material(name, original):
    """A copy of the slot's material, whose colour chains (texture, UV map, Mapping ...) are kept to multiply
    the stored light by (an irradiance bake) and to show an emission texture, with its own outputs removed.
    Returns (material, the socket that fed the diffuse colour, or None; the constant colour to use when there
    is no such socket; the copy's emission colour and strength inputs, or None)."""
    const = parse_material(original).albedo
    if original is None or not compat.uses_nodes(original):
        mat = bpy.data.materials.new(name)
        compat.enable_nodes(mat)
        mat.node_tree.nodes.clear()
        return mat, None, const, (None, None)
    mat = original.copy()
    mat.name = name
    nt = mat.node_tree
    sock = albedo_input(nt)
    source = _linked_source(sock)
    if sock is not None and not sock.is_linked:
        const = tuple(sock.default_value[:3])
    emission = emission_input(nt)
    for node in [n for n in nt.nodes if n.type == "OUTPUT_MATERIAL"]:
        nt.nodes.remove(node)
    return mat, source, const, emission


def _make_material(name, state, original):
    irradiance = bool(state.get("irradiance"))
    # An emission texture is shown through the material's own chain too, so the material is copied for it.
    copied = irradiance or emission_varies(original)
    if copied:
        mat, albedo_source, albedo_const, (colour, strength) = _copied_material(name, original)
    else:
        colour = strength = None
        mat = bpy.data.materials.new(name)
        compat.enable_nodes(mat)
        mat.node_tree.nodes.clear()
    # The preview only shows stored light; letting Cycles sample it as a light would only add noise.
    compat.no_light_sampling(mat)
    nt = mat.node_tree
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    out.location = (600, 0)
    emit = nt.nodes.new("ShaderNodeEmission")
    emit.location = (200, 0)
    emit.inputs["Strength"].default_value = 1.0
    img = bpy.data.images.get(state.get("image", "")) if state.get("image") else None
    if img is not None:
        if state.get("uv_attribute"):
            # An object whose modifiers copy faces: its lightmap UVs are a corner attribute of the modified
            # surface (writeback.unwrap_copies), which a UV Map node cannot name in Blender 3.4.
            uv = nt.nodes.new("ShaderNodeAttribute")
            uv.attribute_type = "GEOMETRY"
            uv.attribute_name = state["uv_attribute"]
            uv_out = uv.outputs["Vector"]
        else:
            uv = nt.nodes.new("ShaderNodeUVMap")
            # Without a UV Map node an Image Texture reads the render-active UV map, not the lightmap's.
            uv.uv_map = state.get("uv_map", "")
            uv_out = uv.outputs["UV"]
        uv.location = (-400, 0)
        if state.get("tiles"):
            # One lightmap, a tile per collection instance: uv * scale + offset, from the instancing empty's
            # TILE_PROP (the object's own when it is not an instance).
            tile = nt.nodes.new("ShaderNodeAttribute")
            tile.attribute_type = "INSTANCER"
            tile.attribute_name = TILE_PROP
            sep = nt.nodes.new("ShaderNodeSeparateXYZ")
            nt.links.new(tile.outputs["Vector"], sep.inputs[0])
            scale = nt.nodes.new("ShaderNodeVectorMath")
            scale.operation = "SCALE"
            nt.links.new(uv_out, scale.inputs[0])
            nt.links.new(sep.outputs["Z"], scale.inputs["Scale"])
            offset = nt.nodes.new("ShaderNodeCombineXYZ")
            nt.links.new(sep.outputs["X"], offset.inputs["X"])
            nt.links.new(sep.outputs["Y"], offset.inputs["Y"])
            add = nt.nodes.new("ShaderNodeVectorMath")
            add.operation = "ADD"
            nt.links.new(scale.outputs["Vector"], add.inputs[0])
            nt.links.new(offset.outputs["Vector"], add.inputs[1])
            uv_out = add.outputs["Vector"]
        tex = nt.nodes.new("ShaderNodeTexImage")
        tex.location = (-150, 0)
        tex.image = img
        tex.interpolation = "Linear"
        tex.extension = "EXTEND"
        nt.links.new(uv_out, tex.inputs["Vector"])
        nt.links.new(tex.outputs["Color"], emit.inputs["Color"])
    else:
        attr = nt.nodes.new("ShaderNodeVertexColor")
        attr.location = (-150, 0)
        attr.layer_name = state.get("attribute", ATTRIBUTE)
        nt.links.new(attr.outputs["Color"], emit.inputs["Color"])
    if irradiance:
        # The stored light is E/pi without any albedo: times the material's own colour it is what the
        # material reflects, as the game engine this bake is for would show it.
        light = emit.inputs["Color"].links[0].from_socket
        mul = nt.nodes.new("ShaderNodeVectorMath")
        mul.operation = "MULTIPLY"
        mul.location = (50, 150)
        nt.links.new(light, mul.inputs[0])
        if albedo_source is not None:
            nt.links.new(albedo_source, mul.inputs[1])
        else:
            mul.inputs[1].default_value = albedo_const[:3]
        nt.links.new(mul.outputs["Vector"], emit.inputs["Color"])
    shader = emit.outputs["Emission"]
    radiance = parse_material(original).radiance
    peak = max(radiance)
    source = _linked_source(colour)
    if source is not None:
        own = nt.nodes.new("ShaderNodeEmission")
        own.location = (200, -200)
        nt.links.new(source, own.inputs["Color"])
        if _linked_source(strength) is not None:
            nt.links.new(_linked_source(strength), own.inputs["Strength"])
        else:
            own.inputs["Strength"].default_value = strength.default_value
        add = nt.nodes.new("ShaderNodeAddShader")
        add.location = (400, 0)
        nt.links.new(shader, add.inputs[0])
        nt.links.new(own.outputs["Emission"], add.inputs[1])
        shader = add.outputs["Shader"]
    elif peak > 0:
        own = nt.nodes.new("ShaderNodeEmission")
        own.location = (200, -200)
        own.inputs["Color"].default_value = (*(c / peak for c in radiance), 1.0)
        own.inputs["Strength"].default_value = peak
        add = nt.nodes.new("ShaderNodeAddShader")
        add.location = (400, 0)
        nt.links.new(shader, add.inputs[0])
        nt.links.new(own.outputs["Emission"], add.inputs[1])
        shader = add.outputs["Shader"]
    nt.links.new(shader, out.inputs["Surface"])
    return mat


def preview_on(ob):
    state = baked_state(ob)
    if not state or ob.get(STATE) is not None:
        return False
    added = len(ob.material_slots) == 0
    active_index = ob.active_material_index
    if added:
        ob.data.materials.append(None)
    slots = []
    for slot in ob.material_slots:
        om = _object_level_material(slot)
        slots.append({"link": slot.link, "object_material": om.name if om is not None else ""})
    made = []
    try:
        for i, slot in enumerate(ob.material_slots):
            mat = _make_material(f"Penumbra Preview {ob.name} {i}", state, slot.material)
            made.append(mat.name)
            slot.link = "OBJECT"
            slot.material = mat
    except BaseException:
        _restore(ob, slots, made, added)
        raise
    ob[STATE] = {"slots": slots, "materials": made, "added_slot": added, "active_index": active_index}
    return True


def _restore(ob, slots, made, added):
    for slot, rec in zip(ob.material_slots, slots):
        slot.link = "OBJECT"
        slot.material = bpy.data.materials.get(rec["object_material"]) if rec["object_material"] else None
        slot.link = rec["link"]
    for name in made:
        m = bpy.data.materials.get(name)
        if m is not None:
            bpy.data.materials.remove(m)
    if added and len(ob.material_slots):
        # Mesh.materials.pop() leaves the object's own slot count behind; the operator removes both.
        ob.active_material_index = len(ob.material_slots) - 1
        with bpy.context.temp_override(**compat.override_object(ob)):
            bpy.ops.object.material_slot_remove()


def preview_off(ob):
    rec = ob.get(STATE)
    if rec is None:
        return False
    rec = rec.to_dict()
    _restore(ob, rec["slots"], rec["materials"], rec["added_slot"])
    ob.active_material_index = rec.get("active_index", 0)
    del ob[STATE]
    return True


def instanced_only(scene):
    """Objects baked for their collection instances in `scene` that are in no collection of the scene."""
    return [o for o in bpy.data.objects if o.type == "MESH" and scene.objects.get(o.name) is None and
            any(scene.objects.get(n) is not None for n in baked_state(o).get("tiles", {}))]


def set_preview(scene, on):
    changed = []
    for ob in list(scene.objects) + instanced_only(scene):
        if ob.type != "MESH":
            continue
        if (preview_on if on else preview_off)(ob):
            changed.append(ob.name)
    return changed

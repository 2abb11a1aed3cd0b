"""The bpy differences between the Blender versions Penumbra supports (3.4 in Debian 12, 4.3 in Debian 13,
5.x in sid), each in one place so the rest of the add-on reads the same on all of them. Each helper names the
version that changed the API; docs/blender-versions.md lists them with how each was found."""
import math

import bpy

VERSION = bpy.app.version


def socket(node, *names):
    """The first of `names` that `node` has as an input: Principled BSDF sockets were renamed in 4.0
    ('Emission' became 'Emission Color', 'Transmission' became 'Transmission Weight', ...)."""
    for name in names:
        s = node.inputs.get(name)
        if s is not None:
            return s
    raise KeyError(f"node '{node.name}' ({node.bl_idname}) has none of the inputs {', '.join(names)}")


def principled(node, name):
    """A Principled BSDF input under its 3.x name, looked up under its 4.0+ name where that differs."""
    renamed = {"Emission": "Emission Color", "Transmission": "Transmission Weight",
               "Specular": "Specular IOR Level", "Subsurface": "Subsurface Weight",
               "Clearcoat": "Coat Weight", "Sheen": "Sheen Weight"}
    return socket(node, renamed[name], name) if name in renamed else node.inputs[name]


def light_casts_shadow(light):
    """Cycles' per-light shadow switch: light.cycles.cast_shadow in 3.x; 5.2 has only Light.use_shadow, and
    reading the old name with a default silently took every light as shadowing."""
    cyc = getattr(light, "cycles", None)
    if cyc is not None and hasattr(cyc, "cast_shadow"):
        return bool(cyc.cast_shadow)
    return bool(getattr(light, "use_shadow", True))


def set_light_casts_shadow(light, on):
    cyc = getattr(light, "cycles", None)
    if cyc is not None and hasattr(cyc, "cast_shadow"):
        cyc.cast_shadow = on
    else:
        light.use_shadow = on


def uses_nodes(mat):
    """Whether a material (or world) renders from its node tree. 5.0 made every one node-based and deprecated
    use_nodes, whose setter no longer does anything there."""
    if VERSION >= (5, 0, 0):
        return mat.node_tree is not None
    return bool(mat.use_nodes) and mat.node_tree is not None


def enable_nodes(mat):
    """Give a new material or world its node tree (5.0 creates it already; use_nodes goes in 6.0)."""
    if VERSION < (5, 0, 0):
        mat.use_nodes = True


def no_light_sampling(mat):
    """Keep Cycles from sampling a material's emission as a light: a bool until 3.4, an enum from 3.5."""
    cyc = mat.cycles
    if hasattr(cyc, "emission_sampling"):
        cyc.emission_sampling = "NONE"
    else:
        cyc.sample_as_light = False


def multilayer_exr(image_settings):
    """Set image settings to multilayer EXR: 5.0 refuses the format unless the media type is chosen first."""
    if hasattr(image_settings, "media_type"):
        image_settings.media_type = "MULTI_LAYER_IMAGE"
    image_settings.file_format = "OPEN_EXR_MULTILAYER"


def single_layer_exr(image_settings):
    """Set image settings to a plain (single-layer) EXR; 5.0 wants the media type chosen first."""
    if hasattr(image_settings, "media_type"):
        image_settings.media_type = "IMAGE"
    image_settings.file_format = "OPEN_EXR"


def panorama_settings(cam_data):
    """Where a camera's panorama settings (panorama_type, latitude/longitude range) live: Camera.cycles in 3.x,
    the Camera itself since 4.0 (5.2 has no Camera.cycles.panorama_type)."""
    cyc = getattr(cam_data, "cycles", None)
    if cyc is not None and hasattr(cyc, "panorama_type"):
        return cyc
    return cam_data


def world_ray_visibility(world):
    """The world's Cycles ray visibility flags (camera, diffuse, ...): World.cycles_visibility in 3.4 and 5.2
    alike; a later rename to World.visibility is looked for too. None when neither is there."""
    for name in ("cycles_visibility", "visibility"):
        vis = getattr(world, name, None)
        if vis is not None and hasattr(vis, "camera"):
            return vis
    return None


def override_object(ob):
    """temp_override keywords that make `ob` the context object: operators' poll functions read
    `active_object` in 5.x where 3.4's read `object`."""
    return {"object": ob, "active_object": ob}


def mesh_attribute_names(me):
    return {a.name for a in me.attributes}


def drop_new_internal_attributes(me, before):
    """Remove the internal ('.'-named) attributes that edit mode added to `me` since `before` (a set of names):
    .hide_*, .select_*, .uv_select_* and the UV maps' .vs./.es./.pn. layers. Since 4.x they stay on the mesh
    after an edit-mode round trip; absent, each means all elements unhidden, unselected, unpinned, so removing
    one that was absent before restores exactly what the mesh held."""
    for name in sorted(mesh_attribute_names(me) - before):
        if not name.startswith("."):
            continue
        attr = me.attributes.get(name)
        if attr is None:
            continue
        try:
            me.attributes.remove(attr)
        except RuntimeError:
            pass   # an attribute the mesh requires (none of the edit-mode ones is); leave it


def area_light_exitance(power, area):
    """Exitance M of an area light of power P over its area A. Cycles before 4.0 gave it radiance P / (4A)
    (M = pi P / (4A), measured: blender-facts section 1); 4.0 changed the factor 4 to pi (Blender issue 109404),
    so M = P / A: a textured floor under a square lamp came out pi / 4 of Cycles 5.2's bake with the old one."""
    if VERSION >= (4, 0, 0):
        return power / area
    return math.pi * power / (4.0 * area)


def lamp_is_sphere(light):
    """Whether Cycles draws a POINT or SPOT lamp with a radius as a sphere of uniform radiance. Before 4.0 it
    is always a disk of that radius facing the shaded point. 4.0 made the sphere the model and kept the disk
    behind Light.use_soft_falloff, on by default: measured in 5.2 (DIFFUSE bake, 100 W, 1 m above a plane)
    the default lamp gives P cos / (4 pi (d^2 + r^2)) like 3.4 (0.9407 of the bare point's irradiance on the
    axis at r = 0.25, 0.8016 at r = 0.5), and with Soft Falloff off P cos / (4 pi d^2) (0.9990, 0.9986)."""
    return VERSION >= (4, 0, 0) and not getattr(light, "use_soft_falloff", True)


def spot_multiplies_cosine():
    """Cycles 3.x multiplies a spot's intensity by the cosine from its axis; 4.0's spot code does not. Measured:
    48 degrees off the axis of a 160 degree cone, Cycles 3.4 gave 0.654 of the point lamp's irradiance (the
    cosine, 0.667, over the window), 5.2 gave 1.000."""
    return VERSION < (4, 0, 0)


def ray_visibility(ob):
    """(shadow, diffuse): Cycles' per-object Ray Visibility, Object.visible_shadow and visible_diffuse since 3.0
    (the same names in 5.2, which adds visible_raycast)."""
    return bool(getattr(ob, "visible_shadow", True)), bool(getattr(ob, "visible_diffuse", True))


def sync_layer_collections(view_layer):
    """Blender 4.x+ syncs a view layer's layer collections lazily: in a scene that is not the window's, right
    after objects were linked to it, a layer collection can read as None (seen in 5.2). An update syncs them."""
    def stale(lc):
        return lc is None or any(stale(c) for c in lc.children)
    if stale(view_layer.layer_collection):
        view_layer.update()


def geometry_group_sockets(ng):
    """Give a new Geometry Nodes group one Geometry input and one Geometry output, so a modifier can use it:
    3.x has NodeTree.inputs/outputs, 4.0 moved them to NodeTree.interface (and marks modifier groups)."""
    if hasattr(ng, "interface"):
        ng.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
        ng.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
        if hasattr(ng, "is_modifier"):
            ng.is_modifier = True
    else:
        ng.inputs.new("NodeSocketGeometry", "Geometry")
        ng.outputs.new("NodeSocketGeometry", "Geometry")


def shown_socket(sockets, name):
    """The socket called `name` that the node's data type shows: 3.x nodes keep one socket per type under the
    same name and hide the others (`enabled`); newer ones have a single socket that changes type."""
    for s in sockets:
        if s.name == name and getattr(s, "enabled", True):
            return s
    raise KeyError(name)


def operator_call_without_update():
    """A function (idname, props) that runs an operator without the view-layer update bpy.ops does before and
    after each call, or None where Blender has no such entry point. Blender's private _bpy.ops.call takes
    (idname, context_dict, props) in 3.x and (idname, props) from 4.0, which dropped context dicts (read in
    the bpy/ops.py of 3.4.1 and 4.3.2; on 4.3 the 3.x call raised "argument 2 must be dict, not None").
    5.x has no _bpy.ops.call at all (operators are C callables made by _bpy.ops.create_function)."""
    try:
        from _bpy import ops as native_ops
    except ImportError:
        return None
    call = getattr(native_ops, "call", None)
    if call is None:
        return None
    if VERSION >= (4, 0, 0):
        return lambda idname, props: call(idname, props)
    return lambda idname, props: call(idname, None, props)

"""Scene export: Blender's evaluated geometry, materials and lights as flat numpy arrays for the solver.

Area lights become light-only polygons; point, spot and sun lights and a uniform world become the solver's
analytic lights (a list of dicts, `Exported.lights`).

Everything is world space and in Cycles' units (blender-facts §1). Per-element work is done with
`foreach_get` and numpy; Python loops run over objects, material slots and lights only.
"""
import math

import bpy
import numpy as np

from . import compat
from .materials import image_rgb, parse_material

PREVIEW_STATE = "penumbra_preview"     # preview.STATE (preview imports writeback, which needs bpy data)

EMIT_BACK = 1      # also emits from the back side (Cycles mesh emitters are two-sided); the solver gives such a
                   # face a back twin that receives and reflects too, which is how two-sided objects are sent
LIGHT_ONLY = 2     # a Blender light: emits, but neither receives, reflects nor blocks
NO_LAMP_SHADOW = 4  # Ray Visibility > Shadow off: shadow rays to lamps, area lights and emitters pass it
CASTS_NO_SHADOW = 8  # an AREA light with Cast Shadow off: nothing hides its light
NO_DIFFUSE = 16    # Ray Visibility > Diffuse off: it reflects nothing onto others and bounced light passes it

DISK_SECTORS = 32
# A quad is sent as one polygon only if it is flat and convex: the solver subdivides it as a planar
# quadrilateral. Both diagonals' triangle pairs must agree in orientation to within this cosine.
QUAD_FLAT_COS = 0.99999


class ExportError(ValueError):
    pass


class Exported:
    """The solver's input arrays and what the export decided along the way."""

    def __init__(self):
        self.vertices = np.zeros((0, 3), np.float32)
        self.polygons = np.zeros((0, 4), np.int32)
        self.reflectance = np.zeros((0, 3), np.float32)
        self.emission = np.zeros((0, 3), np.float32)
        self.flags = np.zeros(0, np.uint8)
        self.object_index = np.zeros(0, np.int32)
        self.object_names = []
        self.lights = []              # _native.solve's lights: point, spot, sun and the world
        self.bake_objects = []        # names of original mesh objects that get a lightmap / attribute
        self.two_sided = set()        # of those, the ones lit on both sides (Object Properties > Two-sided)
        # With instance_lightmaps: object name -> [(instancing empty's name, world matrix (4, 4))], each
        # collection instance of the object, which gets a tile of its own in the object's lightmap.
        self.instances = {}
        self.instance_only = set()    # objects baked only through their instances (not rendered themselves)
        self.skipped = []             # {"name", "reason"}
        self.warnings = []
        self.notes = []
        self.counts = {}

    def skip(self, name, reason):
        self.skipped.append({"name": name, "reason": reason})


def _get(coll, attr, n, dtype, width=1):
    a = np.empty(n * width, dtype)
    if n:
        coll.foreach_get(attr, a)
    return a.reshape(n, width) if width > 1 else a


def _transform(co, m):
    return co @ m[:3, :3].T + m[:3, 3]


def mesh_polygons(me):
    """Polygons of a mesh as (P, 4) vertex indices (-1 pads triangles) plus each row's source polygon.

    Flat convex quads and triangles are kept; n-gons and bent or concave quads become their loop triangles,
    which Blender already winds like the polygon they come from.
    """
    n_poly = len(me.polygons)
    loop_total = _get(me.polygons, "loop_total", n_poly, np.int32)
    loop_start = _get(me.polygons, "loop_start", n_poly, np.int32)
    loop_vert = _get(me.loops, "vertex_index", len(me.loops), np.int32)
    co = _get(me.vertices, "co", len(me.vertices), np.float32, 3).astype(np.float64)

    keep = loop_total <= 4
    rows = np.full((n_poly, 4), -1, np.int32)
    for k in range(4):
        m = keep & (loop_total > k)
        rows[m, k] = loop_vert[loop_start[m] + k]

    quad = np.nonzero(keep & (loop_total == 4))[0]
    if len(quad):
        p = co[rows[quad]]                                   # (Q, 4, 3)
        def tri_n(a, b, c):
            n = np.cross(p[:, b] - p[:, a], p[:, c] - p[:, a])
            return n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-30)
        ok = (np.einsum("ij,ij->i", tri_n(0, 1, 2), tri_n(0, 2, 3)) > QUAD_FLAT_COS) & \
             (np.einsum("ij,ij->i", tri_n(1, 2, 3), tri_n(1, 3, 0)) > QUAD_FLAT_COS)
        keep[quad[~ok]] = False

    src = np.nonzero(keep)[0].astype(np.int32)
    out = rows[keep]
    if not keep.all():
        me.calc_loop_triangles()
        n_tri = len(me.loop_triangles)
        lt_vert = _get(me.loop_triangles, "vertices", n_tri, np.int32, 3)
        lt_poly = _get(me.loop_triangles, "polygon_index", n_tri, np.int32)
        sel = ~keep[lt_poly]
        tris = np.full((int(sel.sum()), 4), -1, np.int32)
        tris[:, :3] = lt_vert[sel]
        out = np.concatenate([out, tris])
        src = np.concatenate([src, lt_poly[sel]])
    return co, out, src


def _own_materials(original, ob_eval):
    """The materials the object renders with when the preview is off. While the preview shows a bake, the
    slots hold emissive preview materials; exporting those would bake the old bake back in (black, albedo
    0), so they are read from what the preview stored instead, without switching anything."""
    slots = [s.material for s in ob_eval.material_slots]
    rec = original.get(PREVIEW_STATE)
    if rec is None:
        return slots
    rec = rec.to_dict() if hasattr(rec, "to_dict") else dict(rec)
    if rec.get("added_slot"):
        return [None]
    stored = rec.get("slots", [])
    if len(stored) != len(slots):
        return slots
    mesh_mats = original.data.materials if original.type == "MESH" else []
    own = []
    for i, r in enumerate(stored):
        if r.get("link") == "OBJECT":
            own.append(bpy.data.materials.get(r["object_material"]) if r.get("object_material") else None)
        else:
            own.append(mesh_mats[i] if i < len(mesh_mats) else None)
    return own


def _material_table(ob_eval, ob_name, cache, result):
    slots = _own_materials(ob_eval.original, ob_eval) or [None]
    albedo = np.empty((len(slots), 3), np.float64)
    radiance = np.empty((len(slots), 3), np.float64)
    for i, mat in enumerate(slots):
        key = mat.name_full if mat is not None else None
        if key not in cache:
            cache[key] = parse_material(mat)
        info = cache[key]
        albedo[i] = info.albedo
        radiance[i] = info.radiance
    return slots, albedo, radiance


def _report_material(slots, used, ob_name, cache, result, reported):
    for i in np.nonzero(used)[0]:
        mat = slots[i]
        key = mat.name_full if mat is not None else None
        if (ob_name, key) in reported:
            continue
        reported.add((ob_name, key))
        info = cache[key]
        label = f"object '{ob_name}', material '{mat.name if mat else '(none)'}'"
        result.warnings += [f"{label}: {w}" for w in info.warnings]
        result.notes += [f"{label}: {n}" for n in info.notes]


def area_light_polygon(light, matrix):
    """World-space polygons (list of (k, 3) arrays, counter-clockwise about the emitting direction, local -Z)
    and the true world-space area of the light's shape."""
    m = np.asarray(matrix, np.float64)
    sx = float(light.size)
    sy = float(light.size_y) if light.shape in ("RECTANGLE", "ELLIPSE") else sx
    if light.shape in ("SQUARE", "RECTANGLE"):
        # Clockwise seen from +Z, so the right-hand normal points along -Z.
        local = np.array([[-sx / 2, -sy / 2, 0], [-sx / 2, sy / 2, 0], [sx / 2, sy / 2, 0], [sx / 2, -sy / 2, 0]])
        polys = [_transform(local, m)]
        area = _polygon_area(polys[0])
        return polys, area
    if light.shape in ("DISK", "ELLIPSE"):
        n = DISK_SECTORS
        # Inscribed n-gon scaled so its area equals the ellipse's, pi*a*b (size is the diameter).
        k = math.sqrt(math.pi / (0.5 * n * math.sin(2 * math.pi / n)))
        ang = -2 * math.pi * np.arange(n) / n                     # decreasing angle: clockwise from +Z
        rim = np.stack([k * sx / 2 * np.cos(ang), k * sy / 2 * np.sin(ang), np.zeros(n)], axis=1)
        centre = np.zeros((1, 3))
        world_rim = _transform(rim, m)
        world_c = _transform(centre, m)[0]
        polys = [np.stack([world_c, world_rim[i], world_rim[(i + 1) % n]]) for i in range(n)]
        area = sum(_polygon_area(p) for p in polys)
        return polys, area
    raise ExportError(f"area light shape '{light.shape}' is not supported")


def _polygon_area(p):
    s = np.zeros(3)
    for i in range(len(p)):
        s += np.cross(p[i], p[(i + 1) % len(p)])
    return 0.5 * float(np.linalg.norm(s))


def _cast_shadow(light):
    # Cycles' own settings are an add-on property group, which a change does not re-evaluate: read the original.
    light = getattr(light, "original", None) or light
    return compat.light_casts_shadow(light)


def lamp_light(light, matrix, name, index):
    """The solver's dict for a POINT, SPOT or SUN light in Cycles' units (blender-facts section 1), or None
    when it gives no light."""
    m = np.asarray(matrix, np.float64)
    colour = np.array(light.color[:3], np.float64)
    value = float(light.energy) * colour
    if not (value > 0).any():
        return None
    # Lamps emit along their local -Z; Cycles ignores the object's scale for their size.
    down = -m[:3, 2]
    norm = np.linalg.norm(down)
    d = {"type": light.type, "value": tuple(value), "cast_shadow": _cast_shadow(light), "object": index,
         "position": tuple(m[:3, 3]), "direction": tuple(down / norm) if norm > 0 else (0.0, 0.0, -1.0)}
    if light.type in ("POINT", "SPOT"):
        d["radius"] = float(light.shadow_soft_size)
        d["sphere"] = compat.lamp_is_sphere(light)
    if light.type == "SPOT":
        d["spot_size"] = float(light.spot_size)
        d["spot_blend"] = float(light.spot_blend)
        d["spot_cosine"] = compat.spot_multiplies_cosine()
    if light.type == "SUN":
        d["angle"] = float(light.angle)
    return d


def world_light(scene, result):
    """The world for the solver: (its light dict without "object", or None; a reason it was skipped, or None).

    A uniform Background colour, or an Environment Texture (equirectangular, default vector) on its Color, read
    directly; any other world node tree as Cycles renders it into an equirectangular map (world_map)."""
    value, why = _world_value(scene)
    if isinstance(value, dict) or value is None:
        return value, why
    return {"type": "WORLD", "value": value}, why


def _environment(node, strength, world):
    """A Background colour linked straight from an equirectangular Environment Texture: its light dict. Any
    other texture, mapping or projection: the world as Cycles renders it (world_map)."""
    if node.type != "TEX_ENVIRONMENT" or node.projection != "EQUIRECTANGULAR" or node.inputs["Vector"].is_linked:
        return _rendered(world)
    try:
        rgb = image_rgb(node.image)
    except Exception as e:  # a missing file: say so rather than bake the scene dark
        return None, f"world Environment Texture cannot be read ({e})"
    if strength <= 0 or not (rgb > 0).any():
        return None, None
    return {"type": "WORLD", "value": (strength,) * 3, "environment": rgb}, None


def _rendered(world):
    """Any other world node tree, evaluated by Cycles into an equirectangular map (world_map.render_world)."""
    from . import world_map
    try:
        rgb, suns = world_map.render_world_and_sun(world)
    except (RuntimeError, ValueError) as e:
        return None, f"world could not be rendered into an environment map ({e})"
    if not (rgb > 0).any() and not suns:
        return None, None
    return {"type": "WORLD", "value": (1.0, 1.0, 1.0), "environment": rgb, "rendered": True, "suns": suns}, None


def _world_value(scene):
    w = scene.world
    if w is None:
        return None, None
    if not compat.uses_nodes(w):
        c = np.array(w.color[:3], np.float64)
        return (tuple(c) if (c > 0).any() else None), None
    out = w.node_tree.get_output_node("CYCLES")
    if out is None or not out.inputs["Surface"].is_linked:
        return None, None
    node = out.inputs["Surface"].links[0].from_node
    if node.type != "BACKGROUND":
        return _rendered(w)
    c, s = node.inputs["Color"], node.inputs["Strength"]
    if s.is_linked:
        return _rendered(w)
    if c.is_linked:
        if s.default_value <= 0:
            return None, None
        return _environment(c.links[0].from_node, float(s.default_value), w)
    value = np.array(c.default_value[:3], np.float64) * float(s.default_value)
    return (tuple(value) if (value > 0).any() else None), None


def rendered_objects(view_layer):
    """Objects Cycles renders in this view layer, by full name: in a collection that is neither excluded
    nor disabled in renders, and not disabled in renders themselves. Viewport hiding plays no part."""
    found = {}
    compat.sync_layer_collections(view_layer)

    def walk(lc):
        if lc.exclude or lc.collection.hide_render:
            return
        for ob in lc.collection.objects:
            if not ob.hide_render:
                found[ob.name_full] = ob
        for child in lc.children:
            walk(child)
    walk(view_layer.layer_collection)
    return found


class render_visibility:
    """While the scene is read or written, show what Cycles renders but the viewport hides (the eye and the
    monitor of objects and collections): the viewport's depsgraph leaves such objects out, and a bake that
    dropped them would light the scene differently from a render. Every flag is put back on exit."""

    def __init__(self, scene, view_layer):
        self.vl = view_layer
        self.changes = []

    def _set(self, target, attr, value):
        try:
            old = getattr(target, attr)
            if old != value:
                setattr(target, attr, value)
                self.changes.append((target, attr, old))
        except (AttributeError, TypeError, RuntimeError):
            pass           # linked (read-only) data stays as it is

    def __enter__(self):
        vl = self.vl
        compat.sync_layer_collections(vl)

        def walk(lc):
            if lc.exclude or lc.collection.hide_render:
                return
            self._set(lc, "hide_viewport", False)
            self._set(lc.collection, "hide_viewport", False)
            for child in lc.children:
                walk(child)
        try:
            walk(vl.layer_collection)
            for ob in rendered_objects(vl).values():
                self._set(ob, "hide_viewport", False)
                if ob.hide_get(view_layer=vl):
                    ob.hide_set(False, view_layer=vl)
                    self.changes.append((ob, "hide_set", True))
        except BaseException:
            self.__exit__()
            raise
        return self

    def __exit__(self, *exc):
        for target, attr, old in reversed(self.changes):
            try:
                if attr == "hide_set":
                    target.hide_set(old, view_layer=self.vl)
                else:
                    setattr(target, attr, old)
            except ReferenceError:
                pass       # removed meanwhile
        self.changes.clear()
        return False


NO_SURFACE_TYPES = ("CURVE", "SURFACE", "META", "FONT")


def _instance_bakes(res, mesh_owner):
    """Which instanced objects get a lightmap with a tile per collection instance: each object once (its own
    placement, if rendered, is tile 0), unless its mesh is linked, shared with another baked object, or one
    empty instances it twice (nested collections)."""
    for name, placements in list(res.instances.items()):
        ob = bpy.data.objects[name]
        owners = [p[0] for p in placements]
        why = None
        if ob.data.library is not None or getattr(ob.data, "override_library", None):
            why = "the mesh is linked from a library"
        elif len(set(owners)) != len(owners):
            why = "an empty instances it more than once (nested collections)"
        elif name not in res.bake_objects and ob.data.name_full in mesh_owner:
            why = f"it shares its mesh with '{mesh_owner[ob.data.name_full]}'"
        if why:
            del res.instances[name]
            res.skip(f"{name} (instances)", f"not baked: instance; {why} (its instances take part in the solve)")
            continue
        if name not in res.bake_objects:
            mesh_owner[ob.data.name_full] = name
            res.bake_objects.append(name)
            res.instance_only.add(name)
            if two_sided(ob):
                res.two_sided.add(name)
        res.notes.append(f"object '{name}': its {len(placements)} collection instance(s) ({', '.join(owners)}) "
                         f"get tiles of their own in its lightmap")


def two_sided(ob):
    """Object Properties > Penumbra > Two-sided. Reading ob.penumbra_settings creates the group on the object,
    and a bake must not change objects: look first whether it is set (as __init__._opted_out does)."""
    try:
        return ob.is_property_set("penumbra_settings") and bool(ob.penumbra_settings.two_sided)
    except (AttributeError, TypeError):
        return False


# The share of a lightmap its UV islands cover (a smart projection with margins, measured on the examples:
# 0.45-0.6), to turn an object's area and the lightmap's resolution into a texel size before the UVs exist.
UV_FILL = 0.5


def element_floor(ex, resolution, texels):
    """Per exported face, the finest element edge in metres the solver may cut it into (`_native.solve`'s
    `min_edge`): `texels` texel sizes of the object's lightmap, so that a hall is meshed as finely as its
    lightmaps can show and a small object no finer than they can. 0 (the solver's min_size rule) for faces
    that get no lightmap: lamps, instances and objects the bake skips."""
    if not len(ex.polygons):
        return np.zeros(0, np.float32)
    v, p = ex.vertices.astype(np.float64), ex.polygons
    a, b, c = v[p[:, 0]], v[p[:, 1]], v[p[:, 2]]
    d = np.where((p[:, 3] >= 0)[:, None], v[np.maximum(p[:, 3], 0)], b)
    area = 0.5 * np.linalg.norm(np.cross(c - a, d - b), axis=1)
    per_object = np.bincount(ex.object_index, weights=area, minlength=len(ex.object_names))
    baked = set(ex.bake_objects)
    edge = np.zeros(len(ex.object_names))
    for k, name in enumerate(ex.object_names):
        if name in baked and per_object[k] > 0:
            tiles = max(1, len(ex.instances.get(name, ())) + (name not in ex.instance_only))
            edge[k] = texels * np.sqrt(per_object[k] * tiles / (UV_FILL * resolution * resolution))
    return edge[ex.object_index].astype(np.float32)


def export_scene(scene, view_layer, depsgraph, selection_only=False, progress=None, instance_lightmaps=False):
    res = Exported()
    verts, polys, refl, emit, flags, oidx = [], [], [], [], [], []
    base = 0
    cache = {}
    reported = set()
    mesh_owner = {}                  # mesh name -> first baked object that uses it

    def add_part(name, co_w, rows, albedo, exitance, fl):
        nonlocal base
        k = len(res.object_names)
        res.object_names.append(name)
        verts.append(co_w.astype(np.float32))
        polys.append(np.where(rows >= 0, rows + base, -1).astype(np.int32))
        refl.append(albedo.astype(np.float32))
        emit.append(exitance.astype(np.float32))
        flags.append(fl.astype(np.uint8))
        oidx.append(np.full(len(rows), k, np.int32))
        base += len(co_w)

    n_lights = 0
    rendered = rendered_objects(view_layer)
    not_rendered = set()
    non_mesh = {}                    # curve, text, ... object name -> type
    own_surface = set()              # of those, the ones whose evaluated surface was exported
    seen = set()
    for inst in depsgraph.object_instances:
        ob_eval = inst.object
        original = ob_eval.original
        is_inst = inst.is_instance
        owner = inst.parent.original if is_inst and inst.parent is not None else original
        if not is_inst:
            seen.add(original.name_full)
        if not is_inst and not inst.show_self:
            continue
        if owner.name_full not in rendered or (is_inst and original.hide_render):
            # Cycles does not render it, so it must neither be baked nor cast shadows.
            if not is_inst and owner.name_full not in not_rendered and \
                    original.type in ("MESH", "LIGHT") + NO_SURFACE_TYPES:
                not_rendered.add(owner.name_full)
                res.skip(owner.name, "not exported: disabled in renders (camera icon of the object or its "
                                     "collection), as in Cycles")
            continue
        if selection_only and not owner.select_get(view_layer=view_layer):
            continue
        # Curves, text, surfaces and metaballs evaluate to a mesh that the depsgraph lists as an instance of
        # the object itself: that is the object's own surface, not an instance.
        own = is_inst and owner == original and original.type in NO_SURFACE_TYPES
        name = original.name if not is_inst or own else f"{original.name} (instance via {owner.name})"
        matrix = np.array(inst.matrix_world, np.float64)

        if ob_eval.type == "LIGHT":
            light = ob_eval.data
            if light.type in ("POINT", "SPOT", "SUN"):
                k = len(res.object_names)
                d = lamp_light(light, matrix, name, k)
                if d is None:
                    res.skip(name, f"{light.type} light with negative power ({light.energy:g} W) is not supported"
                                   if light.energy < 0 else f"{light.type} light with zero power")
                    continue
                res.object_names.append(name)
                res.lights.append(d)
                continue
            if light.type != "AREA":
                res.skip(name, f"{light.type} light is not supported")
                continue
            if abs(light.spread - math.pi) > 1e-4:
                res.warnings.append(f"area light '{name}': spread {math.degrees(light.spread):.0f} deg is "
                                    f"treated as 180 deg (Lambertian)")
            if light.energy < 0:
                res.skip(name, f"area light with negative power ({light.energy:g} W) is not supported")
                continue
            if light.energy == 0:
                res.skip(name, "area light with zero power")
                continue
            lpolys, area = area_light_polygon(light, matrix)
            if area <= 0:
                res.skip(name, "area light with zero area")
                continue
            exitance = compat.area_light_exitance(light.energy, area) * np.array(light.color, np.float64)
            co_w = np.concatenate(lpolys)
            rows = np.full((len(lpolys), 4), -1, np.int32)
            start = 0
            for i, p in enumerate(lpolys):
                rows[i, :len(p)] = np.arange(start, start + len(p))
                start += len(p)
            n = len(lpolys)
            # Cycles' bake under a black card with the light's Cast Shadow off: the bare light (5.49 against 0.43
            # with it on, blender_tests/test_ray_visibility.py); before, the flag was ignored for AREA lights.
            flag = LIGHT_ONLY if _cast_shadow(light) else LIGHT_ONLY | CASTS_NO_SHADOW
            add_part(name, co_w, rows, np.zeros((n, 3)), np.tile(exitance, (n, 1)), np.full(n, flag, np.uint8))
            n_lights += 1
            continue

        if ob_eval.type != "MESH":
            if ob_eval.type in NO_SURFACE_TYPES:
                non_mesh[name] = ob_eval.type
            elif ob_eval.type in ("CURVES", "POINTCLOUD", "VOLUME", "GPENCIL"):
                res.skip(name, f"not exported: {ob_eval.type} objects are not supported (Cycles renders it, so "
                               f"its shadow and reflected light are missing; convert it to a mesh)")
            continue

        me = ob_eval.to_mesh()
        try:
            if len(me.polygons) == 0:
                if not own:
                    res.skip(name, "mesh has no faces")
                continue
            co, rows, src = mesh_polygons(me)
            mat_index = _get(me.polygons, "material_index", len(me.polygons), np.int32)
            slots, albedo_t, rad_t = _material_table(ob_eval, name, cache, res)
            si = np.clip(mat_index[src], 0, len(slots) - 1)
            used = np.bincount(si, minlength=len(slots)) > 0
            _report_material(slots, used, name, cache, res, reported)
            co_w = _transform(co, matrix)
            if np.linalg.det(matrix[:3, :3]) < 0:
                # A mirroring transform reverses the winding; Blender keeps the normal, so reverse the order.
                tri = rows[:, 3] < 0
                rows = np.where(tri[:, None], rows[:, [2, 1, 0, 3]], rows[:, [3, 2, 1, 0]])
            radiance = rad_t[si]
            fl = np.where(radiance.max(axis=1) > 0, EMIT_BACK, 0).astype(np.uint8)
            both = two_sided(original)
            if both:
                # Cycles shades both sides of a face; the solver's back twin of each face receives and
                # reflects there (and emits what the front emits, which Cycles' mesh emitters do too).
                fl |= EMIT_BACK
            shadow, diffuse = compat.ray_visibility(ob_eval.original)
            if not shadow:
                fl |= NO_LAMP_SHADOW
                res.notes.append(f"object '{name}': hidden from shadow rays, so lamps, area lights and emitting "
                                 f"meshes shine through it onto the lightmaps; the world is still blocked by it, "
                                 f"and the light bounced on from what it shades is as if it blocked")
            if not diffuse:
                fl |= NO_DIFFUSE
                res.notes.append(f"object '{name}': hidden from diffuse rays, so it reflects no light onto others and "
                                 f"the light bounced between others passes it; it is still lit and baked, and still "
                                 f"blocks the lamps', area lights', emitters' and the world's light")
            add_part(name, co_w, rows, albedo_t[si], math.pi * radiance, fl)
        finally:
            ob_eval.to_mesh_clear()

        if own:
            own_surface.add(name)
        elif is_inst and instance_lightmaps and owner.instance_type == "COLLECTION" and owner != original \
                and owner.library is None:
            # (A linked empty cannot hold its tile's property, so its instances stay untiled and reported.)
            res.instances.setdefault(original.name, []).append((owner.name, matrix))
        elif is_inst:
            res.skip(name, "not baked: instance (its mesh data is shared; it takes part in the solve)"
                     + ("" if owner.instance_type != "COLLECTION" else
                        "; the instance_lightmaps setting gives collection instances tiles of their own"))
        elif original.data.library is not None or getattr(original.data, "override_library", None):
            res.skip(name, "not baked: the mesh is linked from a library (it takes part in the solve)")
        elif original.data.name_full in mesh_owner:
            res.skip(name, f"not baked: shares its mesh with '{mesh_owner[original.data.name_full]}' "
                           f"(it takes part in the solve)")
        else:
            mesh_owner[original.data.name_full] = original.name
            res.bake_objects.append(original.name)
            if both:
                res.two_sided.add(original.name)

    _instance_bakes(res, mesh_owner)
    for name_full, ob in rendered.items():
        if name_full not in seen and ob.type in ("MESH", "LIGHT") + NO_SURFACE_TYPES:
            # render_visibility could not show it (linked, read-only flags), so the depsgraph left it out.
            res.skip(ob.name, "not exported: Cycles renders it, but it is hidden in the viewport and its "
                              "visibility cannot be changed for the bake (linked data); show it to include it")
    for name, kind in non_mesh.items():
        if name in own_surface:
            res.skip(name, f"not baked: {kind} object; its surface takes part in the solve (casts and reflects "
                           f"light) but only mesh objects get a lightmap (convert it to a mesh to bake it)")
        else:
            res.skip(name, f"not exported: the {kind} object has no faces (Cycles renders none either)")
    world, why = world_light(scene, res)
    if why:
        res.skip(scene.world.name, why)
    elif world is not None:
        res.object_names.append(f"World '{scene.world.name}'")
        k = len(res.object_names) - 1
        suns = world.pop("suns", [])
        if world.pop("rendered", False):
            from . import world_map
            res.notes.append(f"world '{scene.world.name}': its node tree was evaluated by Cycles into a "
                             f"{world_map.WIDTH} x {world_map.HEIGHT} environment map"
                             + (f", its sun disc sent as a SUN lamp" if suns else ""))
        res.lights.append(dict(world, object=k))
        res.lights += [dict(sun, object=k) for sun in suns]
    if polys:
        res.vertices = np.ascontiguousarray(np.concatenate(verts), np.float32)
        res.polygons = np.ascontiguousarray(np.concatenate(polys), np.int32)
        res.reflectance = np.ascontiguousarray(np.concatenate(refl), np.float32)
        res.emission = np.ascontiguousarray(np.concatenate(emit), np.float32)
        res.flags = np.ascontiguousarray(np.concatenate(flags), np.uint8)
        res.object_index = np.ascontiguousarray(np.concatenate(oidx), np.int32)
    kinds = [d["type"] for d in res.lights]
    res.counts = {"objects": len(res.object_names), "area_lights": n_lights,
                  "point_lights": kinds.count("POINT"), "spot_lights": kinds.count("SPOT"),
                  "sun_lights": kinds.count("SUN"), "world": kinds.count("WORLD"),
                  "polygons": int(len(res.polygons)), "vertices": int(len(res.vertices)),
                  "emitting_polygons": int((res.emission.max(axis=1) > 0).sum()) if len(res.emission) else 0}
    return res

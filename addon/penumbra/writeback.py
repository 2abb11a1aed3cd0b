"""Writing a solved bake back into the .blend: lightmap UV maps, float lightmap images, CORNER color attributes.

The write-back is a transaction. Every change is recorded with a way to undo it; anything that can fail
(unwrapping, rasterising, writing files) happens before the commit, which only swaps the new data for what an
earlier bake made. On any exception the recorded changes are undone in reverse order, so the .blend is left as
it was before the bake. Files are part of it: lightmaps go to temporary names that replace the old files only
at the commit, and folders the bake created are removed again.
"""
import math
import os
import uuid
import zlib

import bpy
import numpy as np

from . import compat

UV_NAME = "PenumbraLightmap"
ATTRIBUTE = "Penumbra"
IMAGE_PREFIX = "Penumbra_"
PROP = "penumbra"            # custom property on a baked object: what the last bake made
# Above this fraction of shared texels a lightmap is called wrong; a few shared texels where islands touch
# at the packing margin are harmless.
OVERLAP_WARN = 0.02
# Objects whose modifiers (Array, Mirror, ...) copy faces onto the same lightmap UVs get a UV layout of their
# own, made for the modified surface: a mesh of it (COPIES_PREFIX + object) unwrapped like any other, which a
# Geometry Nodes modifier appended by the bake (COPIES_MODIFIER) copies corner by corner into the corner
# attribute COPIES_ATTRIBUTE of the evaluated mesh, where the preview (and any material) reads it.
COPIES_PREFIX = "PenumbraUV_"
COPIES_MODIFIER = "Penumbra Lightmap UV"
COPIES_ATTRIBUTE = "PenumbraLightmapUV"
# An object whose collection instances get lightmaps of their own (the instance_lightmaps setting) has one
# lightmap with a tile per instance: each instancing empty (and the object itself, when it is rendered) holds
# its tile as the custom property TILE_PROP = (u offset, v offset, scale), which the preview reads with an
# Attribute node of type Instancer (an instance reads its empty's, the object itself its own).
TILE_PROP = "penumbra_lightmap_tile"


def instance_tiles(instancers, own):
    """{instancer name (or "" for the object itself): (u offset, v offset, scale)} on a square grid."""
    names = ([""] if own else []) + list(instancers)
    g = max(1, math.ceil(math.sqrt(len(names))))
    return {n: ((k % g) / g, (k // g) / g, 1.0 / g) for k, n in enumerate(names)}


class WritebackError(RuntimeError):
    pass


class Transaction:
    def __init__(self):
        self._undo = []
        self._commit = []
        self._discard = []
        self._index = {}

    def index(self, collection, key="name"):
        """{key: data-block} of bpy.data.<collection>, made once per commit: a lookup by name in bpy.data walks
        the whole collection, so one per object made the commit of N objects cost N^2. Commit steps that
        rename a data-block of it update it (`renamed`)."""
        idx = self._index.get((collection, key))
        if idx is None:
            idx = {}
            for d in getattr(bpy.data, collection):
                idx.setdefault(getattr(d, key), d)     # the first of equal names, as bpy.data[name] gives
            self._index[(collection, key)] = idx
        return idx

    def renamed(self, collection, old_name, datablock):
        idx = self._index.get((collection, "name"))
        if idx is not None:
            if idx.get(old_name) is not None and idx[old_name] == datablock:
                del idx[old_name]
            idx.setdefault(datablock.name, datablock)

    def discard(self, datablock):
        """Remove `datablock` once every commit step has run, in one batch with the others."""
        self._discard.append(datablock)

    def on_rollback(self, fn):
        self._undo.append(fn)

    def on_commit(self, fn):
        self._commit.append(fn)

    def commit(self):
        try:
            for fn in self._commit:
                fn()
        finally:
            self._index.clear()
        if self._discard:
            bpy.data.batch_remove(self._discard)
            self._discard.clear()
        self._undo.clear()

    def rollback(self):
        errors = []
        for fn in reversed(self._undo):
            try:
                fn()
            except Exception as e:  # keep undoing the rest; report what could not be undone
                errors.append(str(e))
        self._undo.clear()
        return errors


def _get(coll, attr, n, dtype, width=1):
    a = np.empty(n * width, dtype)
    if n:
        coll.foreach_get(attr, a)
    return a.reshape(n, width) if width > 1 else a


def baked_state(ob):
    """What the last bake recorded on the object, as a plain dict (empty if never baked)."""
    v = ob.get(PROP)
    return v.to_dict() if v is not None and hasattr(v, "to_dict") else {}


# ---------------------------------------------------------------------------------------------- UV maps

class _SelectionState:
    """Object selection, active object and mode, restored after the unwrap operators ran."""

    def __init__(self, view_layer):
        self.vl = view_layer
        self.selected = {o.name for o in view_layer.objects if o.select_get(view_layer=view_layer)}
        self.active = view_layer.objects.active.name if view_layer.objects.active else None

    def restore(self):
        objs = self.vl.objects
        for o in objs:
            want = o.name in self.selected
            if o.select_get(view_layer=self.vl) != want:
                o.select_set(want, view_layer=self.vl)
        objs.active = objs.get(self.active) if self.active else None


def _element_flags(me):
    """Select and hide flags of the mesh elements (edit mode's select-all and reveal overwrite them)."""
    out = {}
    for coll_name in ("vertices", "edges", "polygons"):
        coll = getattr(me, coll_name)
        for attr in ("select", "hide"):
            out[(coll_name, attr)] = _get(coll, attr, len(coll), bool)
    return out


def _restore_element_flags(me, flags):
    for (coll_name, attr), a in flags.items():
        coll = getattr(me, coll_name)
        if len(coll) == len(a):
            coll.foreach_set(attr, a)


def _call_op(idname, **props):
    """Run an operator without the view-layer update that bpy.ops does before and after every call. Each of
    those updates re-evaluates the whole scene once anything is tagged (a selection change is enough), so five
    operators per object made the unwrap of N objects cost N^2; the depsgraph is brought up to date once,
    after the last object. Falls back to bpy.ops where Blender's private entry point is missing (5.x)."""
    call = compat.operator_call_without_update()
    if call is None:
        module, name = idname.split(".")
        return getattr(getattr(bpy.ops, module), name)(**props)
    return call(idname, props)


def _unwrap(ob, scene, view_layer, stand_in=False):
    """Smart-project every face of `ob` into its active UV map (edit mode, with `ob` alone selected).
    `stand_in`: `ob` is not in the view layer."""
    if stand_in:
        # A collection member seen only through its instances is not in the view layer, where edit mode needs
        # it: its mesh is unwrapped through a stand-in object linked to the scene meanwhile.
        tmp = bpy.data.objects.new(ob.name + ".penumbra-unwrap", ob.data)
        tmp.matrix_world = ob.matrix_world
        scene.collection.objects.link(tmp)
        try:
            _unwrap(tmp, scene, view_layer)
        finally:
            bpy.data.objects.remove(tmp)
        return
    ob.select_set(True, view_layer=view_layer)
    view_layer.objects.active = ob
    try:
        with bpy.context.temp_override(scene=scene, view_layer=view_layer, active_object=ob, object=ob):
            _call_op("object.mode_set", mode="EDIT")
            try:
                _call_op("mesh.reveal", select=False)
                _call_op("mesh.select_all", action="SELECT")
                # Smart project keeps whole coplanar regions in one island (blender-facts §4), so bilinear
                # lookups do not show seams at every face.
                _call_op("uv.smart_project", angle_limit=math.radians(66.0), island_margin=0.02,
                         area_weight=0.0, correct_aspect=True, scale_to_bounds=False)
            finally:
                _call_op("object.mode_set", mode="OBJECT")
    finally:
        ob.select_set(False, view_layer=view_layer)


def _prepare_uv(ob, scene, view_layer, uv_setting, tx, stand_in=False):
    me = ob.data
    if uv_setting:
        if uv_setting not in me.uv_layers:
            raise WritebackError(f"object '{ob.name}' has no UV map named '{uv_setting}'")
        return uv_setting, False

    layers = me.uv_layers
    old_active = layers.active.name if layers.active else None
    old_render = next((l.name for l in layers if l.active_render), None)
    layer = layers.get(UV_NAME)
    created = layer is None
    if created:
        if len(layers) >= 8:
            raise WritebackError(f"object '{ob.name}' already has 8 UV maps; name one for the lightmap "
                                 f"with the uv_map setting")
        layer = layers.new(name=UV_NAME, do_init=False)
        if layer is None:
            raise WritebackError(f"cannot add a UV map to object '{ob.name}'")
        mesh_name = me.name_full

        def drop():
            m = bpy.data.meshes.get(mesh_name)
            if m is not None and UV_NAME in m.uv_layers:
                m.uv_layers.remove(m.uv_layers[UV_NAME])
        tx.on_rollback(drop)
    else:
        saved = _get(layer.data, "uv", len(layer.data), np.float32, 2)
        mesh_name = me.name_full

        def restore_uv():
            m = bpy.data.meshes.get(mesh_name)
            if m is not None and UV_NAME in m.uv_layers:
                m.uv_layers[UV_NAME].data.foreach_set("uv", saved.ravel())
        tx.on_rollback(restore_uv)

    layers.active = layer
    flags = _element_flags(me)
    attrs_before = compat.mesh_attribute_names(me)
    try:
        _unwrap(ob, scene, view_layer, stand_in)
    finally:
        _restore_element_flags(me, flags)
        compat.drop_new_internal_attributes(me, attrs_before)
        if old_active and old_active in layers:
            layers.active = layers[old_active]
        if old_render and old_render in layers:
            layers[old_render].active_render = True
    return UV_NAME, created


def prepare_uvs(objects, scene, view_layer, uv_setting, tx):
    """{name: (lightmap UV map's name, whether this bake created it)} for `objects`, unwrapping
    PenumbraLightmap unless the user named a UV map. The selection is cleared once for all of them and
    restored once at the end: doing it per object walked every object of the view layer per object."""
    out = {}
    if uv_setting:
        for ob in objects:
            out[ob.name] = _prepare_uv(ob, scene, view_layer, uv_setting, tx)
        return out
    sel = _SelectionState(view_layer)
    try:
        in_layer = set()
        for o in view_layer.objects:
            in_layer.add(o.name_full)
            if o.select_get(view_layer=view_layer):
                o.select_set(False, view_layer=view_layer)
        for ob in objects:
            # An object baked for its collection instances only is in no collection of the view layer.
            out[ob.name] = _prepare_uv(ob, scene, view_layer, uv_setting, tx, ob.name_full not in in_layer)
    finally:
        sel.restore()
    return out


# ---------------------------------------------------------------------------------------------- modifier copies

def _is_copies_modifier(mod):
    return mod.type == "NODES" and mod.name == COPIES_MODIFIER and mod.node_group is not None and \
        bool(mod.node_group.get("penumbra"))


def find_copies(objs, names, dg, uv, native, resolution):
    """The objects among `names` whose modifiers lay faces onto texels of the bake's own lightmap UV map that
    other faces use too (an Array's or a Mirror's copies): the share of texels is measured on the modified
    surface, as the lightmap would be baked. Objects without modifiers are not looked at: their UV map is a
    smart projection of their own faces, which never overlaps."""
    cand, tris = [], []
    for n in names:
        ob = objs[n]
        # Any modifier: the mesh is measured as the bake's depsgraph evaluated it, whichever switch it heeded.
        if uv[n][0] != UV_NAME or not any(not _is_copies_modifier(m) for m in ob.modifiers):
            continue
        ob_eval = ob.evaluated_get(dg)
        me = ob_eval.to_mesh()
        try:
            if UV_NAME not in me.uv_layers:
                continue
            me.calc_loop_triangles()
            n_tri = len(me.loop_triangles)
            tri_l = _get(me.loop_triangles, "loops", n_tri, np.int32, 3)
            uvs = _get(me.uv_layers[UV_NAME].data, "uv", len(me.loops), np.float32, 2)
            tris.append(np.ascontiguousarray(uvs[tri_l], np.float32))
            cand.append(n)
        finally:
            ob_eval.to_mesh_clear()
    if not cand:
        return []
    shared = native.uv_overlaps(tris, min(resolution, 256))
    return [n for n, sh in zip(cand, shared) if float(sh) > OVERLAP_WARN]


def unwrap_copies(ob, dg, scene, view_layer, tx):
    """A mesh of `ob`'s modified surface (corner for corner the evaluated mesh) with a smart-projected
    PenumbraLightmap UV map, held by an object of its own that no collection shows, and the Geometry Nodes
    group that copies those UVs onto the evaluated mesh. Nothing is attached to `ob` before the commit
    (attach_copies); until then a rollback removes all three."""
    ob_eval = ob.evaluated_get(dg)
    me = bpy.data.meshes.new_from_object(ob_eval)
    made = {"mesh": me.name}

    def drop(made=made):
        for coll, key in (("node_groups", "group"), ("objects", "object"), ("meshes", "mesh")):
            d = getattr(bpy.data, coll).get(made.get(key, ""))
            if d is not None:
                getattr(bpy.data, coll).remove(d)
    tx.on_rollback(drop)
    # Never rename onto a taken name: Blender 3.4 would rename the other data-block (an earlier bake's helper,
    # which a rollback must leave as it was) instead.
    me.name = _free_name(bpy.data.meshes, COPIES_PREFIX + ob.name)
    made["mesh"] = me.name
    if COPIES_ATTRIBUTE in me.attributes:           # copied from an earlier bake's modifier: not needed here
        me.attributes.remove(me.attributes[COPIES_ATTRIBUTE])
    layer = me.uv_layers.get(UV_NAME)
    if layer is None:
        raise WritebackError(f"object '{ob.name}': its modified surface lost the UV map '{UV_NAME}'")
    me.uv_layers.active = layer
    helper = bpy.data.objects.new(_free_name(bpy.data.objects, COPIES_PREFIX + ob.name), me)
    made["object"] = helper.name
    # The same transform as the object, so the smart projection sees the shapes an applied modifier gives.
    helper.matrix_world = ob.matrix_world
    scene.collection.objects.link(helper)
    sel = _SelectionState(view_layer)
    try:
        for o in view_layer.objects:
            if o.select_get(view_layer=view_layer):
                o.select_set(False, view_layer=view_layer)
        _unwrap(helper, scene, view_layer)
    finally:
        scene.collection.objects.unlink(helper)
        sel.restore()
    helper.matrix_world = ((1, 0, 0, 0), (0, 1, 0, 0), (0, 0, 1, 0), (0, 0, 0, 1))
    helper["penumbra"] = True
    ng = _copies_group(helper)
    made["group"] = ng.name
    return me, ng.name


def _free_name(coll, name):
    """`name`, or the first `name.NNN` that no data-block of `coll` has."""
    i, out = 0, name
    while coll.get(out) is not None:
        i += 1
        out = f"{name}.{i:03d}"
    return out


def _copies_group(helper):
    """Store Named Attribute (corner, vector) COPIES_ATTRIBUTE = the helper mesh's lightmap UV at the same
    corner index (Sample Index over Object Info): the evaluated mesh keeps its geometry and gains the UVs."""
    from . import compat
    ng = bpy.data.node_groups.new(COPIES_MODIFIER, "GeometryNodeTree")
    ng["penumbra"] = True
    compat.geometry_group_sockets(ng)
    nodes, links = ng.nodes, ng.links
    gin, gout = nodes.new("NodeGroupInput"), nodes.new("NodeGroupOutput")
    info = nodes.new("GeometryNodeObjectInfo")
    info.inputs["Object"].default_value = helper
    named = nodes.new("GeometryNodeInputNamedAttribute")
    named.data_type = "FLOAT_VECTOR"
    named.inputs["Name"].default_value = UV_NAME
    sample = nodes.new("GeometryNodeSampleIndex")
    sample.data_type, sample.domain = "FLOAT_VECTOR", "CORNER"
    index = nodes.new("GeometryNodeInputIndex")
    store = nodes.new("GeometryNodeStoreNamedAttribute")
    store.data_type, store.domain = "FLOAT_VECTOR", "CORNER"
    store.inputs["Name"].default_value = COPIES_ATTRIBUTE
    links.new(gin.outputs[0], store.inputs["Geometry"])
    links.new(info.outputs["Geometry"], sample.inputs["Geometry"])
    links.new(compat.shown_socket(named.outputs, "Attribute"), compat.shown_socket(sample.inputs, "Value"))
    links.new(index.outputs["Index"], sample.inputs["Index"])
    links.new(compat.shown_socket(sample.outputs, "Value"), compat.shown_socket(store.inputs, "Value"))
    links.new(store.outputs["Geometry"], gout.inputs[0])
    return ng


def _copies_parts(mod):
    """The node group, helper object and helper mesh of one of our modifiers (those that exist)."""
    ng = mod.node_group
    out = [ng]
    info = next((n for n in ng.nodes if n.type == "OBJECT_INFO"), None)
    helper = info.inputs["Object"].default_value if info is not None else None
    if helper is not None and helper.get("penumbra"):
        out.append(helper)
        if helper.data is not None and helper.data.users <= 1:
            out.append(helper.data)
    return out


def _drop_copies_modifiers(o, discard):
    for mod in [m for m in o.modifiers if _is_copies_modifier(m)]:
        parts = _copies_parts(mod)
        o.modifiers.remove(mod)
        for d in parts:
            discard(d)


def attach_copies(ob, group_name, tx):
    """At the commit: `ob`'s modifier of an earlier bake (and its helper) goes, and a new one with the group
    unwrap_copies made is appended last in the stack, so it sees the surface every other modifier made."""
    ob_name = ob.name

    def attach():
        o = tx.index("objects")[ob_name]

        def retire(d):
            # The old helper's names go free for the new one before it is removed with the others.
            d.name = d.name[:40] + ".penumbra-old"
            tx.discard(d)
        _drop_copies_modifiers(o, retire)
        mod = o.modifiers.new(COPIES_MODIFIER, "NODES")
        ng = bpy.data.node_groups[group_name]
        mod.node_group = ng
        for d in _copies_parts(mod)[1:]:
            if COPIES_PREFIX + ob_name not in (bpy.data.objects if isinstance(d, bpy.types.Object)
                                               else bpy.data.meshes):
                d.name = COPIES_PREFIX + ob_name
    tx.on_commit(attach)


def detach_copies(ob, tx):
    """At the commit: an earlier bake's modifier goes when this bake needs none (the copies were applied or
    removed)."""
    if not any(_is_copies_modifier(m) for m in ob.modifiers):
        return
    ob_name = ob.name
    tx.on_commit(lambda: _drop_copies_modifiers(tx.index("objects")[ob_name], tx.discard))


# ---------------------------------------------------------------------------------------------- sampling

class _MeshCache:
    """World vertices and face normals of one mesh under one transform, computed once for the lightmap, the
    corner colours and the front-side check (each computed the same numbers on its own)."""

    def __init__(self, me, matrix):
        self.me, self.matrix = me, matrix
        self._co_w = self._nw = None

    def co_w(self):
        if self._co_w is None:
            me, matrix = self.me, self.matrix
            co = _get(me.vertices, "co", len(me.vertices), np.float32, 3).astype(np.float64)
            self._co_w = co @ matrix[:3, :3].T + matrix[:3, 3]
        return self._co_w

    def face_normals(self):
        """World normal of every face (normals transform with the inverse transpose)."""
        if self._nw is None:
            me = self.me
            pn = _get(me.polygons, "normal", len(me.polygons), np.float32, 3).astype(np.float64)
            nw = pn @ np.linalg.inv(self.matrix[:3, :3])
            nw /= np.maximum(np.linalg.norm(nw, axis=1, keepdims=True), 1e-30)
            self._nw = nw
        return self._nw


def _cache(me, matrix, cache):
    return cache if cache is not None and cache.me == me and cache.matrix is matrix else _MeshCache(me, matrix)


def _world_loop_triangles(me, matrix, cache=None):
    me.calc_loop_triangles()
    n_tri = len(me.loop_triangles)
    co_w = _cache(me, matrix, cache).co_w()
    tri_v = _get(me.loop_triangles, "vertices", n_tri, np.int32, 3)
    tri_l = _get(me.loop_triangles, "loops", n_tri, np.int32, 3)
    return co_w, tri_v, tri_l


def _lightmap_inputs(me, name, uv_name, matrix, cache=None, copies=None):
    """World-space corners (T,3,3) and UVs (T,3,2) of an evaluated mesh's loop triangles; with `copies` (the
    mesh unwrapped for the modified surface, corner for corner) its UV map instead of the object's own."""
    if copies is not None:
        if len(copies.loops) != len(me.loops):
            raise WritebackError(f"object '{name}': its modified surface changed while it was unwrapped")
        uv = _get(copies.uv_layers[UV_NAME].data, "uv", len(me.loops), np.float32, 2)
    elif uv_name not in me.uv_layers:
        raise WritebackError(f"object '{name}': the UV map '{uv_name}' does not survive its modifiers")
    else:
        uv = _get(me.uv_layers[uv_name].data, "uv", len(me.loops), np.float32, 2)
    co_w, tri_v, tri_l = _world_loop_triangles(me, matrix, cache)
    if np.linalg.det(matrix[:3, :3]) < 0:
        # A mirroring transform reverses the winding, and the solver takes a triangle's side from its
        # winding: without this a mirrored object's lightmap would hold the light behind each face.
        tri_v, tri_l = tri_v[:, [0, 2, 1]], tri_l[:, [0, 2, 1]]
    positions = np.ascontiguousarray(co_w[tri_v], np.float32)
    uvs = np.ascontiguousarray(uv[tri_l], np.float32)
    return positions, uvs


def uv_overlap(uvs, grid=256, chunk=200000):
    """Fraction of the covered texel centres (on a grid x grid raster) that lie strictly inside more than one
    UV triangle, from (T, 3, 2) UVs. Overlapping islands share texels, so those faces all get one light.
    The write-back uses the native module's uv_overlaps, which does this for many objects at once with the
    same arithmetic (blender_tests/test_writeback_scaling.py compares the two)."""
    t = np.asarray(uvs, np.float64) * grid - 0.5        # texel centre j sits at coordinate j
    a, b, c = t[:, 0], t[:, 1], t[:, 2]
    det = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (c[:, 0] - a[:, 0]) * (b[:, 1] - a[:, 1])
    ok = np.abs(det) > 1e-12
    lo = np.clip(np.ceil(t.min(axis=1)), 0, grid - 1).astype(np.int64)
    hi = np.clip(np.floor(t.max(axis=1)), -1, grid - 1).astype(np.int64)
    nx, ny = np.maximum(hi[:, 0] - lo[:, 0] + 1, 0), np.maximum(hi[:, 1] - lo[:, 1] + 1, 0)
    n = np.where(ok, nx * ny, 0)
    counts = np.zeros(grid * grid, np.int64)
    tri_ids = np.nonzero(n)[0]
    start = 0
    while start < len(tri_ids):
        # Bounded memory: candidate texels of a run of triangles at a time.
        end = start + 1
        total = n[tri_ids[start]]
        while end < len(tri_ids) and total + n[tri_ids[end]] <= chunk:
            total += n[tri_ids[end]]
            end += 1
        ids = tri_ids[start:end]
        k = np.repeat(ids, n[ids])
        offs = np.arange(len(k)) - np.repeat(np.cumsum(n[ids]) - n[ids], n[ids])
        px = lo[k, 0] + offs % nx[k]
        py = lo[k, 1] + offs // nx[k]
        d = det[k]
        l1 = ((px - a[k, 0]) * (c[k, 1] - a[k, 1]) - (c[k, 0] - a[k, 0]) * (py - a[k, 1])) / d
        l2 = ((b[k, 0] - a[k, 0]) * (py - a[k, 1]) - (px - a[k, 0]) * (b[k, 1] - a[k, 1])) / d
        # Strictly inside, so a texel centre on an edge two neighbours share is not an overlap.
        eps = 1e-6
        inside = (l1 > eps) & (l2 > eps) & (1.0 - l1 - l2 > eps)
        np.add.at(counts, (py * grid + px)[inside], 1)
        start = end
    covered = int((counts > 0).sum())
    return float((counts > 1).sum()) / covered if covered else 0.0


def corner_samples(me, matrix, cache=None):
    """World position of every corner and the world normal of its face, for a mesh in its own loop order."""
    n_loops, n_poly = len(me.loops), len(me.polygons)
    cache = _cache(me, matrix, cache)
    co_w = cache.co_w()
    lv = _get(me.loops, "vertex_index", n_loops, np.int32)
    loop_total = _get(me.polygons, "loop_total", n_poly, np.int32)
    nw = cache.face_normals()
    loop_poly = np.repeat(np.arange(n_poly), loop_total)
    return (np.ascontiguousarray(co_w[lv], np.float32), np.ascontiguousarray(nw[loop_poly], np.float32))


# ---------------------------------------------------------------------------------------------- writing

def _safe_filename(name):
    """A file name for a data-block name. Names that need no change keep it; any other gets a hash of the
    exact name, so that "Wall/1" and "Wall_1" cannot write the same file, and a name always maps to the
    same file from one bake to the next."""
    safe = "".join(c if c.isascii() and (c.isalnum() or c in "-_.") else "_" for c in name)
    if safe != name or safe.startswith("."):
        safe = f"{safe}-{zlib.crc32(name.encode('utf-8')):08x}"
    return safe


def store_pixels(img, px, native, data=None):
    """Put a lightmap (H, W, 4) into a new float image `img` (alpha off) as a packed EXR: `data`, or
    native.exr_bytes(px), the very file Blender 3.4's Image.pack() would write of `px`.

    Image.pack() encodes through OpenEXR, 0.6 ms for a 32 x 32 image: as long as the rest of an object's
    write-back. Here the image becomes a file image whose file is the packed one, and Blender reads its
    pixels from it when something first needs them (a material drawn, Image.pixels), as it does after the
    .blend is opened again; the EXR is lossless, so they are `px`'s bit for bit, alpha 1
    (blender_tests/test_writeback_scaling.py). Should a Blender keep no packed file from the bytes, the
    pixels are set and packed by Blender instead, as before."""
    if data is None:
        data = native.exr_bytes(px)
    if not _pack_file(img, data):
        img.source = "GENERATED"
        img.pixels.foreach_set(px.ravel())
        img.update()
        img.pack()


def _pack_file(img, data):
    """Make `img` a file image whose packed file is `data`; whether Blender kept it."""
    img.source = "FILE"
    img.pack(data=data, data_len=len(data))
    pf = img.packed_file
    return pf is not None and pf.size == len(data)


def _our_attribute(me, old):
    """The colour attribute name for this bake: the one the last bake made, else 'Penumbra' unless the user
    already has an attribute of that name (never replaced), else the first free 'Penumbra.NNN'."""
    if old.get("attribute") and old["attribute"] in me.attributes:
        return old["attribute"]
    name, i = ATTRIBUTE, 0
    while name in me.attributes:
        i += 1
        name = f"{ATTRIBUTE}.{i:03d}"
    return name


def _front_samples(me, matrix, cache=None):
    """World centres, normals and areas of (a sample of) the faces, for the front-light check; None without faces."""
    n = len(me.polygons)
    if n == 0:
        return None
    centre = _get(me.polygons, "center", n, np.float32, 3).astype(np.float64)
    area = _get(me.polygons, "area", n, np.float32).astype(np.float64)
    step = max(1, n // 20000)             # a sample is enough for a warning
    centre, area = centre[::step], area[::step]
    cw = centre @ matrix[:3, :3].T + matrix[:3, 3]
    if step == 1:
        nw = _cache(me, matrix, cache).face_normals()
    else:
        normal = _get(me.polygons, "normal", n, np.float32, 3).astype(np.float64)[::step]
        nw = normal @ np.linalg.inv(matrix[:3, :3])
        nw /= np.maximum(np.linalg.norm(nw, axis=1, keepdims=True), 1e-30)
    return np.ascontiguousarray(cw, np.float32), np.ascontiguousarray(nw, np.float32), area


def _front_warning(name, area, rgb):
    """Penumbra's surfaces receive and reflect light on their front (normal) side only, where Cycles shades
    both sides of a face. A mesh whose faces mostly get no light on the front usually has flipped normals;
    say so, since its bake will be dark where a render is lit."""
    dark = area[np.asarray(rgb).max(axis=1) <= 0].sum() / max(area.sum(), 1e-30)
    if dark > 0.5:
        return (f"object '{name}': {100 * dark:.0f} % of its surface receives no light on its front side. "
                f"Penumbra lights faces on the side their normals point to; Cycles lights both sides, so a render "
                f"shows light here. If its normals are flipped, recalculate them (Mesh > Normals); if it is an "
                f"open surface seen from both sides, turn on Two-sided in its Object Properties > Penumbra")
    return None


def _radiance_of_all(solution, samples, irradiance=False):
    """solution.radiance of every (points, normals) pair of `samples` (None entries give None), in one call:
    each point's radiance is computed alone, so the values are the ones a call per object gives."""
    sizes = [0 if x is None else len(x[0]) for x in samples]
    if not sum(sizes):
        return [None if x is None else np.zeros((0, 3), np.float32) for x in samples]
    pts = np.ascontiguousarray(np.concatenate([x[0] for x in samples if x is not None]), np.float32)
    nrm = np.ascontiguousarray(np.concatenate([x[1] for x in samples if x is not None]), np.float32)
    rgb = np.asarray(solution.radiance(pts, nrm, irradiance=irradiance), np.float32)
    if rgb.shape != (len(pts), 3):
        raise WritebackError(f"the solver returned radiance of shape {rgb.shape}, expected {(len(pts), 3)}")
    out, i = [], 0
    for x, n in zip(samples, sizes):
        out.append(None if x is None else rgb[i:i + n])
        i += n
    return out


# Lightmaps baked per native call at most: the call holds about 60 bytes per texel while it runs.
BATCH_TEXELS = 1 << 21
# Texels baked but not yet stored in their images at most (28 bytes each: the texels and their EXR file)
# before the worker waits for the main thread: a bake of many large lightmaps holds a few of them at a time,
# not all.
AHEAD_TEXELS = 1 << 23


class _Job:
    """One object's write-back: what is read from it first, then what the batched native calls give."""
    __slots__ = ("name", "uv_name", "uv_created", "albedo", "reflects", "old", "record", "front", "front_rgb",
                 "positions", "uvs", "uv_outside", "shared", "pixels", "corners", "corner_rgb", "other_topology",
                 "two_sided", "exr")


def _gather(ob, dg, uv_name, uv_created, settings, reflects, albedo, copies=None, placements=None):
    """Everything the write-back needs of one object's evaluated mesh, from one evaluation of it; `copies`:
    the mesh whose UV map the lightmap of a modified surface uses (unwrap_copies)."""
    targets = settings["targets"]
    job = _Job()
    job.name, job.uv_name, job.uv_created, job.albedo, job.reflects = ob.name, uv_name, uv_created, albedo, reflects
    job.old = baked_state(ob)
    job.exr = None
    job.record = {"uv_map": uv_name, "uv_created": bool(uv_created or job.old.get("uv_created", False)) and
                  uv_name == UV_NAME, "irradiance": bool(settings.get("irradiance"))}
    if "LIGHTMAP" in targets:
        # The preview reads the lightmap UVs from this attribute of the evaluated mesh, if any.
        job.record["uv_attribute"] = COPIES_ATTRIBUTE if copies is not None else ""
        job.record["tiles"] = {}
        job.record["own_tile"] = []
    job.front = job.front_rgb = job.positions = job.uvs = job.pixels = job.corners = job.corner_rgb = None
    job.uv_outside, job.shared, job.other_topology = False, 0.0, False
    ob_eval = ob.evaluated_get(dg)
    matrix = np.array(ob_eval.matrix_world, np.float64)
    if placements:
        # (own, [(instancer, matrix)]): the first placement stands for the object in the side check and the
        # colour attribute, which all its instances share.
        own, inst = placements
        tiles = instance_tiles([n for n, _ in inst], own)
        mats = ([("", matrix)] if own else []) + [(n, np.asarray(m, np.float64)) for n, m in inst]
        matrix = mats[0][1]
    me = ob_eval.to_mesh()
    try:
        cache = _MeshCache(me, matrix)
        if reflects:
            # A black object reflects nothing whatever it receives, so its zero radiance says nothing of sides.
            job.front = _front_samples(me, matrix, cache)
        if "LIGHTMAP" in targets:
            job.positions, job.uvs = _lightmap_inputs(me, ob_eval.name, uv_name, matrix, cache, copies)
            uvs = job.uvs
            job.uv_outside = bool(len(uvs) and (uvs.min() < -1e-4 or uvs.max() > 1 + 1e-4))
            if placements:
                pos, tiled = [], []
                for n, m in mats:
                    p, uv = (job.positions, uvs) if m is matrix else _lightmap_inputs(me, ob_eval.name, uv_name, m)
                    ox, oy, s = tiles[n]
                    pos.append(p)
                    tiled.append(uv * np.float32(s) + np.array([ox, oy], np.float32))
                job.positions = np.ascontiguousarray(np.concatenate(pos), np.float32)
                job.uvs = np.ascontiguousarray(np.concatenate(tiled), np.float32)
                job.record["tiles"] = {n: list(t) for n, t in tiles.items() if n}
                job.record["own_tile"] = list(tiles[""]) if "" in tiles else []
        if "COLOR_ATTRIBUTE" in targets:
            base = ob.data
            if len(me.loops) == len(base.loops) and len(me.polygons) == len(base.polygons):
                job.corners = corner_samples(me, matrix, cache)
            else:
                job.other_topology = True
                job.corners = corner_samples(base, matrix)
    finally:
        ob_eval.to_mesh_clear()
    return job


class _LightmapBaker:
    """Bakes lightmaps in a worker thread while the main thread goes on with the Blender side: the native call
    releases the GIL and never touches bpy. Jobs come in chunks of at most BATCH_TEXELS texels (and 64 objects,
    so the first images can be stored while later ones bake); wait(job) returns once the job's chunk is baked,
    and the worker stays at most AHEAD_TEXELS ahead of the images stored."""

    def __init__(self, solution, res, margin, irradiance, native):
        import queue
        import threading
        self.args = (solution, res, margin, irradiance)
        self.native = native
        self.per = max(1, min(64, BATCH_TEXELS // (res * res)))
        self.pending = []
        self.queue = queue.Queue()
        self.error = None
        self.stop = False
        self.done = {}                 # id(job) -> threading.Event of its chunk
        self.ahead = 0                 # texels baked and not stored yet
        self.room = threading.Condition()
        self._event = threading.Event
        self.thread = threading.Thread(target=self._run, name="penumbra-lightmaps", daemon=True)
        self.thread.start()

    def add(self, job):
        self.pending.append(job)
        if len(self.pending) >= self.per:
            self.flush()

    def flush(self):
        if self.pending:
            ev = self._event()
            for j in self.pending:
                self.done[id(j)] = ev
            self.queue.put((self.pending, ev))
            self.pending = []

    def _run(self):
        solution, res, margin, irradiance = self.args
        while True:
            item = self.queue.get()
            if item is None:
                return
            chunk, ev = item
            texels = len(chunk) * res * res
            try:
                with self.room:
                    # Chunks are baked in the main thread's order of storing, so when it waits for this one
                    # every earlier one is stored and `ahead` is 0: this never waits for a waiting thread.
                    while self.ahead and self.ahead + texels > AHEAD_TEXELS and not self.stop:
                        self.room.wait()
                if not self.stop and self.error is None:
                    # A two-sided object is baked a second time with every triangle wound the other way,
                    # which the solver reads as its back side; the lightmap keeps the brighter of the two.
                    both = [j for j in chunk if getattr(j, "two_sided", False)]
                    bakes = chunk + both
                    pos = [j.positions for j in chunk] + [np.ascontiguousarray(j.positions[:, ::-1]) for j in both]
                    uvs = [j.uvs for j in chunk] + [np.ascontiguousarray(j.uvs[:, ::-1]) for j in both]
                    px = solution.bake_lightmaps(pos, uvs, res, res, margin,
                                                 irradiance=[irradiance or j.albedo is not None for j in bakes])
                    px = np.asarray(px)
                    if px.shape != (len(bakes), res, res, 4):
                        raise WritebackError(f"the solver returned lightmaps of shape {px.shape}, expected "
                                             f"{(len(bakes), res, res, 4)}")
                    for j, p in zip(chunk, px):
                        j.pixels = p
                    for j, p in zip(both, px[len(chunk):]):
                        j.pixels[..., :3] = np.maximum(j.pixels[..., :3], p[..., :3])
                    # The images' files are made here, beside the main thread, unless the albedo is to change
                    # the pixels first.
                    for j, exr in zip(chunk, self.native.exr_bytes(px[:len(chunk)])):
                        j.exr = exr if j.albedo is None else None
                    with self.room:
                        self.ahead += texels
            except BaseException as e:      # re-raised in the main thread by wait()
                self.error = e
            finally:
                ev.set()

    def wait(self, job):
        self.done[id(job)].wait()
        if self.error is not None:
            raise self.error

    def stored(self, job):
        """The job's lightmap is in its image: its texels no longer count against AHEAD_TEXELS."""
        res = self.args[1]
        with self.room:
            self.ahead -= res * res
            self.room.notify()

    def close(self):
        """Let the worker finish what it was given and end; after a failure elsewhere, nothing more is baked."""
        with self.room:
            self.room.notify()
        self.queue.put(None)
        self.thread.join()


def _write_attribute(ob, job, settings, tx, outputs):
    """The colour attribute of one object, under a temporary name until the commit."""
    rgb = job.corner_rgb
    pts = job.corners[0]
    if rgb.shape != (len(pts), 3) or not np.isfinite(rgb).all():
        raise WritebackError(f"object '{ob.name}': the solver returned invalid corner radiance")
    rgba = np.ones((len(pts), 4), np.float32)
    rgba[:, :3] = rgb
    base = ob.data
    attrs = base.color_attributes
    old_active = attrs.active_color.name if attrs.active_color else None
    old_render = attrs.keys()[attrs.render_color_index] if 0 <= attrs.render_color_index < len(attrs) \
        else None
    attr_name = _our_attribute(base, job.old)
    had_old = attr_name in base.attributes
    new_name = attr_name + ".penumbra-new" if had_old else attr_name
    ca = attrs.new(name=new_name, type="FLOAT_COLOR", domain="CORNER")
    ca_name, mesh_name = ca.name, base.name_full

    def drop(ca_name=ca_name, mesh_name=mesh_name):
        m = bpy.data.meshes.get(mesh_name)
        if m is not None and ca_name in m.attributes:
            m.attributes.remove(m.attributes[ca_name])
    tx.on_rollback(drop)
    ca.data.foreach_set("color", rgba.ravel())

    def swap_attr(ca_name=ca_name, mesh_name=mesh_name, had_old=had_old, old_active=old_active,
                  old_render=old_render, attr_name=attr_name):
        m = tx.index("meshes", "name_full")[mesh_name]
        if had_old and ca_name != attr_name:
            m.attributes.remove(m.attributes[attr_name])
            m.attributes[ca_name].name = attr_name
        a = m.color_attributes
        keys = a.keys()
        # Keep the user's active and render color attributes; the preview names ours explicitly.
        if old_active and old_active in keys:
            a.active_color = a[old_active]
        if old_render and old_render in keys:
            a.render_color_index = keys.index(old_render)
    tx.on_commit(swap_attr)
    job.record["attribute"] = attr_name
    outputs["attribute"] = attr_name


def _warnings(ob, job, targets, report):
    """The object's warnings, in the order a write-back object by object gave them."""
    if job.front is not None:
        w = _front_warning(ob.name, job.front[2], job.front_rgb)
        if w:
            report["warnings"].append(w)
    if "LIGHTMAP" in targets:
        if job.uv_outside:
            report["warnings"].append(f"object '{ob.name}': UV map '{job.uv_name}' leaves the [0, 1] square; "
                                      f"texels outside it are lost")
        if job.shared > OVERLAP_WARN:
            mods = [m.name for m in ob.modifiers if m.type in ("ARRAY", "MIRROR") and m.show_render]
            why = (f" (its modifier(s) {', '.join(mods)} copy faces onto the same UVs)" if mods else "")
            report["warnings"].append(
                f"object '{ob.name}': {100 * job.shared:.0f} % of its lightmap texels are shared by overlapping "
                f"faces of UV map '{job.uv_name}'{why}; those faces show one light in the lightmap, which is wrong "
                f"for all but one of them: apply the modifiers, or give every face its own UV space")
    if "COLOR_ATTRIBUTE" in targets and job.other_topology:
        # Not "the lightmap follows the modified surface" when the modifier's copies share texels:
        # then neither target is right for the copies, and the overlap warning says so.
        follows = "" if job.shared > OVERLAP_WARN or "LIGHTMAP" not in targets else \
            " (the lightmap follows the modified surface)"
        report["warnings"].append(
            f"object '{ob.name}': modifiers change the topology, so the colour attribute holds the "
            f"light of the mesh before its modifiers, and the faces they add show that light too"
            f"{follows}")


def _write_lightmap(ob, job, native, settings, tx, files, outputs, images):
    """The lightmap image (and file) of one object, under temporary names until the commit.

    With `job.albedo` (the object's albedo per lightmap texel, albedo.py, for a material whose colour varies)
    the lightmap is the solver's irradiance times that albedo. With settings["irradiance"] every target holds
    the irradiance E/pi without any albedo."""
    res = settings["resolution"]
    irradiance = bool(settings.get("irradiance"))
    record, old, albedo = job.record, job.old, job.albedo
    px = job.pixels
    if px is None or px.shape != (res, res, 4):
        raise WritebackError(f"object '{ob.name}': the solver returned a lightmap of shape "
                             f"{None if px is None else px.shape}, expected {(res, res, 4)}")
    if albedo is not None and not irradiance:
        if albedo.shape != (res, res, 3):
            raise WritebackError(f"object '{ob.name}': albedo bake of shape {albedo.shape}, expected "
                                 f"{(res, res, 3)}")
        # Cycles' diffuse colour at each texel times the light arriving there: what its DIFFUSE bake with
        # Direct + Indirect + Color holds, texel by texel.
        px[:, :, :3] *= np.maximum(albedo, 0.0)
    if not np.isfinite(px).all():
        raise WritebackError(f"object '{ob.name}': the solver returned non-finite lightmap texels")
    final = IMAGE_PREFIX + ob.name
    old_img = images.get(old.get("image", "")) if old.get("image") else None
    if old_img is not None and not old_img.get("penumbra"):
        old_img = None            # the name was reused by an image that is not ours: leave it alone
    img = bpy.data.images.new(final if old_img is None else final + ".penumbra-new", res, res,
                              alpha=False, float_buffer=True)
    img_name = img.name
    images.setdefault(img_name, img)
    tx.on_rollback(lambda n=img_name: bpy.data.images.remove(bpy.data.images[n])
                   if n in bpy.data.images else None)
    # The worker encoded the file already unless the albedo changed the pixels since.
    store_pixels(img, px, native, job.exr if albedo is None else None)
    img.use_fake_user = True   # kept in the .blend even when no material shows it
    img["penumbra"] = True
    if settings.get("output_dir"):
        path = os.path.join(settings["output_dir"], _safe_filename(final) + ".exr")
        if path in files.values():
            raise WritebackError(f"object '{ob.name}': two objects would write the lightmap file {path}")
        # The writer picks the format by the extension, so the temporary name ends in .exr too.
        tmp = f"{path[:-4]}.{uuid.uuid4().hex[:8]}.tmp.exr"
        files[tmp] = path
        tx.on_rollback(lambda tmp=tmp: os.path.exists(tmp) and os.remove(tmp))
        native.write_exr(tmp, np.ascontiguousarray(px))
        outputs["exr"] = path

    def swap(img_name=img_name, final=final, old_name=old_img.name if old_img else None):
        images = tx.index("images")
        new = images[img_name]
        if old_name and old_name in images:
            o = images[old_name]
            # Remapping and removing each walk every data-block of the file, so doing both for every
            # object made a re-bake quadratic: remap only an image something uses besides its fake user,
            # and remove the old images together after the last swap.
            if o.users > int(o.use_fake_user):
                o.user_remap(new)
            o.name = old_name + ".penumbra-old"
            tx.renamed("images", old_name, o)
            tx.discard(o)
        # Renaming onto a taken name renames the other data-block in Blender 3.4; a user's image keeps
        # its name and ours keeps the suffixed one.
        want = final if final not in images else old_name
        if want and new.name != want and want not in images:
            was = new.name
            new.name = want
            tx.renamed("images", was, new)
        # Blender may have had to pick another name (an unrelated image already called `final`).
        record["image"] = outputs["image"] = new.name
    tx.on_commit(swap)
    record["image"] = outputs["image"] = img_name


def _record(ob, job, tx):
    """What this bake made, on the object's custom property, at the commit."""
    old = job.old
    old_prop = ob.get(PROP)
    old_prop = old_prop.to_dict() if hasattr(old_prop, "to_dict") else old_prop
    ob_name = ob.name

    def restore_prop(ob_name=ob_name, old_prop=old_prop):
        o = bpy.data.objects.get(ob_name)
        if o is None:
            return
        if old_prop is None:
            o.pop(PROP, None)
        else:
            o[PROP] = old_prop
    tx.on_rollback(restore_prop)

    def set_prop(ob_name=ob_name, record=job.record, old=old):
        o = tx.index("objects")[ob_name]
        # Keep what an earlier bake made for a target this bake did not write.
        merged = dict(old)
        merged.update(record)
        o[PROP] = merged
    tx.on_commit(set_prop)


def _tile_props(ob, job, tx):
    """At the commit: each instancing empty (and the object, when rendered) gets its tile's TILE_PROP; the
    empties an earlier bake gave one and this one does not lose it."""
    ob_name, tiles, own, old = ob.name, job.record["tiles"], job.record["own_tile"], job.old.get("tiles", {})

    def set_props():
        objs = tx.index("objects")
        for n in set(old) - set(tiles):
            o = objs.get(n)
            if o is not None and o.library is None:
                o.pop(TILE_PROP, None)
        for n, t in tiles.items():
            objs[n][TILE_PROP] = t
        o = objs[ob_name]
        if own:
            o[TILE_PROP] = own
        else:
            o.pop(TILE_PROP, None)
    if tiles or old or ob.get(TILE_PROP) is not None:
        tx.on_commit(set_props)


def write_objects(objs, names, solution, native, dg, uv, settings, tx, report, files, black=frozenset(),
                  albedo_maps=None, progress=None, copies=None, two_sided=frozenset(), instances=None,
                  instance_only=frozenset()):
    """Rasterise and store the objects' bakes; {name: outputs}. Nothing here replaces earlier results: that
    is the commit.

    So that the cost per object is Blender's own: each object's evaluated mesh is read once, and its lightmap
    goes to a worker thread that bakes them in chunks over all the cores (_LightmapBaker) while the main thread
    reads the next objects, measures the UV overlaps (one native call), takes the corner and front-side
    radiance (one call each) and writes the colour attributes; last, each object's image is made and packed as
    soon as its chunk is baked. Every value is the one an object-by-object write-back gives
    (blender_tests/test_writeback_scaling.py)."""
    targets = settings["targets"]
    irradiance = bool(settings.get("irradiance"))
    albedo_maps = albedo_maps or {}
    copies = copies or {}
    n = max(len(names), 1)
    images = {}
    for img in bpy.data.images:
        images.setdefault(img.name, img)

    def step(frac):
        if progress is not None:
            progress("write-back", frac)
    jobs = []
    baker = _LightmapBaker(solution, settings["resolution"], settings["margin"], irradiance, native) \
        if "LIGHTMAP" in targets else None
    try:
        for i, name in enumerate(names):
            step(0.3 * i / n)
            job = _gather(objs[name], dg, uv[name][0], uv[name][1], settings, reflects=name not in black,
                          albedo=albedo_maps.get(name), copies=copies.get(name, (None,))[0],
                          placements=(name not in instance_only, instances[name])
                          if instances and name in instances else None)
            job.two_sided = name in two_sided
            if job.two_sided:
                job.front = None         # both sides are lit: no side to warn about
            jobs.append(job)
            if baker is not None:
                baker.add(job)
        if baker is not None:
            baker.flush()
            lit = [j for j in jobs if j.uvs is not None]
            for j, shared in zip(lit, native.uv_overlaps([j.uvs for j in lit], min(settings["resolution"], 256))):
                j.shared = float(shared)
        for j, rgb in zip(jobs, _radiance_of_all(solution, [j.front[:2] if j.front is not None else None
                                                            for j in jobs])):
            j.front_rgb = rgb
        outputs = {j.name: {} for j in jobs}
        if "COLOR_ATTRIBUTE" in targets:
            for j, rgb in zip(jobs, _radiance_of_all(solution, [j.corners for j in jobs], irradiance=irradiance)):
                j.corner_rgb = rgb
            both = [j for j in jobs if j.two_sided]
            flipped = [(j.corners[0], np.ascontiguousarray(-j.corners[1])) for j in both]
            for j, rgb in zip(both, _radiance_of_all(solution, flipped, irradiance=irradiance)):
                j.corner_rgb = np.maximum(j.corner_rgb, rgb)     # the brighter side, as for the lightmap
            for i, j in enumerate(jobs):
                step(0.3 + 0.2 * i / n)
                _write_attribute(objs[j.name], j, settings, tx, outputs[j.name])
        for i, j in enumerate(jobs):
            step(0.5 + 0.5 * i / n)
            ob = objs[j.name]
            _warnings(ob, j, targets, report)
            if baker is not None:
                baker.wait(j)
                _write_lightmap(ob, j, native, settings, tx, files, outputs[j.name], images)
                baker.stored(j)
            _record(ob, j, tx)
            if "LIGHTMAP" in targets:
                _tile_props(ob, j, tx)
            j.pixels = j.exr = j.positions = j.uvs = j.corners = None     # the memory goes once it is stored
    finally:
        if baker is not None:
            baker.stop = True        # on a failure: what is still queued is not baked
            baker.close()
    return outputs


def _uv_survives(ob, dg, uv_name):
    ob_eval = ob.evaluated_get(dg)
    me = ob_eval.to_mesh()
    try:
        return uv_name in me.uv_layers
    finally:
        ob_eval.to_mesh_clear()


class _active_scene:
    """Make `scene` the window's scene meanwhile: the unwrap runs edit-mode operators, whose polls look at
    the window's scene, so baking a scene that is not the active one would fail only after the solve."""

    def __init__(self, scene, view_layer):
        self.scene, self.vl, self.saved = scene, view_layer, None

    def __enter__(self):
        win = bpy.context.window
        if win is not None and win.scene != self.scene:
            self.saved = (win.scene, win.view_layer)
            win.scene = self.scene
            win.view_layer = self.vl
        return self

    def __exit__(self, *exc):
        if self.saved is not None:
            win = bpy.context.window
            scene, vl = self.saved
            win.scene = scene
            win.view_layer = vl
        return False


def write_all(scene, view_layer, object_names, solution, native, settings, report, progress=None,
              before_commit=None, black=(), two_sided=(), instances=None, instance_only=()):
    """`black`: names of objects whose every face has albedo 0 (no side check for them). `two_sided`: names
    of objects lit on both sides; their lightmap and colours hold the brighter side, per texel and corner."""
    with _active_scene(scene, view_layer):
        return _write_all(scene, view_layer, object_names, solution, native, settings, report, progress,
                          before_commit, frozenset(black), frozenset(two_sided), instances or {},
                          frozenset(instance_only))


def _evaluated_depsgraph(scene, view_layer):
    """The scene's depsgraph with its evaluated objects up to date: the unwrap and Cycles' albedo bake change
    the scene, after which objects evaluated before are stale."""
    if bpy.context.scene == scene:
        return bpy.context.evaluated_depsgraph_get()
    view_layer.update()
    return view_layer.depsgraph


def _write_all(scene, view_layer, object_names, solution, native, settings, report, progress, before_commit,
               black, two_sided=frozenset(), instances=None, instance_only=frozenset()):
    """Unwrap, rasterise and store every baked object; all or nothing, on disk too: lightmap files are
    written under temporary names and moved into place only at the commit. `before_commit(outputs)` runs
    last before the commit; whatever it raises rolls everything back."""
    tx = Transaction()
    outputs = {}
    files = {}                     # temporary file -> final path
    try:
        out_dir = settings.get("output_dir")
        if out_dir:
            missing = []
            d = os.path.abspath(out_dir)
            while not os.path.isdir(d):
                missing.append(d)
                parent = os.path.dirname(d)
                if parent == d:
                    break
                d = parent
            os.makedirs(out_dir, exist_ok=True)
            # Undo the folders this bake created, deepest first (they are empty again after the temporary
            # files went).
            for d in reversed(missing):
                tx.on_rollback(lambda d=d: os.path.isdir(d) and not os.listdir(d) and os.rmdir(d))
        objs = {}
        for o in bpy.data.objects:        # one walk; bpy.data.objects[name] walks them all for every name
            objs.setdefault(o.name, o)
        uv = prepare_uvs([objs[n] for n in object_names], scene, view_layer,
                         settings.get("uv_map"), tx)
        dg = _evaluated_depsgraph(scene, view_layer)
        baked = []
        for name in object_names:
            ob = objs[name]
            if "LIGHTMAP" in settings["targets"] and not _uv_survives(ob, dg, uv[name][0]):
                # One object's modifiers (geometry nodes, typically) dropping the UV map must not sink the
                # whole bake: that object gets no lightmap and the report says why.
                reason = (f"not baked: its modifiers do not keep the UV map '{uv[name][0]}' (geometry nodes "
                          f"that build new geometry drop it); it still casts and reflects light")
                report["skipped"].append({"name": name, "reason": reason})
                report["warnings"].append(f"object '{name}': {reason}")
                if uv[name][1]:
                    mesh = ob.data
                    mesh.uv_layers.remove(mesh.uv_layers[uv[name][0]])
                continue
            baked.append(name)
        copies = {}
        if "LIGHTMAP" in settings["targets"] and not settings.get("uv_map"):
            for name in find_copies(objs, [n for n in baked if n not in (instances or {})], dg, uv, native,
                                    settings["resolution"]):
                copies[name] = unwrap_copies(objs[name], dg, scene, view_layer, tx)
                report["notes"].append(
                    f"object '{name}': its modifiers copy faces onto the same lightmap UVs, so the lightmap uses "
                    f"a UV layout made for its modified surface (mesh '{copies[name][0].name}'), which the "
                    f"Geometry Nodes modifier '{COPIES_MODIFIER}' appended to it stores in the corner attribute "
                    f"'{COPIES_ATTRIBUTE}' for the preview and your materials (an Attribute node)")
        for name in baked:
            if "LIGHTMAP" in settings["targets"]:
                if name in copies:
                    attach_copies(objs[name], copies[name][1], tx)
                else:
                    detach_copies(objs[name], tx)
        if copies:
            # The unwrap linked and unlinked an object: the evaluated objects are taken anew.
            dg = _evaluated_depsgraph(scene, view_layer)
        tiled = set(instances or {}) if "LIGHTMAP" in settings["targets"] else set()
        albedo_maps = _albedo_maps(scene, view_layer, [n for n in baked if n not in copies and n not in tiled], uv,
                                   settings, report, objs)
        for n in list(copies) + [n for n in baked if n in tiled]:
            from . import albedo
            if albedo.needs_bake(objs[n]) and not settings.get("irradiance"):
                report["warnings"].append(f"object '{n}': albedo averaged: its material's colour varies across the "
                                          f"surface, but its lightmap is laid out for its modifier copies or "
                                          f"its instances, which Cycles' albedo bake cannot follow; the lightmap "
                                          f"uses the material's mean albedo")
        if albedo_maps:
            # The bake operator re-evaluated the scene; the depsgraph's evaluated objects are taken anew.
            dg = _evaluated_depsgraph(scene, view_layer)
        outputs.update(write_objects(objs, baked, solution, native, dg, uv, settings, tx, report, files, black=black,
                                     albedo_maps=albedo_maps, progress=progress, copies=copies,
                                     two_sided=two_sided, instances=instances, instance_only=instance_only))
        if before_commit is not None:
            before_commit(baked, outputs)
        for tmp, path in files.items():
            os.replace(tmp, path)
        tx.commit()
    except BaseException:
        errors = tx.rollback()
        for tmp in files:
            if os.path.exists(tmp):
                try:
                    os.remove(tmp)
                except OSError as e:
                    errors.append(str(e))
        if errors:
            report["warnings"].append("rollback incomplete: " + "; ".join(errors))
        raise
    return outputs


def _albedo_maps(scene, view_layer, names, uv, settings, report, objs):
    """The per-texel albedo of the objects whose material colour varies (albedo.py), and a word in the report
    for every such object whose light is not followed texel by texel somewhere."""
    from . import albedo
    textured = [n for n in names if albedo.needs_bake(objs[n])]
    if not textured or settings.get("irradiance"):
        return {}
    jobs = {}
    for n in textured:
        if "LIGHTMAP" not in settings["targets"]:
            report["warnings"].append(f"object '{n}': albedo averaged: its material's colour varies across the "
                                      f"surface (a texture), and the colour attribute holds the light with the "
                                      f"material's mean albedo; bake a lightmap to follow it per texel")
            continue
        why = albedo.why_not(objs[n])
        if why:
            report["warnings"].append(f"object '{n}': albedo averaged: its material's colour varies across the "
                                      f"surface, but Cycles cannot bake it ({why}); the lightmap uses the "
                                      f"material's mean albedo")
            continue
        jobs[n] = (uv[n][0], settings["resolution"])
        if "COLOR_ATTRIBUTE" in settings["targets"]:
            report["warnings"].append(f"object '{n}': albedo averaged in the colour attribute (per corner, with "
                                      f"the material's mean albedo); the lightmap follows the texture per texel")
    maps, seconds = albedo.bake_albedo(scene, view_layer, jobs, settings["margin"])
    if jobs:
        report["times"]["albedo_bake"] = seconds
        report["notes"].append(f"albedo followed per texel (Cycles Color bake, {seconds:.2f} s) for: "
                               f"{', '.join(jobs)}; their bounced light uses each material's mean albedo")
    return maps


def remove_bake(ob):
    """Remove what bakes made on one object (image, attribute, the UV map if a bake created it)."""
    state = baked_state(ob)
    if not state:
        return False
    img = bpy.data.images.get(state.get("image", "")) if state.get("image") else None
    if img is not None:
        bpy.data.images.remove(img)
    me = ob.data
    if state.get("attribute") and state["attribute"] in me.attributes:
        me.attributes.remove(me.attributes[state["attribute"]])
    if state.get("uv_created") and state.get("uv_map") in me.uv_layers:
        me.uv_layers.remove(me.uv_layers[state["uv_map"]])
    for n in state.get("tiles", {}):
        o = bpy.data.objects.get(n)
        if o is not None and o.library is None:
            o.pop(TILE_PROP, None)
    ob.pop(TILE_PROP, None)
    gone = []
    _drop_copies_modifiers(ob, gone.append)
    if gone:
        bpy.data.batch_remove(gone)
    del ob[PROP]
    return True


def remove_orphan_images():
    """Remove the lightmap images Penumbra made whose object no longer records them (deleted objects leave
    them behind, packed and fake-used). A user's image is never marked, so it is never removed."""
    kept = {baked_state(ob).get("image") for ob in bpy.data.objects}
    removed = []
    for img in list(bpy.data.images):
        if img.get("penumbra") and img.name not in kept and img.library is None:
            removed.append(img.name)
            bpy.data.images.remove(img)
    return removed

"""Writing a solved bake back into the .blend: lightmap UV maps, float lightmap images, CORNER color attributes.

The write-back is a transaction. Every change is recorded with a way to undo it; anything that can fail
(unwrapping, rasterising, writing files) happens before the commit, which only swaps the new data for what an
earlier bake made. On any exception the recorded changes are undone in reverse order, so the .blend is left as
it was before the bake.
"""
import math
import os

import bpy
import numpy as np

UV_NAME = "PenumbraLightmap"
ATTRIBUTE = "Penumbra"
IMAGE_PREFIX = "Penumbra_"
PROP = "penumbra"            # custom property on a baked object: what the last bake made


class WritebackError(RuntimeError):
    pass


class Transaction:
    def __init__(self):
        self._undo = []
        self._commit = []

    def on_rollback(self, fn):
        self._undo.append(fn)

    def on_commit(self, fn):
        self._commit.append(fn)

    def commit(self):
        for fn in self._commit:
            fn()
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
        self.selected = [o.name for o in view_layer.objects if o.select_get(view_layer=view_layer)]
        self.active = view_layer.objects.active.name if view_layer.objects.active else None

    def restore(self):
        objs = self.vl.objects
        for o in objs:
            o.select_set(o.name in self.selected, view_layer=self.vl)
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


def prepare_uv(ob, scene, view_layer, uv_setting, tx):
    """Return the lightmap UV map's name for `ob`, unwrapping PenumbraLightmap unless the user named one."""
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
    sel = _SelectionState(view_layer)
    try:
        for o in view_layer.objects:
            o.select_set(False, view_layer=view_layer)
        ob.select_set(True, view_layer=view_layer)
        view_layer.objects.active = ob
        with bpy.context.temp_override(scene=scene, view_layer=view_layer, active_object=ob, object=ob):
            bpy.ops.object.mode_set(mode="EDIT")
            try:
                bpy.ops.mesh.reveal(select=False)
                bpy.ops.mesh.select_all(action="SELECT")
                # Smart project keeps whole coplanar regions in one island (blender-facts §4), so bilinear
                # lookups do not show seams at every face.
                bpy.ops.uv.smart_project(angle_limit=math.radians(66.0), island_margin=0.02, area_weight=0.0,
                                         correct_aspect=True, scale_to_bounds=False)
            finally:
                bpy.ops.object.mode_set(mode="OBJECT")
    finally:
        sel.restore()
        _restore_element_flags(me, flags)
        if old_active and old_active in layers:
            layers.active = layers[old_active]
        if old_render and old_render in layers:
            layers[old_render].active_render = True
    return UV_NAME, created


# ---------------------------------------------------------------------------------------------- sampling

def _world_loop_triangles(me, matrix):
    me.calc_loop_triangles()
    n_tri = len(me.loop_triangles)
    co = _get(me.vertices, "co", len(me.vertices), np.float32, 3).astype(np.float64)
    co_w = co @ matrix[:3, :3].T + matrix[:3, 3]
    tri_v = _get(me.loop_triangles, "vertices", n_tri, np.int32, 3)
    tri_l = _get(me.loop_triangles, "loops", n_tri, np.int32, 3)
    return co_w, tri_v, tri_l


def lightmap_inputs(ob_eval, uv_name, matrix):
    """World-space corners (T,3,3) and UVs (T,3,2) of the evaluated mesh's loop triangles."""
    me = ob_eval.to_mesh()
    try:
        if uv_name not in me.uv_layers:
            raise WritebackError(f"object '{ob_eval.name}': the UV map '{uv_name}' does not survive its "
                                 f"modifiers")
        co_w, tri_v, tri_l = _world_loop_triangles(me, matrix)
        uv = _get(me.uv_layers[uv_name].data, "uv", len(me.loops), np.float32, 2)
        positions = np.ascontiguousarray(co_w[tri_v], np.float32)
        uvs = np.ascontiguousarray(uv[tri_l], np.float32)
    finally:
        ob_eval.to_mesh_clear()
    return positions, uvs


def corner_samples(me, matrix):
    """World position of every corner and the world normal of its face, for a mesh in its own loop order."""
    n_loops, n_poly = len(me.loops), len(me.polygons)
    co = _get(me.vertices, "co", len(me.vertices), np.float32, 3).astype(np.float64)
    co_w = co @ matrix[:3, :3].T + matrix[:3, 3]
    lv = _get(me.loops, "vertex_index", n_loops, np.int32)
    loop_total = _get(me.polygons, "loop_total", n_poly, np.int32)
    pn = _get(me.polygons, "normal", n_poly, np.float32, 3).astype(np.float64)
    # Normals transform with the inverse transpose.
    nw = pn @ np.linalg.inv(matrix[:3, :3])
    nw /= np.maximum(np.linalg.norm(nw, axis=1, keepdims=True), 1e-30)
    loop_poly = np.repeat(np.arange(n_poly), loop_total)
    return (np.ascontiguousarray(co_w[lv], np.float32), np.ascontiguousarray(nw[loop_poly], np.float32))


# ---------------------------------------------------------------------------------------------- writing

def _safe_filename(name):
    return "".join(c if c.isalnum() or c in "-_." else "_" for c in name)


def write_object(ob, solution, native, dg, uv_name, uv_created, settings, tx, report):
    """Rasterise and store one object's bake. Nothing here replaces earlier results: that is the commit."""
    targets = settings["targets"]
    res, margin = settings["resolution"], settings["margin"]
    ob_eval = ob.evaluated_get(dg)
    matrix = np.array(ob_eval.matrix_world, np.float64)
    old = baked_state(ob)
    record = {"uv_map": uv_name, "uv_created": bool(uv_created or old.get("uv_created", False)) and
              uv_name == UV_NAME}
    outputs = {}

    if "LIGHTMAP" in targets:
        positions, uvs = lightmap_inputs(ob_eval, uv_name, matrix)
        if len(uvs) and (uvs.min() < -1e-4 or uvs.max() > 1 + 1e-4):
            report["warnings"].append(f"object '{ob.name}': UV map '{uv_name}' leaves the [0, 1] square; "
                                      f"texels outside it are lost")
        px = solution.bake_lightmap(positions, uvs, res, res, margin)
        px = np.ascontiguousarray(px, np.float32)
        if px.shape != (res, res, 4):
            raise WritebackError(f"object '{ob.name}': the solver returned a lightmap of shape {px.shape}, "
                                 f"expected {(res, res, 4)}")
        if not np.isfinite(px).all():
            raise WritebackError(f"object '{ob.name}': the solver returned non-finite lightmap texels")
        final = IMAGE_PREFIX + ob.name
        old_img = bpy.data.images.get(old.get("image", "")) if old.get("image") else None
        img = bpy.data.images.new(final if old_img is None else final + ".penumbra-new", res, res,
                                  alpha=False, float_buffer=True)
        img_name = img.name
        tx.on_rollback(lambda n=img_name: bpy.data.images.remove(bpy.data.images[n])
                       if n in bpy.data.images else None)
        img.pixels.foreach_set(px.ravel())
        img.update()
        img.pack()                 # float32 EXR inside the .blend; exact with alpha off (blender-facts §3)
        img.use_fake_user = True   # kept in the .blend even when no material shows it
        img["penumbra"] = True
        if settings.get("output_dir"):
            path = os.path.join(settings["output_dir"], _safe_filename(final) + ".exr")
            native.write_exr(path, px)
            outputs["exr"] = path

        def swap(img_name=img_name, final=final, old_name=old_img.name if old_img else None):
            new = bpy.data.images[img_name]
            if old_name and old_name in bpy.data.images:
                o = bpy.data.images[old_name]
                o.user_remap(new)
                bpy.data.images.remove(o)
            if new.name != final:
                new.name = final
            # Blender may have had to pick another name (an unrelated image already called `final`).
            record["image"] = outputs["image"] = new.name
        tx.on_commit(swap)
        record["image"] = outputs["image"] = img_name

    if "COLOR_ATTRIBUTE" in targets:
        base = ob.data
        me_eval = ob_eval.to_mesh()
        try:
            if len(me_eval.loops) == len(base.loops) and len(me_eval.polygons) == len(base.polygons):
                pts, nrm = corner_samples(me_eval, matrix)
            else:
                report["warnings"].append(
                    f"object '{ob.name}': modifiers change the topology, so the '{ATTRIBUTE}' attribute is "
                    f"computed on the base mesh (the lightmap follows the modified surface)")
                pts, nrm = corner_samples(base, matrix)
        finally:
            ob_eval.to_mesh_clear()
        rgb = np.asarray(solution.radiance(pts, nrm), np.float32)
        if rgb.shape != (len(pts), 3) or not np.isfinite(rgb).all():
            raise WritebackError(f"object '{ob.name}': the solver returned invalid corner radiance")
        rgba = np.ones((len(pts), 4), np.float32)
        rgba[:, :3] = rgb
        attrs = base.color_attributes
        old_active = attrs.active_color.name if attrs.active_color else None
        old_render = attrs.keys()[attrs.render_color_index] if 0 <= attrs.render_color_index < len(attrs) \
            else None
        had_old = ATTRIBUTE in base.attributes
        new_name = ATTRIBUTE + ".penumbra-new" if had_old else ATTRIBUTE
        ca = attrs.new(name=new_name, type="FLOAT_COLOR", domain="CORNER")
        ca_name, mesh_name = ca.name, base.name_full

        def drop(ca_name=ca_name, mesh_name=mesh_name):
            m = bpy.data.meshes.get(mesh_name)
            if m is not None and ca_name in m.attributes:
                m.attributes.remove(m.attributes[ca_name])
        tx.on_rollback(drop)
        ca.data.foreach_set("color", rgba.ravel())

        def swap_attr(ca_name=ca_name, mesh_name=mesh_name, had_old=had_old, old_active=old_active,
                      old_render=old_render):
            m = bpy.data.meshes[mesh_name]
            if had_old and ca_name != ATTRIBUTE:
                m.attributes.remove(m.attributes[ATTRIBUTE])
                m.attributes[ca_name].name = ATTRIBUTE
            a = m.color_attributes
            keys = a.keys()
            # Keep the user's active and render color attributes; the preview names ours explicitly.
            if old_active and old_active in keys:
                a.active_color = a[old_active]
            if old_render and old_render in keys:
                a.render_color_index = keys.index(old_render)
        tx.on_commit(swap_attr)
        record["attribute"] = ATTRIBUTE
        outputs["attribute"] = ATTRIBUTE

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

    def set_prop(ob_name=ob_name, record=record, old=old):
        o = bpy.data.objects[ob_name]
        # Keep what an earlier bake made for a target this bake did not write.
        merged = dict(old)
        merged.update(record)
        o[PROP] = merged
    tx.on_commit(set_prop)
    return outputs


def write_all(scene, view_layer, object_names, solution, native, settings, report, progress=None):
    """Unwrap, rasterise and store every baked object; all or nothing."""
    tx = Transaction()
    outputs = {}
    try:
        uv = {}
        for name in object_names:
            ob = bpy.data.objects[name]
            uv[name] = prepare_uv(ob, scene, view_layer, settings.get("uv_map"), tx)
        if bpy.context.scene == scene:
            dg = bpy.context.evaluated_depsgraph_get()
        else:
            view_layer.update()
            dg = view_layer.depsgraph
        for i, name in enumerate(object_names):
            if progress is not None:
                progress("write-back", i / max(len(object_names), 1))
            ob = bpy.data.objects[name]
            outputs[name] = write_object(ob, solution, native, dg, uv[name][0], uv[name][1], settings, tx,
                                         report)
        tx.commit()
    except BaseException:
        errors = tx.rollback()
        if errors:
            report["warnings"].append("rollback incomplete: " + "; ".join(errors))
        raise
    return outputs


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
    del ob[PROP]
    return True

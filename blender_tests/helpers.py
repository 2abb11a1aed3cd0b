"""Scene builders and analytic answers shared by the tests."""
import math

import bpy
import numpy as np


def diffuse_material(name, color):
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    nt = mat.node_tree
    nt.nodes.clear()
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    bsdf = nt.nodes.new("ShaderNodeBsdfDiffuse")
    bsdf.inputs["Color"].default_value = (*color, 1.0)
    nt.links.new(bsdf.outputs["BSDF"], out.inputs["Surface"])
    return mat


def emission_material(name, color, strength):
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    nt = mat.node_tree
    nt.nodes.clear()
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    em = nt.nodes.new("ShaderNodeEmission")
    em.inputs["Color"].default_value = (*color, 1.0)
    em.inputs["Strength"].default_value = strength
    nt.links.new(em.outputs["Emission"], out.inputs["Surface"])
    return mat


def quad_object(name, half_x, half_y, z=0.0, material=None, flip=False, cuts=1):
    """A horizontal quad grid centred on the origin; its normal is +Z (or -Z with flip)."""
    xs = np.linspace(-half_x, half_x, cuts + 1)
    ys = np.linspace(-half_y, half_y, cuts + 1)
    verts = [(x, y, z) for y in ys for x in xs]
    faces = []
    for j in range(cuts):
        for i in range(cuts):
            a = j * (cuts + 1) + i
            f = (a, a + 1, a + cuts + 2, a + cuts + 1)
            faces.append(tuple(reversed(f)) if flip else f)
    me = bpy.data.meshes.new(name)
    me.from_pydata(verts, [], faces)
    if material is not None:
        me.materials.append(material)
    ob = bpy.data.objects.new(name, me)
    bpy.context.scene.collection.objects.link(ob)
    return ob


def area_light(name, shape, size, size_y=None, energy=100.0, color=(1, 1, 1), location=(0, 0, 1),
               rotation=(0, 0, 0), scale=(1, 1, 1)):
    light = bpy.data.lights.new(name, "AREA")
    light.shape = shape
    light.size = size
    if size_y is not None:
        light.size_y = size_y
    light.energy = energy
    light.color = color
    ob = bpy.data.objects.new(name, light)
    ob.location = location
    ob.rotation_euler = rotation
    ob.scale = scale
    bpy.context.scene.collection.objects.link(ob)
    return ob


def lambert_irradiance_factor(polygon, points, normals):
    """Sum over edges of Lambert's formula: E = L * factor for a polygon of uniform radiance L.

    polygon (k, 3), points and normals (N, 3). Exact for any planar polygon above each point's horizon."""
    acc = np.zeros(len(points))
    k = len(polygon)
    for i in range(k):
        r0 = polygon[i][None, :] - points
        r1 = polygon[(i + 1) % k][None, :] - points
        c = np.cross(r0, r1)
        cn = np.linalg.norm(c, axis=1)
        gamma = np.arctan2(cn, np.einsum("ij,ij->i", r0, r1))
        acc += gamma * np.einsum("ij,ij->i", normals, c) / np.maximum(cn, 1e-300)
    return np.abs(0.5 * acc)


def ellipse_polygon(matrix, sx, sy, n=4096):
    t = 2 * math.pi * np.arange(n) / n
    local = np.stack([sx / 2 * np.cos(t), sy / 2 * np.sin(t), np.zeros(n), np.ones(n)], axis=1)
    return (local @ np.asarray(matrix).T)[:, :3]


def rect_polygon(matrix, sx, sy):
    local = np.array([[-sx / 2, -sy / 2, 0, 1], [sx / 2, -sy / 2, 0, 1], [sx / 2, sy / 2, 0, 1],
                      [-sx / 2, sy / 2, 0, 1]], float)
    return (local @ np.asarray(matrix).T)[:, :3]


def polygon_area(p):
    s = np.zeros(3)
    for i in range(len(p)):
        s += np.cross(p[i], p[(i + 1) % len(p)])
    return 0.5 * np.linalg.norm(s)


def texel_world_positions(ob, uv_name, w, h):
    """World position of every texel centre covered by the mesh's UV triangles; (mask (h,w), pos (h,w,3))."""
    me = ob.data
    me.calc_loop_triangles()
    uv = np.empty(len(me.loops) * 2, np.float32)
    me.uv_layers[uv_name].data.foreach_get("uv", uv)
    uv = uv.reshape(-1, 2).astype(np.float64)
    co = np.empty(len(me.vertices) * 3, np.float32)
    me.vertices.foreach_get("co", co)
    m = np.array(ob.matrix_world)
    co = co.reshape(-1, 3) @ m[:3, :3].T + m[:3, 3]
    mask = np.zeros((h, w), bool)
    pos = np.zeros((h, w, 3))
    px, py = np.meshgrid((np.arange(w) + 0.5) / w, (np.arange(h) + 0.5) / h)
    for t in me.loop_triangles:
        a, b, c = (uv[l] for l in t.loops)
        pa, pb, pc = (co[v] for v in t.vertices)
        det = (b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1])
        if abs(det) < 1e-14:
            continue
        l1 = ((px - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (py - a[1])) / det
        l2 = ((b[0] - a[0]) * (py - a[1]) - (px - a[0]) * (b[1] - a[1])) / det
        l0 = 1 - l1 - l2
        inside = (l0 >= 0) & (l1 >= 0) & (l2 >= 0)
        mask |= inside
        pos[inside] = (l0[inside, None] * pa + l1[inside, None] * pb + l2[inside, None] * pc)
    return mask, pos


def image_pixels(img):
    w, h = img.size
    px = np.empty(w * h * 4, np.float32)
    img.pixels.foreach_get(px)
    return px.reshape(h, w, 4)


def blend_state():
    """Everything a bake or a preview may touch, in comparable form (bit-exact for arrays)."""
    state = {"images": {}, "materials": {}, "meshes": {}, "objects": {}, "node_groups": {}}
    for g in bpy.data.node_groups:
        state["node_groups"][g.name] = g.users
    for img in bpy.data.images:
        w, h = img.size
        px = np.empty(w * h * img.channels, np.float32)
        if w * h:
            img.pixels.foreach_get(px)
        state["images"][img.name] = (tuple(img.size), px.tobytes(), img.users, img.use_fake_user)
    for m in bpy.data.materials:
        state["materials"][m.name] = m.users
    for me in bpy.data.meshes:
        uvs = {}
        for layer in me.uv_layers:
            a = np.empty(len(me.loops) * 2, np.float32)
            layer.data.foreach_get("uv", a)
            uvs[layer.name] = (a.tobytes(), layer.active, layer.active_render)
        attrs = {a.name: (a.domain, a.data_type) for a in me.attributes}
        colors = {}
        for ca in me.color_attributes:
            a = np.empty(len(ca.data) * 4, np.float32)
            ca.data.foreach_get("color", a)
            colors[ca.name] = a.tobytes()
        flags = {}
        for coll in ("vertices", "edges", "polygons"):
            for attr in ("select", "hide"):
                c = getattr(me, coll)
                a = np.empty(len(c), bool)
                c.foreach_get(attr, a)
                flags[(coll, attr)] = a.tobytes()
        co = np.empty(len(me.vertices) * 3, np.float32)
        me.vertices.foreach_get("co", co)
        state["meshes"][me.name] = {
            "uvs": uvs, "attrs": attrs, "colors": colors, "flags": flags, "co": co.tobytes(),
            "materials": [m.name if m else None for m in me.materials],
            "active_color": me.color_attributes.active_color_index,
            "render_color": me.color_attributes.render_color_index,
        }
    vl = bpy.context.view_layer
    for ob in bpy.data.objects:
        slots = []
        for s in ob.material_slots:
            link = s.link
            s.link = "OBJECT"
            om = s.material.name if s.material else None
            s.link = "DATA"
            dm = s.material.name if s.material else None
            s.link = link
            slots.append((link, om, dm))
        props = {k: (ob[k].to_dict() if hasattr(ob[k], "to_dict") else ob[k]) for k in ob.keys()}
        # The modifier stack, with each Geometry Nodes modifier's group (a bake may append one).
        mods = [(m.name, m.type, m.node_group.name if m.type == "NODES" and m.node_group else None)
                for m in ob.modifiers]
        state["objects"][ob.name] = {"slots": slots, "props": props, "selected": ob.select_get(),
                                     "mode": ob.mode, "modifiers": mods,
                                     "data": ob.data.name if ob.data is not None else None}
    state["active"] = vl.objects.active.name if vl.objects.active else None
    return state


def assert_same_state(before, after):
    assert before.keys() == after.keys()
    for key in before:
        if before[key] != after[key]:
            if isinstance(before[key], dict):
                diff = {k for k in set(before[key]) | set(after[key]) if before[key].get(k) != after[key].get(k)}
                detail = {k: (before[key].get(k), after[key].get(k)) for k in sorted(diff)}
                raise AssertionError(f"{key} changed: {sorted(diff)}: {str(detail)[:2000]}")
            raise AssertionError(f"{key} changed: {before[key]!r} -> {after[key]!r}")

"""The Cornell box used by the main job, the Cycles reference and the tests.

Import it (`import cornell_box; cornell_box.build()`) or run it
(`blender -b --factory-startup --python examples/cornell_box.py -- --save box.blend`).

The room spans x, y in [-1, 1] and z in [0, 2]; the front (y = -1) is open and the camera looks in
along +y. The lamp is an emissive mesh that fills a hole in the ceiling, so its back side faces the
(black) outside: Cycles mesh emitters are two-sided, and a lamp hanging below the ceiling would light
the ceiling just above it far more brightly than anything else in the room. The lamp is split into
4x4 faces because Cycles' light sampling of a big two-triangle emitter is biased by a few tenths of
a percent (blender-facts §1). Everything is built from fixed numbers, so two builds are identical.
"""
import math
import sys

import bpy
import numpy as np

WHITE = (0.73, 0.73, 0.73)
RED = (0.63, 0.065, 0.05)
GREEN = (0.14, 0.45, 0.091)
LAMP_COLOR = (1.0, 0.9, 0.75)
LAMP_STRENGTH = 12.0
LAMP_HALF = 0.25          # the lamp is 0.5 m x 0.5 m
WALL_DIVISIONS = 8        # 0.25 m faces on every wall

# Objects whose reflected light is baked and compared (the lamp reflects nothing).
RECEIVERS = ("Floor", "Ceiling", "BackWall", "LeftWall", "RightWall", "ShortBlock", "TallBlock")


def _grid(origin, u, v, nu, nv, skip=None):
    """Quads on origin + s*u + t*v; the front normal is u x v (counter-clockwise in (u, v))."""
    origin, u, v = (np.asarray(a, float) for a in (origin, u, v))
    s = np.linspace(0.0, 1.0, nu + 1)
    t = np.linspace(0.0, 1.0, nv + 1)
    verts = origin + s[:, None, None] * u + t[None, :, None] * v      # (nu+1, nv+1, 3)
    idx = np.arange((nu + 1) * (nv + 1)).reshape(nu + 1, nv + 1)
    faces = []
    for i in range(nu):
        for j in range(nv):
            if skip is not None and skip(i, j):
                continue
            faces.append((idx[i, j], idx[i + 1, j], idx[i + 1, j + 1], idx[i, j + 1]))
    return verts.reshape(-1, 3), faces


def _compact(verts, faces):
    used = sorted({k for f in faces for k in f})
    remap = {old: new for new, old in enumerate(used)}
    return verts[used], [tuple(remap[k] for k in f) for f in faces]


def _mesh_object(name, parts, material):
    verts_all, faces_all, base = [], [], 0
    for verts, faces in parts:
        verts, faces = _compact(verts, faces)
        verts_all.append(verts)
        faces_all += [tuple(k + base for k in f) for f in faces]
        base += len(verts)
    me = bpy.data.meshes.new(name)
    me.from_pydata(np.concatenate(verts_all).tolist(), [], faces_all)
    me.validate()
    me.materials.append(material)
    ob = bpy.data.objects.new(name, me)
    bpy.context.scene.collection.objects.link(ob)
    return ob


def _diffuse(name, color):
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    nt = mat.node_tree
    nt.nodes.clear()
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    bsdf = nt.nodes.new("ShaderNodeBsdfDiffuse")
    bsdf.inputs["Color"].default_value = (*color, 1.0)
    bsdf.inputs["Roughness"].default_value = 0.0
    nt.links.new(bsdf.outputs["BSDF"], out.inputs["Surface"])
    return mat


def _emission(name, color, strength):
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


def _block(name, center_xy, half, height, angle_deg, divisions, material):
    """An open-bottomed box (the bottom would lie in the floor and never be seen)."""
    c, s = math.cos(math.radians(angle_deg)), math.sin(math.radians(angle_deg))
    ex = np.array([c, s, 0.0]) * half            # local x half-axis
    ey = np.array([-s, c, 0.0]) * half           # local y half-axis
    up = np.array([0.0, 0.0, height])
    o = np.array([center_xy[0], center_xy[1], 0.0])
    nh, nv = divisions
    parts = [
        _grid(o - ex - ey + up, 2 * ex, 2 * ey, nh, nh),            # top, normal +z
        _grid(o - ex - ey, 2 * ex, up, nh, nv),                      # side facing -ey
        _grid(o + ex - ey, 2 * ey, up, nh, nv),                      # side facing +ex
        _grid(o + ex + ey, -2 * ex, up, nh, nv),                     # side facing +ey
        _grid(o - ex + ey, -2 * ey, up, nh, nv),                     # side facing -ex
    ]
    return _mesh_object(name, parts, material)


def clear_scene():
    bpy.ops.wm.read_homefile(use_empty=True)


def build(scene=None):
    """Build the Cornell box into the (empty) current scene and return {name: object}."""
    scene = scene or bpy.context.scene
    white = _diffuse("White", WHITE)
    red = _diffuse("Red", RED)
    green = _diffuse("Green", GREEN)
    lamp_mat = _emission("Lamp", LAMP_COLOR, LAMP_STRENGTH)

    n = WALL_DIVISIONS
    lo, hi = n // 2 - 1, n // 2      # the 2x2 centre faces of the ceiling are the lamp's hole
    obs = {}
    obs["Floor"] = _mesh_object("Floor", [_grid((-1, -1, 0), (2, 0, 0), (0, 2, 0), n, n)], white)
    obs["Ceiling"] = _mesh_object(
        "Ceiling",
        [_grid((-1, -1, 2), (0, 2, 0), (2, 0, 0), n, n, skip=lambda i, j: lo <= i <= hi and lo <= j <= hi)],
        white)
    obs["BackWall"] = _mesh_object("BackWall", [_grid((-1, 1, 0), (2, 0, 0), (0, 0, 2), n, n)], white)
    obs["LeftWall"] = _mesh_object("LeftWall", [_grid((-1, -1, 0), (0, 2, 0), (0, 0, 2), n, n)], red)
    obs["RightWall"] = _mesh_object("RightWall", [_grid((1, -1, 0), (0, 0, 2), (0, 2, 0), n, n)], green)
    h = LAMP_HALF
    obs["Lamp"] = _mesh_object("Lamp", [_grid((-h, -h, 2), (0, 2 * h, 0), (2 * h, 0, 0), 4, 4)], lamp_mat)
    obs["ShortBlock"] = _block("ShortBlock", (0.38, -0.32), 0.3, 0.6, -17.0, (2, 2), white)
    obs["TallBlock"] = _block("TallBlock", (-0.36, 0.32), 0.3, 1.2, 17.0, (2, 4), white)

    cam_data = bpy.data.cameras.new("Camera")
    cam_data.lens = 35.0
    cam = bpy.data.objects.new("Camera", cam_data)
    cam.location = (0.0, -3.3, 1.0)
    cam.rotation_euler = (math.radians(90.0), 0.0, 0.0)
    scene.collection.objects.link(cam)
    scene.camera = cam
    obs["Camera"] = cam

    world = bpy.data.worlds.new("Black")
    world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (0, 0, 0, 1)
    world.node_tree.nodes["Background"].inputs["Strength"].default_value = 0.0
    world.color = (0, 0, 0)
    scene.world = world
    return obs


if __name__ == "__main__":
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    clear_scene()
    build()
    if "--save" in argv:
        path = argv[argv.index("--save") + 1]
        bpy.ops.wm.save_as_mainfile(filepath=bpy.path.abspath(path))
        print("saved", path)


def face_texel_averages(mesh, uv_name, pixels):
    """Average lightmap texels per polygon of `mesh` (no modifiers): the texels whose centres lie inside the
    polygon's UV footprint.

    `pixels` is (H, W, >=3), rows bottom-to-top as Blender stores them. Returns (mean (P,3), stderr (P,3),
    count (P,)). The standard error comes from differences of horizontally adjacent texels inside the face,
    which measure the per-texel noise while the smooth shading gradient largely cancels.
    """
    h, w = pixels.shape[:2]
    n_loops = len(mesh.loops)
    uv = np.empty(n_loops * 2, np.float32)
    mesh.uv_layers[uv_name].data.foreach_get("uv", uv)
    uv = uv.reshape(-1, 2).astype(np.float64)
    owner = np.full((h, w), -1, np.int64)
    for p in mesh.polygons:
        loops = list(range(p.loop_start, p.loop_start + p.loop_total))
        for k in range(1, len(loops) - 1):
            a, b, c = uv[loops[0]], uv[loops[k]], uv[loops[k + 1]]
            x0 = max(int(math.floor(min(a[0], b[0], c[0]) * w - 0.5)), 0)
            x1 = min(int(math.ceil(max(a[0], b[0], c[0]) * w - 0.5)), w - 1)
            y0 = max(int(math.floor(min(a[1], b[1], c[1]) * h - 0.5)), 0)
            y1 = min(int(math.ceil(max(a[1], b[1], c[1]) * h - 0.5)), h - 1)
            if x1 < x0 or y1 < y0:
                continue
            xs = (np.arange(x0, x1 + 1) + 0.5) / w
            ys = (np.arange(y0, y1 + 1) + 0.5) / h
            px, py = np.meshgrid(xs, ys)
            def edge(p0, p1):
                return (p1[0] - p0[0]) * (py - p0[1]) - (p1[1] - p0[1]) * (px - p0[0])
            e0, e1, e2 = edge(a, b), edge(b, c), edge(c, a)
            inside = ((e0 >= 0) & (e1 >= 0) & (e2 >= 0)) | ((e0 <= 0) & (e1 <= 0) & (e2 <= 0))
            sub = owner[y0:y1 + 1, x0:x1 + 1]
            sub[inside & (sub < 0)] = p.index
    n_poly = len(mesh.polygons)
    rgb = pixels[..., :3].astype(np.float64)
    mean = np.zeros((n_poly, 3))
    se = np.zeros((n_poly, 3))
    count = np.zeros(n_poly, np.int64)
    flat_owner = owner.ravel()
    flat_rgb = rgb.reshape(-1, 3)
    valid = flat_owner >= 0
    count[:] = np.bincount(flat_owner[valid], minlength=n_poly)
    for c in range(3):
        sums = np.bincount(flat_owner[valid], weights=flat_rgb[valid, c], minlength=n_poly)
        mean[:, c] = sums / np.maximum(count, 1)
    same = (owner[:, 1:] == owner[:, :-1]) & (owner[:, 1:] >= 0)
    d = (rgb[:, 1:] - rgb[:, :-1])[same]
    pair_owner = owner[:, 1:][same]
    pairs = np.bincount(pair_owner, minlength=n_poly)
    for c in range(3):
        sq = np.bincount(pair_owner, weights=d[:, c] ** 2, minlength=n_poly)
        var = sq / np.maximum(pairs, 1) / 2.0
        se[:, c] = np.sqrt(var / np.maximum(count, 1))
    return mean, se, count

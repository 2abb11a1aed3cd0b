"""Pathological scenes for the native module, built from numpy arrays.

Every case is a function returning a `Case`: the solve() arguments plus what must happen -- either the
solve and bake succeed (finite, non-negative) or solve() raises ValueError whose message contains
`raises` (the offending object's name, quoted as the module quotes it).
"""
import math
from dataclasses import dataclass, field

import numpy as np

import _native

LIGHT_ONLY = _native.LIGHT_ONLY
EMIT_BACK = _native.EMIT_BACK


class Builder:
    """Accumulates faces; vertices are kept in float64 until `arrays()` so transforms stay exact."""

    def __init__(self):
        self.verts, self.polys, self.refl, self.emis, self.flags, self.obj = [], [], [], [], [], []
        self.names = []

    def object(self, name):
        if name not in self.names:
            self.names.append(name)
        return self.names.index(name)

    def face(self, pts, name, rho=0.5, emit=0.0, flags=0):
        """A triangle or quad, counter-clockwise around its front normal."""
        base = len(self.verts)
        self.verts += [list(map(float, p)) for p in pts]
        row = list(range(base, base + len(pts))) + ([-1] if len(pts) == 3 else [])
        self.polys.append(row)
        self.refl.append(_rgb(rho))
        self.emis.append(_rgb(emit))
        self.flags.append(flags)
        self.obj.append(self.object(name))
        return len(self.polys) - 1

    def quad_xy(self, x0, y0, x1, y1, z, name, up=True, **kw):
        pts = [(x0, y0, z), (x1, y0, z), (x1, y1, z), (x0, y1, z)]
        return self.face(pts if up else pts[::-1], name, **kw)

    def box(self, lo, hi, name, inward=False, **kw):
        """Six faces of an axis-aligned box, facing out (a solid object) or in (a room)."""
        (x0, y0, z0), (x1, y1, z1) = lo, hi
        c = [(x0, y0, z0), (x1, y0, z0), (x1, y1, z0), (x0, y1, z0),
             (x0, y0, z1), (x1, y0, z1), (x1, y1, z1), (x0, y1, z1)]
        faces = [(0, 3, 2, 1), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7)]
        for f in faces:
            pts = [c[i] for i in f]
            self.face(pts[::-1] if inward else pts, name, **kw)

    def lamp(self, cx, cy, z, size, emit, name="Lamp", down=True, flags=LIGHT_ONLY):
        s = size / 2
        return self.quad_xy(cx - s, cy - s, cx + s, cy + s, z, name, up=not down, rho=0.0, emit=emit,
                            flags=flags)

    def transform(self, scale=1.0, offset=(0.0, 0.0, 0.0)):
        self.verts = [[v * scale + o for v, o in zip(p, offset)] for p in self.verts]
        return self

    def arrays(self):
        return (np.array(self.verts, np.float32).reshape(-1, 3), np.array(self.polys, np.int32).reshape(-1, 4),
                np.array(self.refl, np.float32).reshape(-1, 3), np.array(self.emis, np.float32).reshape(-1, 3),
                np.array(self.flags, np.uint8), np.array(self.obj, np.int32), list(self.names))


def _rgb(x):
    return [float(x)] * 3 if np.isscalar(x) else [float(c) for c in x]


@dataclass
class Case:
    args: tuple
    raises: str = None            # substring of the ValueError's message, or None: must bake
    settings: dict = field(default_factory=dict)
    note: str = ""


def room(lamp_emit=20.0, rho=0.6, size=4.0, height=2.5):
    """A floor and a lamp facing it: the base that most cases perturb."""
    b = Builder()
    h = size / 2
    b.quad_xy(-h, -h, h, h, 0.0, "Floor", rho=rho)
    b.lamp(0.0, 0.0, height, 0.5, lamp_emit)
    return b


def cube_on_floor(z0, name="Cube", size=1.0, **kw):
    b = room(**kw)
    s = size / 2
    b.box((-s, -s, z0), (s, s, z0 + size), name, rho=0.7)
    return b


def cornellish(scale=1.0, offset=(0.0, 0.0, 0.0)):
    """A closed room with a lamp and a box: interreflection and shadows, used for invariance checks."""
    b = Builder()
    b.box((-1.0, -1.0, 0.0), (1.0, 1.0, 2.0), "Room", inward=True, rho=0.6)
    b.box((-0.5, -0.25, 0.0), (0.25, 0.5, 0.75), "Block", rho=0.7)
    b.lamp(0.0, 0.0, 1.96875, 0.5, 30.0)
    return b.transform(scale, offset)


# ---------------------------------------------------------------------------------------------------- cases

def nan_vertex():
    b = cube_on_floor(0.0)
    b.verts[-3][1] = math.nan
    return Case(b.arrays(), raises="'Cube'")


def inf_vertex():
    b = cube_on_floor(0.0)
    b.verts[0][2] = -math.inf
    return Case(b.arrays(), raises="'Floor'")


def nan_unreferenced_vertex():
    b = room()
    b.verts.append([math.nan, math.inf, 0.0])  # no face uses it: harmless
    return Case(b.arrays())


def huge_coordinate():
    b = room()
    b.face([(0, 0, 0.5), (1e38, 0, 0.5), (0, 1, 0.5)], "Spike", rho=0.5)
    return Case(b.arrays(), raises="'Spike'", note="beyond what float32 ray tracing can resolve")


def zero_area_triangle():
    b = room()
    b.face([(0.2, 0.2, 0.5), (0.2, 0.2, 0.5), (0.4, 0.3, 0.5)], "Degenerate", rho=0.5)
    return Case(b.arrays())


def collinear_triangle():
    b = room()
    b.face([(0.0, 0.0, 0.5), (0.5, 0.5, 0.5), (1.0, 1.0, 0.5)], "Collinear", rho=0.5)
    return Case(b.arrays())


def needle_triangles():
    b = room()
    for k in range(20):
        y = -1.0 + 0.1 * k
        b.face([(-1.5, y, 0.3), (1.5, y, 0.3), (1.5, y + 1e-5, 0.3)], "Needles", rho=0.8)
        b.face([(-1.5, y, 0.3), (1.5, y + 1e-5, 0.3), (-1.5, y + 2e-6, 0.3)][::-1], "Needles", rho=0.8)
    return Case(b.arrays())


def degenerate_only_mesh():
    b = Builder()
    b.face([(0, 0, 0), (1, 1, 1), (2, 2, 2)], "Line", rho=0.5)
    b.lamp(0, 0, 2, 0.5, 10.0)
    return Case(b.arrays(), raises="no mesh faces")


def nonplanar_quad():
    b = room()
    b.face([(-1, -1, 0.5), (1, -1, 0.9), (1, 1, 0.5), (-1, 1, 0.1)], "Warped", rho=0.5)
    return Case(b.arrays())


def concave_quad():
    b = room()
    # A dart: the fourth corner is inside the triangle of the other three.
    b.face([(-1, -1, 0.5), (1, -1, 0.5), (1, 1, 0.5), (0.5, -0.5, 0.5)], "Dart", rho=0.5)
    return Case(b.arrays())


def bowtie_quad():
    b = room()
    b.face([(-1, -1, 0.5), (1, 1, 0.5), (1, -1, 0.5), (-1, 1, 0.5)], "Bowtie", rho=0.5)
    return Case(b.arrays())


def duplicate_coplanar_faces():
    b = room()
    for _ in range(3):
        b.quad_xy(-0.5, -0.5, 0.5, 0.5, 0.4, "Shelf", rho=0.5)
    b.quad_xy(-0.5, -0.5, 0.5, 0.5, 0.4, "Shelf", up=False, rho=0.5)
    return Case(b.arrays())


def resting_on_floor():
    return Case(cube_on_floor(0.0).arrays())


def interpenetrating_floor():
    return Case(cube_on_floor(-0.4).arrays())


def gap_1mm():
    return Case(cube_on_floor(0.001).arrays())


def offset_1e5():
    return Case(cornellish(offset=(1e5, -1e5, 1e5)).arrays())


def scale_1e_minus_4():
    return Case(cornellish(scale=1e-4).arrays())


def scale_1e4():
    return Case(cornellish(scale=1e4).arrays())


def emitter_facing_away():
    b = room()
    b.polys[1] = [b.polys[1][i] for i in (3, 2, 1, 0)]  # lamp now faces the sky
    return Case(b.arrays(), note="everything stays black")


def emitter_only():
    b = Builder()
    b.lamp(0, 0, 1, 1.0, 10.0)
    return Case(b.arrays(), raises="no mesh faces")


def emissive_mesh_only():
    b = Builder()
    b.quad_xy(-1, -1, 1, 1, 0, "Panel", rho=0.0, emit=5.0, flags=EMIT_BACK)
    return Case(b.arrays())


def empty_scene():
    return Case(Builder().arrays(), raises="no faces")


def nothing_emits():
    b = room()
    b.emis[1] = [0.0] * 3
    return Case(b.arrays(), raises="nothing emits")


def albedo_zero():
    return Case(room(rho=0.0).arrays())


def albedo_0999():
    b = cornellish()
    b.refl = [[0.999] * 3 if r[0] > 0 else r for r in b.refl]
    # Plain Jacobi needed ~16000 sweeps at this albedo; mixed sweeps converge in ~30, within max_iterations.
    return Case(b.arrays(), settings={"max_iterations": 100, "epsilon": 0.002, "min_size": 0.05})


def albedo_above_one():
    b = cube_on_floor(0.0)
    b.refl[-1] = [0.5, 1.2, 0.5]
    return Case(b.arrays(), raises="'Cube'")


def albedo_negative():
    b = cube_on_floor(0.0)
    b.refl[0] = [0.5, 0.5, -0.1]
    return Case(b.arrays(), raises="'Floor'")


def albedo_nan():
    b = cube_on_floor(0.0)
    b.refl[2] = [0.5, math.nan, 0.5]
    return Case(b.arrays(), raises="'Cube'")


def emission_negative():
    b = room()
    b.emis[1] = [1.0, -1.0, 1.0]
    return Case(b.arrays(), raises="'Lamp'")


def emission_inf():
    b = room()
    b.emis[1] = [math.inf] * 3
    return Case(b.arrays(), raises="'Lamp'")


def light_power_1e_minus_9():
    return Case(cube_on_floor(0.0, lamp_emit=20e-9).arrays())


def light_power_1e9():
    return Case(cube_on_floor(0.0, lamp_emit=20e9).arrays())


def light_inside_closed_box(z0=0.0):
    """A lamp sealed inside a solid (outward-facing) box standing on the floor."""
    b = Builder()
    b.quad_xy(-2, -2, 2, 2, 0.0, "Floor", rho=0.6)
    b.box((-0.5, -0.5, z0), (0.5, 0.5, z0 + 1.0), "Crate", rho=0.7)
    b.lamp(0, 0, z0 + 0.9, 0.3, 50.0)
    return Case(b.arrays(), note="nothing outside the crate is lit")


def single_polygon():
    b = Builder()
    b.quad_xy(-1, -1, 1, 1, 0, "Only", rho=0.5, emit=1.0)
    return Case(b.arrays())


def single_dark_polygon():
    b = Builder()
    b.quad_xy(-1, -1, 1, 1, 0, "Only", rho=0.5)
    return Case(b.arrays(), raises="nothing emits")


def index_out_of_range():
    b = room()
    b.polys[0][2] = 99
    return Case(b.arrays(), raises="'Floor'")


def negative_index():
    b = cube_on_floor(0.0)
    b.polys[3][3] = -7
    return Case(b.arrays(), raises="'Cube'")


def triangle_marker_in_wrong_column():
    b = room()
    b.polys[0][1] = -1
    return Case(b.arrays(), raises="'Floor'")


def object_index_out_of_range():
    a = list(room().arrays())
    a[5] = a[5].copy()
    a[5][0] = 5
    return Case(tuple(a), raises="object_index")


def unknown_flag_bits():
    b = room()
    b.flags[0] = 0xFC  # bits the module does not define: ignored, the floor stays an ordinary face
    return Case(b.arrays())


def two_sided_mesh_emitter():
    b = room()
    b.quad_xy(-0.3, -0.3, 0.3, 0.3, 1.0, "Glow", up=False, rho=0.0, emit=8.0, flags=EMIT_BACK)
    return Case(b.arrays())


def grid(n, name="Grid"):
    """An n x n grid of quads under a lamp, with a blocker in between: n^2 + 7 faces."""
    b = Builder()
    xs = np.linspace(-2, 2, n + 1)
    for i in range(n):
        for j in range(n):
            b.quad_xy(xs[i], xs[j], xs[i + 1], xs[j + 1], 0.0, name, rho=0.5)
    b.box((-0.4, -0.4, 0.8), (0.4, 0.4, 1.0), "Blocker", rho=0.5)
    b.lamp(0, 0, 2.5, 0.5, 20.0)
    return b


def shade(b, z, tiles=4, pitch=0.5, tile=0.3, rho=0.0, name="Shade"):
    """A perforated shade of tiles x tiles flat tiles facing down at height z: a convolution site."""
    for i in range(tiles):
        for j in range(tiles):
            cx, cy = (i - (tiles - 1) / 2) * pitch, (j - (tiles - 1) / 2) * pitch
            b.quad_xy(cx - tile / 2, cy - tile / 2, cx + tile / 2, cy + tile / 2, z, name, up=False, rho=rho)
    return b


def shade_against_the_lamp():
    """A shade 1e-4 m under the lamp: the penumbra scale is unbounded (the convolution must refuse or cope)."""
    return Case(shade(grid_floor(8), 2.5 - 1e-4).arrays(), note="convolution: source-side contact")


def shade_on_the_floor():
    """Black tiles lying in the floor's plane, facing up: an occluder coplanar with the receiver."""
    b = grid_floor(8)
    for i in range(4):
        b.quad_xy(-1 + 0.5 * i, -0.2, -0.8 + 0.5 * i, 0.2, 0.0, "Sheet", rho=0.0)
    return Case(shade(b, 1.2).arrays(), note="convolution: coplanar occluder")


def triangle_lamp_over_shade():
    """A lamp of four emitting triangles (a non-rectangular emitter group) over a shade: the emission image."""
    b = shade(grid_floor(8), 1.2)
    c, s, z = (0.0, 0.0), 0.4, 2.5
    pts = [(-s, -s), (-s, s), (s, s), (s, -s)]
    for k in range(4):
        a, e = pts[k], pts[(k + 1) % 4]
        b.face([(c[0], c[1], z), (e[0], e[1], z), (a[0], a[1], z)], "TriLamp", rho=0.0, emit=20.0)
    return Case(b.arrays(), note="convolution: emitter group of triangles")


def wide_lamp_near_shade():
    """A lamp as wide as its height above the floor: its textures are cut into the most parts."""
    b = grid_floor(8)
    b.lamp(0, 0, 1.0, 2.0, 10.0)
    return Case(shade(b, 0.5, tiles=6, pitch=0.4, tile=0.2).arrays(), note="convolution: 4 x 4 source parts")


def grid_floor(n):
    """A 4 x 4 m floor in n x n faces under a 0.8 m lamp at 2.5 m."""
    b = Builder()
    xs = np.linspace(-2, 2, n + 1)
    for i in range(n):
        for j in range(n):
            b.quad_xy(xs[i], xs[j], xs[i + 1], xs[j + 1], 0.0, "Floor", rho=0.5)
    b.lamp(0, 0, 2.5, 0.8, 20.0)
    return b


def large_scene():
    return Case(grid(40).arrays(), settings={"min_size": 0.02}, note="1607 faces")


CASES = {f.__name__: f for f in [
    nan_vertex, inf_vertex, nan_unreferenced_vertex, huge_coordinate, zero_area_triangle, collinear_triangle,
    needle_triangles, degenerate_only_mesh, nonplanar_quad, concave_quad, bowtie_quad,
    duplicate_coplanar_faces, resting_on_floor, interpenetrating_floor, gap_1mm, offset_1e5,
    scale_1e_minus_4, scale_1e4, emitter_facing_away, emitter_only, emissive_mesh_only, empty_scene,
    nothing_emits, albedo_zero, albedo_0999, albedo_above_one, albedo_negative, albedo_nan,
    emission_negative, emission_inf, light_power_1e_minus_9, light_power_1e9, light_inside_closed_box,
    single_polygon, single_dark_polygon, index_out_of_range, negative_index, triangle_marker_in_wrong_column,
    object_index_out_of_range, unknown_flag_bits, two_sided_mesh_emitter, large_scene, shade_against_the_lamp,
    shade_on_the_floor, triangle_lamp_over_shade, wide_lamp_near_shade,
]}


# ------------------------------------------------------------------------------------------ probing a solution

def face_samples(args):
    """Centroid and corners of every face with area (float32 points, unit normals), for radiance()."""
    verts, polys = args[0].astype(np.float64), args[1]
    pts, nrm = [], []
    for row in polys:
        idx = [i for i in row if i >= 0]
        p = verts[idx]
        if not np.all(np.isfinite(p)):
            continue
        n = sum(np.cross(p[k] - p[0], p[k + 1] - p[0]) for k in range(1, len(p) - 1))
        ln = np.linalg.norm(n)
        if not ln > 0:
            continue
        for q in [p.mean(axis=0), *p]:
            pts.append(q)
            nrm.append(n / ln)
    return np.array(pts, np.float32).reshape(-1, 3), np.array(nrm, np.float32).reshape(-1, 3)


def atlas(args, limit=256):
    """Every face's triangles, each in its own cell of a UV grid; at most `limit` triangles."""
    verts, polys = args[0], args[1]
    tris = []
    for row in polys:
        idx = [i for i in row if i >= 0]
        for k in range(1, len(idx) - 1):
            tris.append(verts[[idx[0], idx[k], idx[k + 1]]])
    tris = tris[:limit]
    cells = max(1, math.ceil(math.sqrt(len(tris))))
    uvs = []
    for t in range(len(tris)):
        u0, v0 = (t % cells) / cells, (t // cells) / cells
        d = 0.9 / cells
        uvs.append([[u0, v0], [u0 + d, v0], [u0, v0 + d]])
    return (np.array(tris, np.float32).reshape(-1, 3, 3), np.array(uvs, np.float32).reshape(-1, 3, 2))

"""A procedural open-plan office whose polygon count is a parameter, for scaling benchmarks (bench/scaling.py).

    import scalable_scene
    scene = scalable_scene.make_scene(20000)          # numpy arrays, the arguments of penumbra._native.solve
    solution = _native.solve(**scene, settings={...})
    blender -b --factory-startup --python examples/scalable_scene.py -- --polygons 20000 --save office20k.blend

A closed room (floor, ceiling, four walls, all subdivided into roughly square faces) with four rectangular area
lights under the ceiling, one per quadrant, filled with a grid of workstations. A workstation is a desk (top,
four legs, a drawer unit), a monitor on a stand and a chair (seat, back, four legs): 65 quads. About 65 % of
the polygons are workstations and the rest is the room's subdivision; the floor's subdivision absorbs the
rounding, so the total lands within 1 % of the target from 200 polygons up (0.4 % from 500).

The scene grows like a real floor plan: the workstation density is constant (one per 2 m x 2 m), so the room's
area grows with the polygon count, and the lights grow with it (each covers 16 % of its quadrant at a fixed
exitance), so the illumination level and the brightest emitter -- which the solver's relative `epsilon` refers
to -- stay the same at every size. What does *not* stay the same is anything relative to the bounding box:
the solver's `min_size` is a fraction of the scene's diagonal, which grows like sqrt(polygons);
`scene_diagonal(scene)` gives the diagonal so a benchmark can hold the smallest element size fixed in metres.

`layout="classroom"` fills the same room with rows of school desks (top and four legs) and chairs behind them,
all facing the front wall, without monitors or drawer units: the furnished room of issue 12 (desks and chairs
standing on the floor under four area lights), at the same polygon budget and lights.

Everything is deterministic: the per-workstation variation (rotation, offset, colours, chair position) comes
from a seeded generator, and make_scene(n) twice gives identical arrays. build_bpy(n) builds the same
geometry in Blender (bpy is imported only there), so the add-on's export of it matches make_scene(n).
"""
import math
import os
import sys

import numpy as np

LIGHT_ONLY = 2                      # penumbra._native.LIGHT_ONLY, repeated so this file needs no module

PITCH = 2.0                         # workstation spacing in x and y, metres
MARGIN = 1.0                        # free floor between the outer workstations and the walls
HEIGHT = 3.0                        # room height
ASPECT = 4.0 / 3.0                  # room width / depth, before rounding to whole workstations
FURNITURE_SHARE = 0.65              # fraction of the polygons spent on workstations
QUADS_PER_STATION = {"office": 65, "classroom": 50}
LIGHT_EXITANCE = 100.0              # W/m^2 per colour unit, the same at every size
LIGHT_COLOR = (1.0, 0.95, 0.85)
LIGHT_FILL = 0.4                    # light edge / quadrant edge, in x and in y
LIGHT_DROP = 0.05                   # lights hang this far below the ceiling
MIN_POLYGONS = 200

FLOOR = (0.45, 0.35, 0.25)
CEILING = (0.8, 0.8, 0.8)
WALL = (0.75, 0.75, 0.72)
ACCENT = (0.6, 0.25, 0.2)           # the back wall, so colour bleeding is visible
DESK_COLORS = ((0.55, 0.4, 0.25), (0.62, 0.5, 0.35), (0.7, 0.7, 0.68), (0.35, 0.28, 0.22))
CHAIR_COLORS = ((0.15, 0.2, 0.45), (0.45, 0.12, 0.1), (0.2, 0.35, 0.2), (0.25, 0.25, 0.25))
MONITOR = (0.06, 0.06, 0.07)
STAND = (0.4, 0.4, 0.42)

# Object order is part of the output (object_index); the lights come last so the receivers keep low indices.
MESH_OBJECTS = ("Floor", "Ceiling", "Walls", "Desks", "Monitors", "Chairs")
LIGHTS = ("Light0", "Light1", "Light2", "Light3")
OBJECT_NAMES = MESH_OBJECTS + LIGHTS


class _Builder:
    """Quads per object, each with its reflectance; vertices are shared within a grid only."""

    def __init__(self):
        self.verts, self.quads, self.rgb, self.obj = [], [], [], []
        self.nverts = 0

    def grid(self, obj, rgb, origin, u, v, nu=1, nv=1):
        """Quads on origin + s*u + t*v, s, t in [0, 1]; the front normal is u x v."""
        origin, u, v = (np.asarray(a, np.float64) for a in (origin, u, v))
        s = np.linspace(0.0, 1.0, nu + 1)
        t = np.linspace(0.0, 1.0, nv + 1)
        pts = origin + s[:, None, None] * u + t[None, :, None] * v
        idx = np.arange((nu + 1) * (nv + 1)).reshape(nu + 1, nv + 1) + self.nverts
        quads = np.stack([idx[:-1, :-1], idx[1:, :-1], idx[1:, 1:], idx[:-1, 1:]], axis=-1).reshape(-1, 4)
        self.verts.append(pts.reshape(-1, 3))
        self.quads.append(quads)
        self.rgb.append(np.tile(np.asarray(rgb, np.float64), (len(quads), 1)))
        self.obj.append(np.full(len(quads), OBJECT_NAMES.index(obj)))
        self.nverts += len(pts.reshape(-1, 3))

    def box(self, obj, rgb, lo, hi, place, sides="tbnsew"):
        """An axis-aligned box in a workstation's frame with outward normals, moved by `place` (rotation
        about z, then translation). `sides` picks the faces: t/b top and bottom, s/n -y and +y, w/e -x and +x;
        faces that touch the floor or another part are left out so nothing coincides with a face."""
        (x0, y0, z0), (x1, y1, z1) = lo, hi
        dx, dy, dz = x1 - x0, y1 - y0, z1 - z0
        faces = {
            "t": ((x0, y0, z1), (dx, 0, 0), (0, dy, 0)),
            "b": ((x0, y0, z0), (0, dy, 0), (dx, 0, 0)),
            "s": ((x0, y0, z0), (dx, 0, 0), (0, 0, dz)),
            "n": ((x1, y1, z0), (-dx, 0, 0), (0, 0, dz)),
            "w": ((x0, y1, z0), (0, -dy, 0), (0, 0, dz)),
            "e": ((x1, y0, z0), (0, dy, 0), (0, 0, dz)),
        }
        rot, shift = place
        for key in sides:
            o, u, v = (np.asarray(a, np.float64) for a in faces[key])
            self.grid(obj, rgb, rot @ o + shift, rot @ u, rot @ v)

    def arrays(self):
        return (np.concatenate(self.verts), np.concatenate(self.quads), np.concatenate(self.rgb),
                np.concatenate(self.obj))


def _station(b, place, desk_rgb, chair_rgb, chair_dy):
    """One workstation in its own frame: the desk spans y in [0, 0.7] facing -y, the chair sits in front."""
    b.box("Desks", desk_rgb, (-0.7, 0.0, 0.72), (0.7, 0.7, 0.76), place)
    for x in (-0.67, 0.62):
        for y in (0.03, 0.62):
            b.box("Desks", desk_rgb, (x, y, 0.0), (x + 0.05, y + 0.05, 0.72), place, "snwe")
    b.box("Desks", desk_rgb, (0.2, 0.1, 0.0), (0.58, 0.6, 0.6), place, "tsnwe")
    # The monitor floats 4 cm over the desk on a stand, so its bottom never lies in the desk's plane.
    b.box("Monitors", STAND, (-0.03, 0.48, 0.76), (0.03, 0.51, 0.8), place, "snwe")
    b.box("Monitors", MONITOR, (-0.25, 0.45, 0.8), (0.25, 0.49, 1.12), place)
    c = chair_dy
    b.box("Chairs", chair_rgb, (-0.22, c - 0.55, 0.42), (0.22, c - 0.11, 0.46), place)
    b.box("Chairs", chair_rgb, (-0.22, c - 0.59, 0.46), (0.22, c - 0.55, 0.9), place)
    for x in (-0.2, 0.17):
        for y in (-0.53, -0.16):
            b.box("Chairs", chair_rgb, (x, c + y, 0.0), (x + 0.03, c + y + 0.03, 0.42), place, "snwe")


def _school_station(b, place, desk_rgb, chair_rgb, chair_dy):
    """A pupil's desk and chair in the workstation's frame: the desk spans y in [0, 0.6], the pupil sits at -y.
    Legs stand on the floor with no bottom face, as in _station, so the floor meets every leg edge-on."""
    b.box("Desks", desk_rgb, (-0.6, 0.0, 0.72), (0.6, 0.6, 0.76), place)
    for x in (-0.57, 0.52):
        for y in (0.03, 0.52):
            b.box("Desks", desk_rgb, (x, y, 0.0), (x + 0.05, y + 0.05, 0.72), place, "snwe")
    c = chair_dy
    b.box("Chairs", chair_rgb, (-0.22, c - 0.5, 0.42), (0.22, c - 0.06, 0.46), place)
    b.box("Chairs", chair_rgb, (-0.22, c - 0.54, 0.46), (0.22, c - 0.5, 0.9), place)
    for x in (-0.2, 0.17):
        for y in (-0.48, -0.11):
            b.box("Chairs", chair_rgb, (x, c + y, 0.0), (x + 0.03, c + y + 0.03, 0.42), place, "snwe")


STATIONS = {"office": _station, "classroom": _school_station}


def _rotation_z(angle):
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def plan(n_polygons, layout="office"):
    """The layout for a target polygon count: workstation count and grid, room size, subdivisions."""
    n_polygons = int(n_polygons)
    if layout not in STATIONS:
        raise ValueError(f"unknown layout {layout!r}; known: {', '.join(STATIONS)}")
    if n_polygons < MIN_POLYGONS:
        raise ValueError(f"make_scene needs at least {MIN_POLYGONS} polygons, got {n_polygons}")
    budget = n_polygons - len(LIGHTS)
    stations = max(1, round(FURNITURE_SHARE * budget / QUADS_PER_STATION[layout]))
    nx = max(1, math.ceil(math.sqrt(stations * ASPECT)))
    ny = math.ceil(stations / nx)
    W, D, H = PITCH * nx + 2 * MARGIN, PITCH * ny + 2 * MARGIN, HEIGHT
    room = budget - stations * QUADS_PER_STATION[layout]
    # Square-ish faces of one edge length s everywhere: (2WD + 2(W + D)H) / s^2 = room.
    s = math.sqrt((2 * W * D + 2 * (W + D) * H) / room)
    wx, wy, wz = (max(1, round(a / s)) for a in (W, D, H))
    walls = 2 * (wx + wy) * wz
    ceiling = (wx, wy)
    left = room - walls - wx * wy
    # The floor takes up the rounding: the (fx, fy) closest to `left` faces among those whose faces are at
    # most 1.5 times longer one way than the other, then the squarest faces.
    best = None
    centre = math.sqrt(max(left, 1) * W / D)
    for fx in range(max(1, int(centre) - 4), int(centre) + 6):
        fy = max(1, round(left / fx))
        skew = abs(math.log(fx / fy * D / W))
        key = (skew > math.log(1.5), abs(fx * fy - left), skew)
        if best is None or key < best[0]:
            best = (key, fx, fy)
    floor = best[1:]
    total = len(LIGHTS) + stations * QUADS_PER_STATION[layout] + walls + wx * wy + floor[0] * floor[1]
    return {"target": n_polygons, "layout": layout, "polygons": total, "stations": stations, "grid": (nx, ny),
            "room": (W, D, H), "walls": (wx, wy, wz), "ceiling": ceiling, "floor": floor}


def lights(n_polygons, layout="office"):
    """The four area lights: (name, centre (x, y, z), size (x, y), exitance rgb)."""
    W, D, H = plan(n_polygons, layout)["room"]
    lx, ly = LIGHT_FILL * W / 2, LIGHT_FILL * D / 2
    out = []
    for k, (sx, sy) in enumerate(((-1, -1), (1, -1), (-1, 1), (1, 1))):
        out.append((LIGHTS[k], (sx * W / 4, sy * D / 4, H - LIGHT_DROP), (lx, ly),
                    tuple(LIGHT_EXITANCE * c for c in LIGHT_COLOR)))
    return out


def make_scene(n_polygons, seed=0, layout="office"):
    """The scene as the keyword arguments of penumbra._native.solve (without settings and progress)."""
    p = plan(n_polygons, layout)
    W, D, H = p["room"]
    wx, wy, wz = p["walls"]
    b = _Builder()
    b.grid("Floor", FLOOR, (-W / 2, -D / 2, 0), (W, 0, 0), (0, D, 0), *p["floor"])
    b.grid("Ceiling", CEILING, (-W / 2, -D / 2, H), (0, D, 0), (W, 0, 0), *p["ceiling"][::-1])
    b.grid("Walls", ACCENT, (-W / 2, D / 2, 0), (W, 0, 0), (0, 0, H), wx, wz)        # back, faces -y
    b.grid("Walls", WALL, (W / 2, -D / 2, 0), (0, 0, H), (0, D, 0), wz, wy)          # right, faces -x
    b.grid("Walls", WALL, (-W / 2, -D / 2, 0), (0, D, 0), (0, 0, H), wy, wz)         # left, faces +x
    b.grid("Walls", WALL, (-W / 2, -D / 2, 0), (0, 0, H), (W, 0, 0), wz, wx)         # front, faces +y

    # All random draws happen up front, in one order, so the scene depends on the seed and the size only.
    rng = np.random.default_rng(seed)
    n = p["stations"]
    angle = rng.uniform(-math.radians(10), math.radians(10), n)
    offset = rng.uniform(-0.1, 0.1, (n, 2))
    desk = rng.integers(0, len(DESK_COLORS), n)
    chair = rng.integers(0, len(CHAIR_COLORS), n)
    chair_dy = rng.uniform(-0.1, 0.15, n)
    nx = p["grid"][0]
    if layout == "classroom":
        angle, offset = np.zeros_like(angle), np.zeros_like(offset)     # rows, all facing the front wall
    for k in range(n):
        i, j = k % nx, k // nx
        centre = np.array([-W / 2 + MARGIN + PITCH * (i + 0.5) + offset[k, 0],
                           -D / 2 + MARGIN + PITCH * (j + 0.5) + offset[k, 1], 0.0])
        STATIONS[layout](b, (_rotation_z(angle[k]), centre), DESK_COLORS[desk[k]], CHAIR_COLORS[chair[k]],
                         chair_dy[k])

    for name, (cx, cy, cz), (lx, ly), _ in lights(n_polygons, layout):
        # u x v points down (-z): the lights face the room, as Blender's area lights face local -Z.
        b.grid(name, (0, 0, 0), (cx - lx / 2, cy - ly / 2, cz), (0, ly, 0), (lx, 0, 0))

    verts, quads, rgb, obj = b.arrays()
    emission = np.zeros_like(rgb)
    flags = np.zeros(len(quads), np.uint8)
    first_light = OBJECT_NAMES.index(LIGHTS[0])
    is_light = obj >= first_light
    emission[is_light] = np.array(LIGHT_COLOR) * LIGHT_EXITANCE
    flags[is_light] = LIGHT_ONLY
    assert len(quads) == p["polygons"]
    return {
        "vertices": np.ascontiguousarray(verts, np.float32),
        "polygons": np.ascontiguousarray(quads, np.int32),
        "reflectance": np.ascontiguousarray(rgb, np.float32),
        "emission": np.ascontiguousarray(emission, np.float32),
        "flags": flags,
        "object_index": np.ascontiguousarray(obj, np.int32),
        "object_names": list(OBJECT_NAMES),
    }


def scene_diagonal(scene):
    """The bounding-box diagonal of the polygons' vertices, which the solver's relative min_size refers to."""
    used = scene["polygons"][scene["polygons"] >= 0]
    v = scene["vertices"][np.unique(used)].astype(np.float64)
    return float(np.linalg.norm(v.max(axis=0) - v.min(axis=0)))


def build_bpy(n_polygons, scene=None, seed=0, layout="office"):
    """Build the same scene in Blender: one mesh object per entry of MESH_OBJECTS (one material per distinct
    reflectance, per object, so a Cycles bake can take all objects at once), four RECTANGLE area lights, a
    camera and a black world. Returns {name: object}."""
    import bpy
    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    import scenes                   # noqa: E402  (needs bpy; kept out of make_scene's import path)

    scene = scene or bpy.context.scene
    arrays = make_scene(n_polygons, seed, layout)
    verts, polys = arrays["vertices"], arrays["polygons"]
    rgb, obj = arrays["reflectance"], arrays["object_index"]
    obs = {}
    for k, name in enumerate(MESH_OBJECTS):
        rows = polys[obj == k]
        if not len(rows):
            continue            # the classroom has no monitors; an empty mesh would only trip the bakes
        used, local = np.unique(rows, return_inverse=True)
        colors, mat_index = np.unique(rgb[obj == k], axis=0, return_inverse=True)
        me = bpy.data.meshes.new(name)
        me.from_pydata(verts[used].tolist(), [], local.reshape(rows.shape).tolist())
        for m, c in enumerate(colors):
            me.materials.append(scenes._diffuse(f"{name}{m}", tuple(float(x) for x in c)))
        me.polygons.foreach_set("material_index", mat_index.reshape(-1).astype(np.int32))
        me.validate()
        me.update()
        ob = bpy.data.objects.new(name, me)
        scene.collection.objects.link(ob)
        obs[name] = ob
    for name, centre, (lx, ly), _ in lights(n_polygons, layout):
        light = bpy.data.lights.new(name, "AREA")
        light.shape = "RECTANGLE"
        light.size, light.size_y = lx, ly
        light.color = LIGHT_COLOR
        # The add-on exports exitance pi * P * color / (4 A) before Blender 4.0 and P * color / A since (Cycles'
        # area light units); invert it for the same emission as make_scene.
        light.energy = lx * ly * LIGHT_EXITANCE * (4.0 / math.pi if bpy.app.version < (4, 0, 0) else 1.0)
        ob = bpy.data.objects.new(name, light)
        ob.location = centre                        # no rotation: it faces local -Z, down
        scene.collection.objects.link(ob)
        obs[name] = ob
    W, D, H = plan(n_polygons, layout)["room"]
    # From a front corner at eye height, looking along the diagonal of the room.
    yaw = -math.degrees(math.atan2(W, D))
    obs["Camera"] = scenes._camera((-W / 2 + 0.5, -D / 2 + 0.5, 2.2), (75.0, 0.0, yaw), 16.0, scene)
    scenes._black_world(scene)
    return obs


if __name__ == "__main__":
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else sys.argv[1:]
    n = int(argv[argv.index("--polygons") + 1]) if "--polygons" in argv else 5000
    if "bpy" not in sys.modules and "--save" not in argv:
        s = make_scene(n)
        print(plan(n), "diagonal %.1f m" % scene_diagonal(s))
    else:
        import bpy
        bpy.ops.wm.read_homefile(use_empty=True)
        build_bpy(n)
        if "--save" in argv:
            path = argv[argv.index("--save") + 1]
            bpy.ops.wm.save_as_mainfile(filepath=bpy.path.abspath(path))
            print("saved", path)

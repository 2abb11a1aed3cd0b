"""Benchmark scenes besides the Cornell box, built procedurally from fixed numbers (two builds are identical).

    import scenes; scenes.build("blockers")      # or "office", "office5k", "scalable", "cornell"
    blender -b --factory-startup --python examples/scenes.py -- --scene office --save office.blend
    blender -b --factory-startup --python examples/scenes.py -- --scene scalable --polygons 20000 --save s.blend

- blockers: a 4 m x 4 m floor under one square area light, with a 4 x 4 grid of floating cubes at two heights
  and a table (top and four thin legs) whose shadows overlap: many small blockers at different distances.
- lattice: the same floor and light with a perforated shade in between: 8 x 8 thin tiles (2 cm) at 1.2 m whose
  overlapping penumbrae make a detailed soft shadow over the whole floor; the case convolution links are for
  (one flat-ish blocker far from a large receiver), where standard refinement has to mesh every penumbra.
- office: a 6 m x 4.5 m x 3 m closed room lit by two area lights under the ceiling, with four desks, four chairs
  and a bookcase, in the spirit of the office scene of Soler and Sillion's Fig. 6. About 830 polygons; the
  figures in docs/benchmark.md were measured on it, so it stays as it is.
- office5k: the same room at the size of that figure -- about 5,000 polygons, four rectangular area lights (one
  over each desk), four desks and chairs finely subdivided, the bookcase and two filing cabinets.
- scalable: examples/scalable_scene.py, an open-plan office whose polygon count is a parameter (`polygons`).
- classroom: the same generator's classroom layout at 1,000 polygons (12 m x 8 m x 3 m, 13 pupils' desks and
  chairs in rows, standing on the floor, under four rectangular area lights): issue 12's furnished room.
- window: issue 13's example, a closed 4 m x 4 m x 2.5 m room lit from outside only through a 1 m x 1 m window
  with a cross-shaped frame: a SUN lamp (35 degrees up) whose patch falls on the floor and a box, a Sky Texture
  world (sun disc off, its sun where the lamp is), and inside a POINT lamp with a 10 cm radius in a corner.
- uplight: a 5 m x 4 m x 2.8 m room lit only by two area lights facing up 0.4 m under its white ceiling, so that the
  floor, a table and two stools get bounced light only, from a large source brightest over the lamps: the case
  of issue 12's indirect_sources (a reflector as a convolution source).
- light_point, light_spot, light_sun, light_world, light_sky, light_area: one light type each (issue 13's
  benchmark), over the same open scene: a 4 m x 4 m floor, a back wall and a box, which casts the shadow.

Every object has its own materials, so a Cycles bake can take all objects in one call (one material's active
image node is the bake target, and sharing it would make objects overwrite each other's lightmap).
"""
import math
import os
import sys

import bpy
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import cornell_box  # noqa: E402

LIGHT_SCENES = ("light_point", "light_spot", "light_sun", "light_world", "light_sky", "light_area")
SCENES = ("cornell", "office", "office5k", "blockers", "lattice", "scalable", "classroom", "window",
          "uplight", "vault") + LIGHT_SCENES
CLASSROOM_POLYGONS = 1000


def _diffuse(name, color):
    return cornell_box._diffuse(name, color)


class MeshBuilder:
    """Quads with a material index, merged into one mesh object."""

    def __init__(self):
        self.verts, self.faces, self.mat_index = [], [], []

    def grid(self, origin, u, v, nu, nv, mat=0):
        """Quads on origin + s*u + t*v, front normal u x v."""
        verts, faces = cornell_box._grid(origin, u, v, nu, nv)
        base = len(self.verts)
        self.verts += [tuple(p) for p in verts]
        self.faces += [tuple(k + base for k in f) for f in faces]
        self.mat_index += [mat] * len(faces)

    def box(self, lo, hi, mat=0, divisions=(1, 1, 1), bottom=True):
        """An axis-aligned closed box with outward normals; `divisions` cut the faces along x, y, z."""
        (x0, y0, z0), (x1, y1, z1) = lo, hi
        dx, dy, dz = x1 - x0, y1 - y0, z1 - z0
        nx, ny, nz = divisions
        self.grid((x0, y0, z1), (dx, 0, 0), (0, dy, 0), nx, ny, mat)          # top +z
        if bottom:
            self.grid((x0, y0, z0), (0, dy, 0), (dx, 0, 0), ny, nx, mat)      # bottom -z
        self.grid((x0, y0, z0), (dx, 0, 0), (0, 0, dz), nx, nz, mat)          # -y
        self.grid((x1, y1, z0), (-dx, 0, 0), (0, 0, dz), nx, nz, mat)         # +y
        self.grid((x0, y1, z0), (0, -dy, 0), (0, 0, dz), ny, nz, mat)         # -x
        self.grid((x1, y0, z0), (0, dy, 0), (0, 0, dz), ny, nz, mat)          # +x

    def build(self, name, materials, scene=None):
        me = bpy.data.meshes.new(name)
        me.from_pydata(self.verts, [], self.faces)
        for m in materials:
            me.materials.append(m)
        me.polygons.foreach_set("material_index", np.array(self.mat_index, np.int32))
        me.validate()
        me.update()
        ob = bpy.data.objects.new(name, me)
        (scene or bpy.context.scene).collection.objects.link(ob)
        return ob


def _area_light(name, size, energy, location, color=(1.0, 1.0, 1.0), scene=None):
    light = bpy.data.lights.new(name, "AREA")
    light.shape = "SQUARE"
    light.size = size
    light.energy = energy
    light.color = color
    ob = bpy.data.objects.new(name, light)
    ob.location = location          # faces down (local -Z) with no rotation
    (scene or bpy.context.scene).collection.objects.link(ob)
    return ob


def _camera(location, rotation_deg, lens, scene):
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    cam.data.lens = lens
    cam.location = location
    cam.rotation_euler = tuple(math.radians(a) for a in rotation_deg)
    scene.collection.objects.link(cam)
    scene.camera = cam
    return cam


def _black_world(scene):
    world = bpy.data.worlds.new("Black")
    world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (0, 0, 0, 1)
    world.node_tree.nodes["Background"].inputs["Strength"].default_value = 0.0
    world.color = (0, 0, 0)
    scene.world = world


def _floor(material, scene):
    """The 4 m x 4 m floor of the blocker and lattice scenes, in 16 x 16 faces."""
    floor = MeshBuilder()
    floor.grid((-2, -2, 0), (4, 0, 0), (0, 4, 0), 16, 16)
    return floor.build("Floor", [_diffuse(material, (0.7, 0.7, 0.7))], scene)


def _light_and_camera(obs, scene):
    """A 1 m square area light 2.5 m above that floor, the camera looking at it, a black world."""
    obs["Light"] = _area_light("Light", 1.0, 400.0, (0.0, 0.0, 2.5), scene=scene)
    obs["Camera"] = _camera((0.0, -5.2, 3.6), (55.0, 0.0, 0.0), 32.0, scene)
    _black_world(scene)
    return obs


def build_blockers(scene=None):
    scene = scene or bpy.context.scene
    obs = {"Floor": _floor("FloorWhite", scene)}
    cubes = MeshBuilder()
    for i in range(4):
        for j in range(4):
            x, y = -1.05 + 0.7 * i, -1.05 + 0.7 * j
            z = 0.35 if (i + j) % 2 == 0 else 0.8      # two heights: penumbrae of different widths overlap
            h = 0.12 + 0.03 * ((i * 3 + j) % 3)
            cubes.box((x - h, y - h, z), (x + h, y + h, z + 2 * h), mat=(i + j) % 2)
    obs["Cubes"] = cubes.build("Cubes", [_diffuse("CubeOrange", (0.75, 0.4, 0.15)),
                                         _diffuse("CubeBlue", (0.2, 0.35, 0.7))], scene)
    table = MeshBuilder()
    table.box((-0.9, 0.9, 0.6), (0.9, 1.7, 0.65), divisions=(6, 3, 1))
    for x in (-0.85, 0.8):
        for y in (0.95, 1.6):
            table.box((x, y, 0.0), (x + 0.05, y + 0.05, 0.6), bottom=False)
    obs["Table"] = table.build("Table", [_diffuse("TableWood", (0.55, 0.4, 0.25))], scene)
    return _light_and_camera(obs, scene)


def _lattice_shade(material, scene):
    """64 thin 0.18 m tiles on a 0.3 m pitch, 1.2 m up: the shade of the lattice and vault scenes."""
    shade = MeshBuilder()
    pitch, tile, z = 0.3, 0.18, 1.2
    for i in range(8):
        for j in range(8):
            x, y = (i - 3.5) * pitch, (j - 3.5) * pitch
            shade.box((x - tile / 2, y - tile / 2, z), (x + tile / 2, y + tile / 2, z + 0.02))
    return shade.build("Shade", [_diffuse(material, (0.5, 0.5, 0.5))], scene)


def build_lattice(scene=None):
    scene = scene or bpy.context.scene
    obs = {"Floor": _floor("LatticeFloor", scene), "Shade": _lattice_shade("LatticeShade", scene)}
    return _light_and_camera(obs, scene)


def build_vault(scene=None):
    """The lattice scene's shade and light over a curved floor instead of a flat one: a 4 m x 4 m dome
    z = 0.25 cos(pi x / 4) cos(pi y / 4) in 8 x 8 cells of two triangles (one object, no face in the plane of
    another), the receiver the cluster_receivers setting is for (issue 12: curved receivers)."""
    scene = scene or bpy.context.scene
    n, verts, faces = 8, [], []
    for j in range(n + 1):
        for i in range(n + 1):
            x, y = -2 + 4 * i / n, -2 + 4 * j / n
            verts.append((x, y, 0.25 * math.cos(math.pi * x / 4) * math.cos(math.pi * y / 4)))
    for j in range(n):
        for i in range(n):
            a, b, c, d = j * (n + 1) + i, j * (n + 1) + i + 1, (j + 1) * (n + 1) + i + 1, (j + 1) * (n + 1) + i
            faces += [(a, b, c), (a, c, d)]
    me = bpy.data.meshes.new("Floor")
    me.from_pydata(verts, [], faces)
    me.materials.append(_diffuse("VaultFloor", (0.7, 0.7, 0.7)))
    me.validate()
    me.update()
    floor = bpy.data.objects.new("Floor", me)
    scene.collection.objects.link(floor)
    obs = {"Floor": floor, "Shade": _lattice_shade("VaultShade", scene)}
    return _light_and_camera(obs, scene)


def _office_room(W, D, H, faces, prefix, scene):
    """A closed W x D x H room facing inward, with faces = (along x, along y, along z) faces per side."""
    nx, ny, nz = faces
    room = MeshBuilder()
    room.grid((-W / 2, -D / 2, 0), (W, 0, 0), (0, D, 0), nx, ny, mat=0)           # floor, +z
    room.grid((-W / 2, -D / 2, H), (0, D, 0), (W, 0, 0), ny, nx, mat=2)           # ceiling, -z
    room.grid((-W / 2, D / 2, 0), (W, 0, 0), (0, 0, H), nx, nz, mat=1)            # back wall, -y
    room.grid((W / 2, -D / 2, 0), (0, 0, H), (0, D, 0), nz, ny, mat=1)            # right wall, -x
    room.grid((-W / 2, -D / 2, 0), (0, D, 0), (0, 0, H), ny, nz, mat=3)           # left wall, +x
    room.grid((-W / 2, -D / 2, 0), (0, 0, H), (W, 0, 0), nz, nx, mat=1)           # front wall, +y
    return room.build("Room", [_diffuse(prefix + "Floor", (0.45, 0.35, 0.25)),
                               _diffuse(prefix + "Wall", (0.75, 0.75, 0.72)),
                               _diffuse(prefix + "Ceiling", (0.8, 0.8, 0.8)),
                               _diffuse(prefix + "Accent", (0.6, 0.25, 0.2))], scene)


def build_office(scene=None):
    scene = scene or bpy.context.scene
    W, D, H = 6.0, 4.5, 3.0
    obs = {}
    # Inward-facing walls, cut into 0.5 m faces so per-face errors resolve the light's falloff.
    obs["Room"] = _office_room(W, D, H, (12, 9, 6), "Office", scene)
    fur = MeshBuilder()
    for cx in (-1.4, 1.4):
        for cy in (-0.6, 0.9):
            fur.box((cx - 0.7, cy - 0.4, 0.72), (cx + 0.7, cy + 0.4, 0.76), mat=0, divisions=(4, 2, 1))
            for sx in (-0.65, 0.6):
                for sy in (-0.35, 0.3):
                    fur.box((cx + sx, cy + sy, 0.0), (cx + sx + 0.05, cy + sy + 0.05, 0.72), mat=0,
                            bottom=False)
            # A chair in front of each desk: seat, back and four legs.
            ch = cy - 0.75
            fur.box((cx - 0.22, ch - 0.22, 0.42), (cx + 0.22, ch + 0.22, 0.46), mat=1)
            fur.box((cx - 0.22, ch - 0.26, 0.46), (cx + 0.22, ch - 0.22, 0.9), mat=1)
            for sx in (-0.2, 0.17):
                for sy in (-0.2, 0.17):
                    fur.box((cx + sx, ch + sy, 0.0), (cx + sx + 0.03, ch + sy + 0.03, 0.42), mat=1, bottom=False)
    # A bookcase against the back wall: a closed box with three shelves' worth of fronts.
    fur.box((-1.0, D / 2 - 0.35, 0.0), (1.0, D / 2 - 0.01, 1.9), mat=2, divisions=(4, 1, 4), bottom=False)
    obs["Furniture"] = fur.build("Furniture", [_diffuse("Desk", (0.55, 0.4, 0.25)),
                                               _diffuse("Chair", (0.15, 0.2, 0.45)),
                                               _diffuse("Bookcase", (0.35, 0.3, 0.28))], scene)
    obs["Light1"] = _area_light("Light1", 0.8, 300.0, (-1.4, 0.2, H - 0.05), (1.0, 0.95, 0.85), scene)
    obs["Light2"] = _area_light("Light2", 0.8, 300.0, (1.4, 0.2, H - 0.05), (1.0, 0.95, 0.85), scene)
    obs["Camera"] = _camera((-2.6, -2.0, 2.2), (70.0, 0.0, -52.0), 18.0, scene)
    _black_world(scene)
    return obs


def build_uplight(scene=None):
    scene = scene or bpy.context.scene
    W, D, H = 5.0, 4.0, 2.8
    obs = {"Room": _office_room(W, D, H, (10, 8, 6), "Uplight", scene)}
    fur = MeshBuilder()
    fur.box((-0.8, -0.5, 0.72), (0.8, 0.5, 0.76), mat=0, divisions=(4, 2, 1))     # table top
    for sx in (-0.75, 0.7):
        for sy in (-0.45, 0.4):
            fur.box((sx, sy, 0.0), (sx + 0.05, sy + 0.05, 0.72), mat=0, bottom=False)
    for cx in (-1.6, 1.6):                                                          # two stools
        fur.box((cx - 0.2, -0.2, 0.0), (cx + 0.2, 0.2, 0.45), mat=1, bottom=False)
    obs["Furniture"] = fur.build("Furniture", [_diffuse("UplightTable", (0.6, 0.45, 0.3)),
                                               _diffuse("UplightStool", (0.2, 0.3, 0.5))], scene)
    for i, x in enumerate((-1.2, 1.2)):
        lamp = _area_light(f"Uplight{i + 1}", 0.6, 300.0, (x, 0.0, H - 0.4), scene=scene)
        lamp.rotation_euler = (math.pi, 0.0, 0.0)   # facing up: the floor sees none of it
        obs[lamp.name] = lamp
    obs["Camera"] = _camera((-2.2, -1.8, 2.0), (70.0, 0.0, -50.0), 18.0, scene)
    _black_world(scene)
    return obs


def build_office5k(scene=None):
    scene = scene or bpy.context.scene
    W, D, H = 6.0, 4.5, 3.0
    obs = {}
    # 0.2 m faces everywhere (22.5 along the depth rounds to 22): about 2,900 of the 5,000 polygons.
    obs["Room"] = _office_room(W, D, H, (30, 22, 15), "Office5k", scene)
    fur = MeshBuilder()
    desks = [(cx, cy) for cx in (-1.4, 1.4) for cy in (-0.6, 0.9)]
    for cx, cy in desks:
        # 10 cm faces on the desk tops, where the chairs' and the other desks' shadows fall.
        fur.box((cx - 0.7, cy - 0.4, 0.72), (cx + 0.7, cy + 0.4, 0.76), mat=0, divisions=(14, 8, 1))
        for sx in (-0.65, 0.6):
            for sy in (-0.35, 0.3):
                fur.box((cx + sx, cy + sy, 0.0), (cx + sx + 0.05, cy + sy + 0.05, 0.72), mat=0, bottom=False)
        ch = cy - 0.75
        fur.box((cx - 0.22, ch - 0.22, 0.42), (cx + 0.22, ch + 0.22, 0.46), mat=1, divisions=(5, 5, 1))
        fur.box((cx - 0.22, ch - 0.26, 0.46), (cx + 0.22, ch - 0.22, 0.9), mat=1, divisions=(5, 1, 5))
        for sx in (-0.2, 0.17):
            for sy in (-0.2, 0.17):
                fur.box((cx + sx, ch + sy, 0.0), (cx + sx + 0.03, ch + sy + 0.03, 0.42), mat=1, bottom=False)
    fur.box((-1.0, D / 2 - 0.35, 0.0), (1.0, D / 2 - 0.01, 1.9), mat=2, divisions=(8, 2, 8), bottom=False)
    for y0 in (-1.6, -0.95):
        fur.box((W / 2 - 0.61, y0, 0.0), (W / 2 - 0.01, y0 + 0.5, 1.2), mat=3, divisions=(2, 3, 6),
                bottom=False)
    obs["Furniture"] = fur.build("Furniture", [_diffuse("Desk5k", (0.55, 0.4, 0.25)),
                                               _diffuse("Chair5k", (0.15, 0.2, 0.45)),
                                               _diffuse("Bookcase5k", (0.35, 0.3, 0.28)),
                                               _diffuse("Cabinet5k", (0.5, 0.52, 0.55))], scene)
    # Four rectangular panels, one over each desk, with the office scene's total power (600 W).
    for k, (cx, cy) in enumerate(desks):
        name = f"Light{k + 1}"
        ob = _area_light(name, 1.2, 150.0, (cx, cy, H - 0.05), (1.0, 0.95, 0.85), scene)
        ob.data.shape = "RECTANGLE"
        ob.data.size_y = 0.4
        obs[name] = ob
    obs["Camera"] = _camera((-2.6, -2.0, 2.2), (70.0, 0.0, -52.0), 18.0, scene)
    _black_world(scene)
    return obs


def _lamp(name, kind, location, toward=None, scene=None, **props):
    """A light of `kind` at `location`, its local -Z (where Blender lights shine) along `toward` when given."""
    from mathutils import Vector
    light = bpy.data.lights.new(name, kind)
    for k, v in props.items():
        setattr(light, k, v)
    ob = bpy.data.objects.new(name, light)
    ob.location = location
    if toward is not None:
        ob.rotation_euler = Vector(toward).to_track_quat("-Z", "Y").to_euler()
    (scene or bpy.context.scene).collection.objects.link(ob)
    return ob


def _sky_world(scene, strength, elevation, azimuth):
    """A Sky Texture world (the running Blender's default sky type) without its sun disc: the disc is the SUN
    lamp's job (with the disc on, the export takes it out of the map and sends a lamp of its own, which would
    light the room twice). Its sun stands where `elevation` and `azimuth` (radians, azimuth from +x towards +y)
    say, the lamp's direction: Cycles puts a Sky Texture's sun at (cos e sin r, cos e cos r, sin e) for
    sun_rotation r (r turns clockwise from +y), so r = 90 degrees - azimuth (blender_tests/test_window_example.py
    finds the disc in Cycles' render of this world)."""
    world = bpy.data.worlds.new("Sky")
    world.use_nodes = True
    nt = world.node_tree
    sky = nt.nodes.new("ShaderNodeTexSky")
    if hasattr(sky, "sun_disc"):
        sky.sun_disc = False
    if hasattr(sky, "sun_elevation"):
        sky.sun_elevation = elevation
        sky.sun_rotation = math.pi / 2 - azimuth
    nt.links.new(sky.outputs["Color"], nt.nodes["Background"].inputs["Color"])
    nt.nodes["Background"].inputs["Strength"].default_value = strength
    scene.world = world
    return world


# The window scene's sun: 35 degrees up, from +x turned 20 degrees towards +y; its patch through the window
# (x = 2, y in [-0.5, 0.5], z in [1, 2]) falls on the floor around (0, -0.7) and on the box standing there.
WINDOW_SUN_ELEVATION = math.radians(35.0)
WINDOW_SUN_AZIMUTH = math.radians(20.0)


def build_window(scene=None):
    scene = scene or bpy.context.scene
    W, H = 2.0, 2.5                       # the room spans x, y in [-W, W] and z in [0, H]
    white, obs = (0.75, 0.75, 0.75), {}
    room = MeshBuilder()
    # Inward-facing floor, ceiling and three walls in 0.5 m faces.
    room.grid((-W, -W, 0), (2 * W, 0, 0), (0, 2 * W, 0), 8, 8, 0)                 # floor, +z
    room.grid((-W, -W, H), (0, 2 * W, 0), (2 * W, 0, 0), 8, 8, 1)                 # ceiling, -z
    room.grid((-W, -W, 0), (0, 0, H), (2 * W, 0, 0), 5, 8, 2)                     # y = -W, +y
    room.grid((W, W, 0), (0, 0, H), (-2 * W, 0, 0), 5, 8, 2)                      # y = +W, -y
    room.grid((-W, W, 0), (0, 0, H), (0, -2 * W, 0), 5, 8, 2)                     # x = -W, +x
    obs["Room"] = room.build("Room", [_diffuse("WindowFloor", (0.6, 0.45, 0.3)),
                                      _diffuse("WindowCeiling", white),
                                      _diffuse("WindowWalls", white)], scene)
    # The window wall (x = +W, facing -x) in 0.25 m faces with the window's 4 x 4 faces left out.
    wall = MeshBuilder()
    verts, faces = cornell_box._grid((W, -W, 0), (0, 0, H), (0, 2 * W, 0), 10, 16,
                                     skip=lambda i, j: 4 <= i < 8 and 6 <= j < 10)
    verts, faces = cornell_box._compact(verts, faces)
    wall.verts += [tuple(p) for p in verts]
    wall.faces += faces
    wall.mat_index += [0] * len(faces)
    obs["WindowWall"] = wall.build("WindowWall", [_diffuse("WindowWallWhite", white)], scene)
    # A cross-shaped frame in the opening (6 cm bars, 8 cm deep) and a box on the floor in the sun patch.
    frame = MeshBuilder()
    frame.box((W - 0.04, -0.03, 1.0), (W + 0.04, 0.03, 2.0))
    frame.box((W - 0.04, -0.5, 1.47), (W + 0.04, -0.03, 1.53))
    frame.box((W - 0.04, 0.03, 1.47), (W + 0.04, 0.5, 1.53))
    obs["Frame"] = frame.build("Frame", [_diffuse("WindowFrame", (0.35, 0.35, 0.35))], scene)
    box = MeshBuilder()
    box.box((0.1, -1.2, 0.0), (0.6, -0.7, 0.5), bottom=False)
    obs["Box"] = box.build("Box", [_diffuse("WindowBox", (0.2, 0.4, 0.7))], scene)
    e, a = WINDOW_SUN_ELEVATION, WINDOW_SUN_AZIMUTH
    to_sun = (math.cos(e) * math.cos(a), math.cos(e) * math.sin(a), math.sin(e))
    obs["Sun"] = _lamp("Sun", "SUN", (4.0, 1.5, 4.0), toward=tuple(-c for c in to_sun), scene=scene,
                       energy=6.0, angle=math.radians(1.0), color=(1.0, 0.95, 0.85))
    obs["Lamp"] = _lamp("Lamp", "POINT", (-1.5, 1.5, 1.9), scene=scene, energy=40.0, shadow_soft_size=0.1,
                        color=(1.0, 0.8, 0.6))
    _sky_world(scene, 0.3, e, a)
    obs["Camera"] = _camera((-1.85, -1.85, 1.5), (80.0, 0.0, -50.0), 16.0, scene)
    return obs


def build_light(kind, scene=None):
    """The light-type benchmark scene: a 4 m x 4 m floor (16 x 16 faces), a 4 m x 2 m back wall at y = 2 and a
    0.6 m box, lit by one light of `kind` (point, spot, sun, world, sky or area) and nothing else."""
    scene = scene or bpy.context.scene
    obs = {"Floor": _floor(f"Floor_{kind}", scene)}
    wall = MeshBuilder()
    wall.grid((-2, 2, 0), (4, 0, 0), (0, 0, 2), 16, 8)                            # faces -y
    obs["Wall"] = wall.build("Wall", [_diffuse(f"Wall_{kind}", (0.7, 0.6, 0.5))], scene)
    box = MeshBuilder()
    box.box((-0.5, -0.1, 0.0), (0.1, 0.5, 0.6), divisions=(2, 2, 2), bottom=False)
    obs["Box"] = box.build("Box", [_diffuse(f"Box_{kind}", (0.3, 0.5, 0.7))], scene)
    _black_world(scene)
    if kind == "point":
        obs["Light"] = _lamp("Light", "POINT", (0.6, -0.6, 1.8), scene=scene, energy=300.0, shadow_soft_size=0.1)
    elif kind == "spot":
        obs["Light"] = _lamp("Light", "SPOT", (1.2, -1.2, 2.2), toward=(-0.5, 0.5, -1.0), scene=scene,
                             energy=600.0, shadow_soft_size=0.1, spot_size=math.radians(70.0), spot_blend=0.3)
    elif kind == "sun":
        obs["Light"] = _lamp("Light", "SUN", (0.0, 0.0, 4.0), toward=(-0.4, 0.5, -1.0), scene=scene,
                             energy=3.0, angle=math.radians(3.0))
    elif kind == "world":
        w = scene.world
        w.node_tree.nodes["Background"].inputs["Color"].default_value = (0.8, 0.9, 1.0, 1)
        w.node_tree.nodes["Background"].inputs["Strength"].default_value = 1.0
    elif kind == "sky":
        # Its sun 35 degrees up towards -x, -y, on the open side facing the wall (sun_rotation -140 degrees,
        # the sky docs/benchmark.md measured).
        _sky_world(scene, 0.3, math.radians(35.0), math.radians(230.0))
    elif kind == "area":
        obs["Light"] = _area_light("Light", 1.0, 400.0, (0.6, -0.6, 2.0), scene=scene)
    else:
        raise ValueError(f"unknown light kind {kind!r}")
    obs["Camera"] = _camera((0.0, -5.2, 3.6), (55.0, 0.0, 0.0), 32.0, scene)
    return obs


def build(name, scene=None, polygons=5000):
    """Build a scene into the current (empty) file; returns {name: object}. `polygons` sizes "scalable"."""
    if name == "cornell":
        return cornell_box.build(scene)
    if name == "office":
        return build_office(scene)
    if name == "office5k":
        return build_office5k(scene)
    if name == "scalable":
        import scalable_scene
        return scalable_scene.build_bpy(polygons, scene)
    if name == "classroom":
        import scalable_scene
        return scalable_scene.build_bpy(CLASSROOM_POLYGONS, scene, layout="classroom")
    if name == "blockers":
        return build_blockers(scene)
    if name == "uplight":
        return build_uplight(scene)
    if name == "lattice":
        return build_lattice(scene)
    if name == "vault":
        return build_vault(scene)
    if name == "window":
        return build_window(scene)
    if name in LIGHT_SCENES:
        return build_light(name[len("light_"):], scene)
    raise ValueError(f"unknown scene {name!r}; known: {', '.join(SCENES)}")


if __name__ == "__main__":
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    which = argv[argv.index("--scene") + 1] if "--scene" in argv else "office"
    polygons = int(argv[argv.index("--polygons") + 1]) if "--polygons" in argv else 5000
    cornell_box.clear_scene()
    build(which, polygons=polygons)
    if "--save" in argv:
        path = argv[argv.index("--save") + 1]
        bpy.ops.wm.save_as_mainfile(filepath=bpy.path.abspath(path))
        print("saved", path)

"""Validation corpus (issue 11): small closed rooms, each built around one geometric situation that a radiosity
solver can get wrong while Cycles gets it right. Procedural, from fixed numbers: two builds are identical.

    import validation_scenes; validation_scenes.build("lamp_gap_5mm")
    blender -b --factory-startup --python examples/validation_scenes.py -- --scene stacked_rooms --save s.blend

Unless stated, the room is 4 m (x) x 3 m (y) x 2.6 m (z), x, y centred on the origin, floor at z = 0, built as
three inward-facing objects -- Floor, Ceiling, Walls (each wall, the floor and the ceiling one quad, as a user
would model a room; the walls hold one white-ish and two coloured materials) -- with a black world. Albedos are
about 0.7 for white surfaces. The standard lamp is an emissive mesh panel (Emission shader, strength 10, cut in
4 x 4 faces, 0.5 m x 0.5 m, facing down), which Cycles makes two-sided: its back lights the ceiling too.

- lamp_gap_1mm, lamp_gap_5mm, lamp_gap_2cm, lamp_gap_10cm: the panel hangs that far under the ceiling at the
  room's centre. The ceiling above it gets almost the panel's full irradiance (E = pi S, so B ~ rho S), inside
  a patch about the panel's size; light must not leak through the ceiling or vanish into the gap.
- lamp_gap_5mm_cut: lamp_gap_5mm with the room cut into 0.5 m faces: the same light transport, so the same
  Cycles answer; a bake that differs between the two depends on how the input mesh is cut.
- area_gap_5mm: the same room with a Blender AREA light (square, 0.5 m, 10 W, one-sided, facing down) 5 mm
  under the ceiling instead of the panel.
- sconce_1cm: a small emissive box (0.24 x 0.12 x 0.16 m, strength 20) 1 cm in front of the back wall at
  1.8 m: its back face lights a wall patch 1 cm away.
- desk_lamp: a desk (top 1.4 x 0.7 m at 0.75 m, four legs) against the left wall half, and a small two-sided
  emissive quad (0.15 m square, strength 60) 2 cm above the desk top; the only light.
- stacked_rooms: two closed rooms stacked; the lower one (z 0..2.6) is lit by the panel 20 cm under its
  ceiling, the upper one (z 2.61..5.21) is sealed and dark. Their walls lie in the same planes and the slab
  between the lower ceiling and the upper floor is 1 cm. Cycles gives exactly 0 in the upper room.
- contacts: the panel 30 cm under the ceiling; two boxes resting on the floor (one 0.6 m cube, one low
  1.0 x 0.5 x 0.3 box), a box pushed against the right wall (touching it and the floor), a bookcase-like box
  (1.2 x 0.35 x 1.8 m) 1 cm in front of the back wall.
- thin_sheet: the panel 30 cm under the ceiling; a zero-thickness sheet (single plane, 1.0 x 0.8 m) hanging
  at 1.6 m on one side of the lamp, and a 2 mm thick slab of the same size at 1.3 m on the other.
- curved: the panel 30 cm under the ceiling; a UV sphere (r 0.4 m, 32 x 16) resting on the floor and a
  cylinder (r 0.25 m, 1.0 m tall, 32 sides, capped) standing on the floor.
- small_lamp: a very bright emissive cube of 5 cm (strength 3000) at (0.4, 0.3, 1.5) in the room; nothing else
  emits.
- cornell: the main job's Cornell box (examples/cornell_box.py), scored per texel like the others.

Every object has its own materials, so a Cycles bake can take all objects in one call. Each scene has a camera
(the stacked rooms' looks around the sealed upper room), denoising is off (Debian's Cycles has no
OpenImageDenoise) and the render engine is Cycles.
"""
import math
import os
import sys

import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import cornell_box  # noqa: E402
from scenes import MeshBuilder, _area_light, _black_world, _camera, _diffuse  # noqa: E402

SCENES = ("lamp_gap_1mm", "lamp_gap_5mm", "lamp_gap_2cm", "lamp_gap_10cm", "lamp_gap_5mm_cut", "area_gap_5mm",
          "sconce_1cm", "desk_lamp", "stacked_rooms", "contacts", "thin_sheet", "curved", "small_lamp", "cornell",
          "point_spot", "sun_window")

W, D, H = 4.0, 3.0, 2.6           # room size (x, y, z)
CUT_FACE = 0.5                     # face size of lamp_gap_5mm_cut's room; the others' surfaces are single quads
LAMP_HALF = 0.25                   # the panel is 0.5 m x 0.5 m
LAMP_STRENGTH = 10.0
LAMP_COLOR = (1.0, 0.95, 0.85)
WHITE = (0.7, 0.7, 0.7)
FLOOR = (0.6, 0.55, 0.45)
CEILING = (0.75, 0.75, 0.75)
RED = (0.7, 0.3, 0.25)
BLUE = (0.3, 0.4, 0.7)
GAPS = {"lamp_gap_1mm": 0.001, "lamp_gap_5mm": 0.005, "lamp_gap_2cm": 0.02, "lamp_gap_10cm": 0.10}


def _emission(name, color, strength):
    return cornell_box._emission(name, color, strength)


def _divisions(length, face):
    return 1 if face is None else max(1, int(round(length / face)))


def room(prefix="", z0=0.0, scene=None, size=(W, D, H), face=None):
    """A closed room facing inward as three objects <prefix>Floor, <prefix>Ceiling, <prefix>Walls; the walls'
    materials: white (back and front), red (left, -x) and blue (right, +x). Each surface is one quad, or cut into
    faces of about `face` metres."""
    w, d, h = size
    nx, ny, nz = _divisions(w, face), _divisions(d, face), _divisions(h, face)
    x0, y0 = -w / 2, -d / 2
    obs = {}
    fl = MeshBuilder()
    fl.grid((x0, y0, z0), (w, 0, 0), (0, d, 0), nx, ny)                       # normal +z
    obs[prefix + "Floor"] = fl.build(prefix + "Floor", [_diffuse(prefix + "FloorMat", FLOOR)], scene)
    ce = MeshBuilder()
    ce.grid((x0, y0, z0 + h), (0, d, 0), (w, 0, 0), ny, nx)                   # normal -z
    obs[prefix + "Ceiling"] = ce.build(prefix + "Ceiling", [_diffuse(prefix + "CeilingMat", CEILING)], scene)
    wa = MeshBuilder()
    wa.grid((x0, -y0, z0), (w, 0, 0), (0, 0, h), nx, nz, mat=0)              # back (+y), normal -y
    wa.grid((x0, y0, z0), (0, 0, h), (w, 0, 0), nz, nx, mat=0)               # front (-y), normal +y
    wa.grid((x0, y0, z0), (0, d, 0), (0, 0, h), ny, nz, mat=1)               # left (-x), normal +x
    wa.grid((-x0, y0, z0), (0, 0, h), (0, d, 0), nz, ny, mat=2)              # right (+x), normal -x
    obs[prefix + "Walls"] = wa.build(prefix + "Walls", [_diffuse(prefix + "WallWhite", WHITE),
                                                        _diffuse(prefix + "WallRed", RED),
                                                        _diffuse(prefix + "WallBlue", BLUE)], scene)
    return obs


def panel(name, center, half, strength, scene=None, color=LAMP_COLOR, cuts=4):
    """A horizontal emissive quad facing down (normal -z), cut into cuts x cuts faces (Cycles samples a big
    two-triangle emitter with a small bias); Cycles' mesh emission is two-sided."""
    cx, cy, cz = center
    b = MeshBuilder()
    b.grid((cx - half, cy - half, cz), (0, 2 * half, 0), (2 * half, 0, 0), cuts, cuts)
    return b.build(name, [_emission(name + "Emission", color, strength)], scene)


def _finish(obs, scene, cam_location, cam_rotation, lens=16.0):
    obs["Camera"] = _camera(cam_location, cam_rotation, lens, scene)
    _black_world(scene)
    scene.render.engine = "CYCLES"
    scene.cycles.use_denoising = False
    for vl in scene.view_layers:
        vl.cycles.use_denoising = False
    return obs


def _room_camera(obs, scene, z0=0.0):
    """Looking from the front-left corner towards the back-right, slightly down."""
    return _finish(obs, scene, (-1.75, -1.3, z0 + 1.7), (78.0, 0.0, -50.0))


def build_lamp_gap(gap, scene=None, face=None):
    scene = scene or bpy.context.scene
    obs = room(scene=scene, face=face)
    obs["Lamp"] = panel("Lamp", (0.0, 0.0, H - gap), LAMP_HALF, LAMP_STRENGTH, scene)
    return _room_camera(obs, scene)


def build_area_gap(gap=0.005, scene=None):
    scene = scene or bpy.context.scene
    obs = room(scene=scene)
    obs["Light"] = _area_light("Light", 2 * LAMP_HALF, 10.0, (0.0, 0.0, H - gap), LAMP_COLOR, scene)
    return _room_camera(obs, scene)


def build_sconce(scene=None):
    scene = scene or bpy.context.scene
    obs = room(scene=scene)
    b = MeshBuilder()
    yb = D / 2 - 0.01                                   # 1 cm in front of the back wall
    b.box((-0.12, yb - 0.12, 1.72), (0.12, yb, 1.88), divisions=(2, 1, 1))
    obs["Sconce"] = b.build("Sconce", [_emission("SconceEmission", LAMP_COLOR, 20.0)], scene)
    return _room_camera(obs, scene)


def build_desk_lamp(scene=None):
    scene = scene or bpy.context.scene
    obs = room(scene=scene)
    desk = MeshBuilder()
    x0, x1, y0, y1, top = -1.9, -0.5, -0.2, 0.5, 0.75
    desk.box((x0, y0, top - 0.04), (x1, y1, top), divisions=(7, 4, 1))
    for x in (x0 + 0.02, x1 - 0.07):
        for y in (y0 + 0.02, y1 - 0.07):
            desk.box((x, y, 0.0), (x + 0.05, y + 0.05, top - 0.04), bottom=False)
    obs["Desk"] = desk.build("Desk", [_diffuse("DeskWood", (0.55, 0.4, 0.25))], scene)
    obs["Lamp"] = panel("Lamp", (-1.2, 0.15, top + 0.02), 0.075, 60.0, scene, cuts=2)
    return _room_camera(obs, scene)


def build_stacked_rooms(scene=None):
    scene = scene or bpy.context.scene
    obs = room("Lower", 0.0, scene)
    obs.update(room("Upper", H + 0.01, scene))
    obs["Lamp"] = panel("Lamp", (0.0, 0.0, H - 0.2), LAMP_HALF, LAMP_STRENGTH, scene)
    # The camera stands in the sealed upper room: Cycles shows it black, a leak shows as light.
    return _finish(obs, scene, (-1.75, -1.3, H + 0.01 + 1.7), (78.0, 0.0, -50.0))


def build_contacts(scene=None):
    scene = scene or bpy.context.scene
    obs = room(scene=scene)
    obs["Lamp"] = panel("Lamp", (0.0, 0.0, H - 0.3), LAMP_HALF, LAMP_STRENGTH, scene)
    specs = [("Cube", (-1.2, -0.9, 0.0), (-0.6, -0.3, 0.6), (0.65, 0.65, 0.65), (2, 2, 2)),
             ("LowBox", (0.1, -1.0, 0.0), (1.1, -0.5, 0.3), (0.7, 0.5, 0.3), (2, 1, 1)),
             ("WallBox", (W / 2 - 0.5, 0.2, 0.0), (W / 2, 0.9, 0.8), (0.3, 0.55, 0.3), (1, 2, 2)),
             ("Bookcase", (-0.6, D / 2 - 0.36, 0.0), (0.6, D / 2 - 0.01, 1.8), (0.45, 0.35, 0.3), (3, 1, 4))]
    for name, lo, hi, color, div in specs:
        b = MeshBuilder()
        b.box(lo, hi, divisions=div)
        obs[name] = b.build(name, [_diffuse(name + "Mat", color)], scene)
    return _room_camera(obs, scene)


def build_thin_sheet(scene=None):
    scene = scene or bpy.context.scene
    obs = room(scene=scene)
    obs["Lamp"] = panel("Lamp", (0.0, 0.0, H - 0.3), LAMP_HALF, LAMP_STRENGTH, scene)
    sheet = MeshBuilder()
    sheet.grid((-1.6, -0.4, 1.6), (1.0, 0, 0), (0, 0.8, 0), 2, 2)             # one plane, normal +z
    obs["Sheet"] = sheet.build("Sheet", [_diffuse("SheetMat", (0.7, 0.65, 0.6))], scene)
    slab = MeshBuilder()
    slab.box((0.6, -0.4, 1.3), (1.6, 0.4, 1.302), divisions=(2, 2, 1))
    obs["Slab"] = slab.build("Slab", [_diffuse("SlabMat", (0.6, 0.65, 0.7))], scene)
    return _room_camera(obs, scene)


def _sphere(name, center, r, nu, nv, material, scene):
    cx, cy, cz = center
    verts = [(cx, cy, cz - r)]
    for j in range(1, nv):
        t = math.pi * j / nv - math.pi / 2
        for i in range(nu):
            a = 2 * math.pi * i / nu
            verts.append((cx + r * math.cos(t) * math.cos(a), cy + r * math.cos(t) * math.sin(a), cz + r * math.sin(t)))
    verts.append((cx, cy, cz + r))
    top = len(verts) - 1

    def ring(j, i):
        return 1 + (j - 1) * nu + i % nu
    faces = [(0, ring(1, i + 1), ring(1, i)) for i in range(nu)]
    for j in range(1, nv - 1):
        faces += [(ring(j, i), ring(j, i + 1), ring(j + 1, i + 1), ring(j + 1, i)) for i in range(nu)]
    faces += [(ring(nv - 1, i), ring(nv - 1, i + 1), top) for i in range(nu)]
    return _mesh(name, verts, faces, material, scene)


def _cylinder(name, center, r, height, n, material, scene):
    cx, cy, z0 = center
    verts = [(cx + r * math.cos(2 * math.pi * i / n), cy + r * math.sin(2 * math.pi * i / n), z)
             for z in (z0, z0 + height) for i in range(n)]
    faces = [(i, (i + 1) % n, n + (i + 1) % n, n + i) for i in range(n)]
    faces.append(tuple(range(n))[::-1])                      # bottom, normal -z (on the floor)
    faces.append(tuple(range(n, 2 * n)))                     # top, normal +z
    return _mesh(name, verts, faces, material, scene)


def _mesh(name, verts, faces, material, scene):
    me = bpy.data.meshes.new(name)
    me.from_pydata(verts, [], faces)
    me.materials.append(material)
    me.validate()
    me.update()
    ob = bpy.data.objects.new(name, me)
    (scene or bpy.context.scene).collection.objects.link(ob)
    return ob


def build_curved(scene=None):
    scene = scene or bpy.context.scene
    obs = room(scene=scene)
    obs["Lamp"] = panel("Lamp", (0.0, 0.0, H - 0.3), LAMP_HALF, LAMP_STRENGTH, scene)
    obs["Sphere"] = _sphere("Sphere", (-0.8, -0.3, 0.4), 0.4, 32, 16, _diffuse("SphereMat", (0.7, 0.7, 0.7)), scene)
    obs["Cylinder"] = _cylinder("Cylinder", (0.8, 0.4, 0.0), 0.25, 1.0, 32, _diffuse("CylinderMat", (0.7, 0.5, 0.3)),
                                scene)
    return _room_camera(obs, scene)


def build_small_lamp(scene=None):
    scene = scene or bpy.context.scene
    obs = room(scene=scene)
    b = MeshBuilder()
    c, s = (0.4, 0.3, 1.5), 0.025
    b.box(tuple(x - s for x in c), tuple(x + s for x in c))
    obs["Lamp"] = b.build("Lamp", [_emission("LampEmission", LAMP_COLOR, 3000.0)], scene)
    return _room_camera(obs, scene)


def _lamp(name, kind, location, rotation_deg=(0, 0, 0), scene=None, **props):
    light = bpy.data.lights.new(name, kind)
    for k, v in props.items():
        setattr(light, k, v)
    ob = bpy.data.objects.new(name, light)
    ob.location = location
    ob.rotation_euler = tuple(math.radians(a) for a in rotation_deg)
    (scene or bpy.context.scene).collection.objects.link(ob)
    return ob


def build_point_spot(scene=None):
    """The room lit by a 150 W point lamp of radius 10 cm and a 300 W spot (60 degrees, blend 0.3) aimed at the
    right wall: no emitting face at all (issue 13)."""
    scene = scene or bpy.context.scene
    obs = room(scene=scene)
    obs["Bulb"] = _lamp("Bulb", "POINT", (-0.8, 0.3, 2.0), scene=scene, energy=150.0, shadow_soft_size=0.1,
                        color=LAMP_COLOR)
    obs["Spot"] = _lamp("Spot", "SPOT", (0.6, -0.6, 2.4), (0.0, -50.0, 20.0), scene=scene, energy=300.0,
                        shadow_soft_size=0.05, spot_size=math.radians(60), spot_blend=0.3)
    return _room_camera(obs, scene)


def build_sun_window(scene=None):
    """The room with a 1.6 m x 1.1 m window in its front wall (-y), a 3 W/m^2 sun of 2 degrees shining in at 35
    degrees and a uniform blue-grey sky (issue 13)."""
    scene = scene or bpy.context.scene
    w, d, h = W, D, H
    x0, y0 = -w / 2, -d / 2
    obs = {}
    fl = MeshBuilder()
    fl.grid((x0, y0, 0), (w, 0, 0), (0, d, 0), 1, 1)
    obs["Floor"] = fl.build("Floor", [_diffuse("FloorMat", FLOOR)], scene)
    ce = MeshBuilder()
    ce.grid((x0, y0, h), (0, d, 0), (w, 0, 0), 1, 1)
    obs["Ceiling"] = ce.build("Ceiling", [_diffuse("CeilingMat", CEILING)], scene)
    wa = MeshBuilder()
    wa.grid((x0, -y0, 0), (w, 0, 0), (0, 0, h), 1, 1, mat=0)                 # back (+y)
    wa.grid((x0, y0, 0), (0, d, 0), (0, 0, h), 1, 1, mat=1)                  # left (-x)
    wa.grid((-x0, y0, 0), (0, 0, h), (0, d, 0), 1, 1, mat=2)                 # right (+x)
    wx0, wx1, wz0, wz1 = -0.8, 0.8, 0.9, 2.0                                   # the window in the front wall
    for (a, b, c, e) in ((x0, wx0, 0, h), (wx1, -x0, 0, h), (wx0, wx1, 0, wz0), (wx0, wx1, wz1, h)):
        wa.grid((a, y0, c), (0, 0, e - c), (b - a, 0, 0), 1, 1, mat=0)         # front (-y), normal +y
    obs["Walls"] = wa.build("Walls", [_diffuse("WallWhite", WHITE), _diffuse("WallRed", RED),
                                      _diffuse("WallBlue", BLUE)], scene)
    obs["Sun"] = _lamp("Sun", "SUN", (0, -4, 4), (55.0, 0.0, 20.0), scene=scene, energy=3.0,
                       angle=math.radians(2))
    out = _room_camera(obs, scene)
    bg = scene.world.node_tree.nodes["Background"]
    bg.inputs["Color"].default_value = (0.35, 0.45, 0.6, 1)
    bg.inputs["Strength"].default_value = 1.0
    return out


def build(name, scene=None):
    """Build a validation scene into the current (empty) file; returns {name: object}."""
    if name in GAPS:
        return build_lamp_gap(GAPS[name], scene)
    if name == "lamp_gap_5mm_cut":
        return build_lamp_gap(0.005, scene, face=CUT_FACE)
    builders = {"area_gap_5mm": build_area_gap, "sconce_1cm": build_sconce, "desk_lamp": build_desk_lamp,
                "stacked_rooms": build_stacked_rooms, "contacts": build_contacts, "thin_sheet": build_thin_sheet,
                "curved": build_curved, "small_lamp": build_small_lamp, "point_spot": build_point_spot,
                "sun_window": build_sun_window,
                "cornell": lambda scene=None: cornell_box.build(scene)}  # the main job's scene, per texel
    if name not in builders:
        raise ValueError(f"unknown validation scene {name!r}; known: {', '.join(SCENES)}")
    return builders[name](scene=scene)


if __name__ == "__main__":
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    which = argv[argv.index("--scene") + 1] if "--scene" in argv else "lamp_gap_5mm"
    cornell_box.clear_scene()
    build(which)
    if "--save" in argv:
        path = argv[argv.index("--save") + 1]
        bpy.ops.wm.save_as_mainfile(filepath=bpy.path.abspath(path))
        print("saved", path)

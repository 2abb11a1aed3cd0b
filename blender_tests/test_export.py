"""What the export sends, skips and reports."""
import json
import math

import bpy
import numpy as np
import pytest

import cornell_box
import helpers
from penumbra import compat, export, materials


def _export(scene, **kw):
    vl = bpy.context.view_layer
    return export.export_scene(scene, vl, bpy.context.evaluated_depsgraph_get(), **kw)


def test_lamps_and_world_are_exported_and_unreadable_ones_reported_by_name(empty_scene, penumbra):
    cornell_box.build()
    for kind in ("POINT", "SPOT", "SUN"):
        light = bpy.data.lights.new(f"My{kind}", kind)
        ob = bpy.data.objects.new(f"My{kind}Object", light)
        empty_scene.collection.objects.link(ob)
    dark = bpy.data.objects.new("DarkBulb", bpy.data.lights.new("DarkBulb", "POINT"))
    dark.data.energy = 0.0
    empty_scene.collection.objects.link(dark)
    world = empty_scene.world
    world.node_tree.nodes["Background"].inputs["Strength"].default_value = 1.0
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.1, 0.1, 0.1, 1)
    ex = _export(empty_scene)
    kinds = sorted(d["type"] for d in ex.lights)
    assert kinds == ["POINT", "SPOT", "SUN", "WORLD"]
    assert ex.counts["point_lights"] == ex.counts["spot_lights"] == ex.counts["sun_lights"] == ex.counts["world"] == 1
    assert {"name": "DarkBulb", "reason": "POINT light with zero power"} in ex.skipped
    # A world coloured by a texture is not a uniform background: Cycles renders it into a map, and the report
    # says so.
    noise = world.node_tree.nodes.new("ShaderNodeTexNoise")
    world.node_tree.links.new(noise.outputs["Color"], world.node_tree.nodes["Background"].inputs["Color"])
    report = penumbra.bake(empty_scene, resolution=16, epsilon=0.01)
    assert not [x for x in report["skipped"] if x["name"] == world.name]
    assert any(world.name in n and "evaluated by Cycles" in n for n in report["notes"])
    assert report["export"]["world"] == 1 and report["export"]["point_lights"] == 1
    text = json.dumps(report)
    assert json.loads(text)["objects_baked"] == report["objects_baked"]
    for key in ("export", "solve", "write_back", "total"):
        assert report["times"][key] >= 0
    for key in ("elements", "links", "iterations", "residual", "lights", "light_rays"):
        assert key in report


def test_instances_take_part_but_are_not_baked(empty_scene, penumbra):
    cornell_box.build()
    src = helpers.quad_object("Shelf", 0.2, 0.2, z=1.0, material=bpy.data.materials["White"])
    coll = bpy.data.collections.new("Shelves")
    coll.objects.link(src)
    empty_scene.collection.objects.unlink(src)      # only the instance is in the scene
    empty = bpy.data.objects.new("ShelfInstance", None)
    empty.instance_type = "COLLECTION"
    empty.instance_collection = coll
    empty.location = (0.5, 0.5, 0.0)
    empty_scene.collection.objects.link(empty)
    ex = _export(empty_scene)
    inst = [x for x in ex.skipped if "instance" in x["reason"]]
    assert inst and "Shelf" in inst[0]["name"], ex.skipped
    names = [n for n in ex.object_names if n.startswith("Shelf")]
    assert names
    k = ex.object_names.index(names[0])
    v = ex.vertices[np.unique(ex.polygons[ex.object_index == k][:, :4].ravel())]
    # World space: the instance sits 0.5 m off in x and y from its source.
    assert np.allclose(v[:, :2].mean(axis=0), (0.5, 0.5), atol=1e-5)
    assert "Shelf" not in ex.bake_objects


def test_ngons_become_triangles_with_the_face_winding(empty_scene):
    bpy.ops.mesh.primitive_circle_add(vertices=12, fill_type="NGON", radius=1.0, location=(0, 0, 0))
    ngon = bpy.context.object
    bpy.ops.mesh.primitive_plane_add(size=1.0, location=(0, 0, 2))
    lamp = bpy.context.object
    lamp.rotation_euler = (math.pi, 0, 0)
    lamp.data.materials.append(helpers.emission_material("E", (1, 1, 1), 1.0))
    ex = _export(empty_scene)
    k = ex.object_names.index(ngon.name)
    rows = ex.polygons[ex.object_index == k]
    assert len(rows) == 10 and (rows[:, 3] == -1).all()
    p = ex.vertices[rows[:, :3]]
    n = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    assert (n[:, 2] > 0).all()               # same side as the circle's +Z face
    kl = ex.object_names.index(lamp.name)
    q = ex.vertices[ex.polygons[ex.object_index == kl][0]]
    assert np.cross(q[1] - q[0], q[2] - q[0])[2] < 0     # the flipped plane faces down
    assert np.allclose(ex.emission[ex.object_index == kl], math.pi)
    assert (ex.flags[ex.object_index == kl] == export.EMIT_BACK).all()


def test_area_light_polygons(empty_scene):
    for shape, size, size_y, scale in (("SQUARE", 0.5, None, (2, 1, 1)), ("RECTANGLE", 0.4, 1.0, (1, 1, 1)),
                                       ("DISK", 0.8, None, (1, 3, 1)), ("ELLIPSE", 0.5, 1.5, (1, 1, 1))):
        bpy.ops.wm.read_homefile(use_empty=True)
        ob = helpers.area_light("L", shape, size, size_y, energy=50.0, color=(1, 0.5, 0.25),
                                location=(1, 2, 3), rotation=(0.3, 0.2, 0.1), scale=scale)
        bpy.context.view_layer.update()
        ex = _export(bpy.context.scene)
        sy = size_y if size_y else size
        true_area = size * sy * scale[0] * scale[1] * (math.pi / 4 if shape in ("DISK", "ELLIPSE") else 1)
        area = 0.0
        local_z = np.array(ob.matrix_world)[:3, 2]
        for row in ex.polygons:
            p = ex.vertices[row[row >= 0]].astype(np.float64)
            n = sum(np.cross(p[i], p[(i + 1) % len(p)]) for i in range(len(p))) / 2
            area += np.linalg.norm(n)
            assert np.dot(n, local_z) < 0, f"{shape}: must emit toward local -Z"
        assert abs(area / true_area - 1) < 1e-4, shape
        assert (ex.flags == export.LIGHT_ONLY).all()
        factor = math.pi / 4 if bpy.app.version < (4, 0, 0) else 1.0   # Cycles' area light units changed in 4.0
        assert np.allclose(ex.emission[0], factor * 50.0 * np.array([1, 0.5, 0.25]) / true_area, rtol=1e-4)
        assert np.allclose(ex.reflectance, 0)


def test_material_parsing(empty_scene):
    mat = bpy.data.materials.new("P")
    mat.use_nodes = True
    bsdf = mat.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (0.2, 0.4, 0.6, 1)
    compat.principled(bsdf, "Emission").default_value = (1.0, 0.5, 0.0, 1)
    bsdf.inputs["Emission Strength"].default_value = 3.0
    info = materials.parse_material(mat)
    assert np.allclose(info.albedo, (0.2, 0.4, 0.6)) and np.allclose(info.radiance, (3.0, 1.5, 0.0))

    img = bpy.data.images.new("Tex", 4, 4, alpha=False, float_buffer=True)
    px = np.zeros((4, 4, 4), np.float32)
    px[..., 3] = 1
    px[:2, :, 0] = 0.5      # half the texels red 0.5, the rest 0: mean 0.25
    img.pixels.foreach_set(px.ravel())
    tex = mat.node_tree.nodes.new("ShaderNodeTexImage")
    tex.image = img
    mat.node_tree.links.new(tex.outputs["Color"], bsdf.inputs["Base Color"])
    info = materials.parse_material(mat)
    assert np.allclose(info.albedo, (0.25, 0.0, 0.0), atol=1e-6)
    assert any("average of image 'Tex'" in n for n in info.notes)

    odd = bpy.data.materials.new("Odd")
    odd.use_nodes = True
    nt = odd.node_tree
    nt.nodes.remove(nt.nodes["Principled BSDF"])
    glass = nt.nodes.new("ShaderNodeBsdfGlass")
    nt.links.new(glass.outputs[0], nt.nodes["Material Output"].inputs["Surface"])
    info = materials.parse_material(odd)
    assert info.albedo == materials.DEFAULT_ALBEDO and info.warnings

    helpers.quad_object("Odd", 1, 1, material=odd)
    ex = _export(empty_scene)
    assert any("'Odd'" in w and "ShaderNodeBsdfGlass" in w for w in ex.warnings), ex.warnings


def test_selection_only_and_hidden_objects(empty_scene):
    cornell_box.build()
    bpy.data.objects["TallBlock"].hide_set(True)
    ex = _export(empty_scene)
    assert "TallBlock" not in ex.object_names
    for ob in bpy.context.view_layer.objects:
        ob.select_set(ob.name in ("Floor", "Lamp"))
    ex = _export(empty_scene, selection_only=True)
    assert sorted(ex.object_names) == ["Floor", "Lamp"]


def test_modifiers_and_mirroring(empty_scene, penumbra):
    cornell_box.build()
    block = bpy.data.objects["ShortBlock"]
    block.modifiers.new("Sub", "SUBSURF").levels = 1
    wall = bpy.data.objects["LeftWall"]
    # Mirror the red wall in place (x -> -2 - x keeps it at x = -1): its faces then point out of the room,
    # which is what Blender shows (normals transform with the inverse transpose).
    wall.scale = (-1, 1, 1)
    wall.location = (-2, 0, 0)
    bpy.context.view_layer.update()
    ex = _export(empty_scene)
    k = ex.object_names.index("ShortBlock")
    assert (ex.object_index == k).sum() == 4 * len(block.data.polygons)
    kw = ex.object_names.index("LeftWall")
    p = ex.vertices[ex.polygons[ex.object_index == kw][:, :3]].astype(np.float64)
    n = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    assert (n[:, 0] < 0).all()
    report = penumbra.bake(empty_scene, resolution=16, epsilon=0.01)
    assert any("ShortBlock" in w and "topology" in w for w in report["warnings"])
    assert "LeftWall" in report["objects_baked"]

"""The Blender builds of the benchmark scenes: the scalable scene exports to exactly what make_scene gives the
solver directly (so bench/scaling.py measures the scene a user would bake), and office5k has its size."""
import bpy
import numpy as np
import pytest

import scalable_scene
import scenes
from penumbra import export


def _export(scene):
    return export.export_scene(scene, bpy.context.view_layer, bpy.context.evaluated_depsgraph_get())


def _per_object(names, vertices, polygons, reflectance, emission, flags, object_index):
    """{object: (corners, reflectance, emission, flags)} in the object's own polygon order: the export's object
    order follows the depsgraph and its vertex numbering follows Blender, so only these are comparable."""
    out = {}
    for k, name in enumerate(names):
        m = object_index == k
        out[name] = (vertices[polygons[m]], reflectance[m], emission[m], flags[m])
    return out


@pytest.mark.parametrize("layout", ["office", "classroom"])
def test_scalable_scene_exports_as_make_scene(empty_scene, layout):
    n = 1000
    scalable_scene.build_bpy(n, empty_scene, layout=layout)
    got = _export(empty_scene)
    want = scalable_scene.make_scene(n, layout=layout)
    assert len(got.polygons) == len(want["polygons"]) == scalable_scene.plan(n, layout)["polygons"]
    assert (got.polygons >= 0).all() and (want["polygons"] >= 0).all()       # quads only
    a = _per_object(got.object_names, got.vertices, got.polygons, got.reflectance, got.emission, got.flags,
                    got.object_index)
    b = _per_object(want["object_names"], want["vertices"], want["polygons"], want["reflectance"],
                    want["emission"], want["flags"], want["object_index"])
    b = {name: v for name, v in b.items() if len(v[1])}       # the classroom has no monitors to build
    assert sorted(a) == sorted(b)
    for name in b:
        for x, y in zip(a[name], b[name]):
            np.testing.assert_allclose(x, y, rtol=1e-5, atol=1e-5, err_msg=name)


def test_office5k_has_about_5000_polygons_and_four_rectangular_lights(empty_scene):
    scenes.build("office5k", empty_scene)
    got = _export(empty_scene)
    assert 4750 <= len(got.polygons) <= 5250
    lights = [o for o in empty_scene.objects if o.type == "LIGHT"]
    assert len(lights) == 4 and all(o.data.shape == "RECTANGLE" for o in lights)
    assert got.counts["area_lights"] == 4

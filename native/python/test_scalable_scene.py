"""examples/scalable_scene.py, the scene of bench/scaling.py: its size, its arrays, and a small solve."""
import os
import sys

import numpy as np
import pytest

import _native

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "examples"))
import scalable_scene  # noqa: E402


@pytest.mark.parametrize("layout", ["office", "classroom"])
@pytest.mark.parametrize("n", [300, 1000, 1234, 5000, 20000, 50000, 77777, 100000])
def test_polygon_count_is_within_five_percent_of_the_target(n, layout):
    # plan() is what make_scene builds (make_scene asserts it), and it is cheap at 100k.
    got = scalable_scene.plan(n, layout)["polygons"]
    assert abs(got - n) <= 0.05 * n, (n, got)


@pytest.mark.parametrize("n, layout", [(1000, "office"), (5000, "office"), (1000, "classroom")])
def test_arrays_are_what_solve_takes(n, layout):
    s = scalable_scene.make_scene(n, layout=layout)
    assert set(s) == {"vertices", "polygons", "reflectance", "emission", "flags", "object_index", "object_names"}
    v, p = s["vertices"], s["polygons"]
    P = len(p)
    assert abs(P - n) <= 0.05 * n
    for key, dtype, shape in (("vertices", np.float32, (len(v), 3)), ("polygons", np.int32, (P, 4)),
                              ("reflectance", np.float32, (P, 3)), ("emission", np.float32, (P, 3)),
                              ("flags", np.uint8, (P,)), ("object_index", np.int32, (P,))):
        a = s[key]
        assert a.dtype == dtype and a.shape == shape and a.flags.c_contiguous, key
    assert np.isfinite(v).all()
    assert ((p >= 0) & (p < len(v))).all()                       # quads only, indices in range
    assert ((s["reflectance"] >= 0) & (s["reflectance"] < 1)).all()
    assert (s["emission"] >= 0).all() and np.isfinite(s["emission"]).all()
    assert ((s["object_index"] >= 0) & (s["object_index"] < len(s["object_names"]))).all()
    lights = s["emission"].max(axis=1) > 0
    assert lights.sum() == 4
    assert (s["flags"][lights] == _native.LIGHT_ONLY).all() and (s["flags"][~lights] == 0).all()

    corners = v[p].astype(np.float64)
    normal = np.cross(corners[:, 1] - corners[:, 0], corners[:, 3] - corners[:, 0])
    area = np.linalg.norm(normal, axis=1)
    assert (area > 1e-6).all()                                   # nothing degenerate
    # Planar quads: the fourth corner lies in the plane of the first three.
    d = np.einsum("ij,ij->i", corners[:, 2] - corners[:, 0], normal / area[:, None])
    assert np.abs(d).max() < 1e-4

    W, D, H = scalable_scene.plan(n, layout)["room"]
    assert (np.abs(v[:, 0]) <= W / 2 + 1e-4).all() and (np.abs(v[:, 1]) <= D / 2 + 1e-4).all()
    assert (v[:, 2] >= -1e-4).all() and (v[:, 2] <= H + 1e-4).all()
    # Every face faces into the room (walls and lights inwards, furniture outwards from its own volume, which
    # is inside the room): a step along any face's normal stays inside the room.
    centre = corners.mean(axis=1)
    inside = centre + 0.01 * normal / area[:, None]
    assert (np.abs(inside[:, 0]) < W / 2).all() and (np.abs(inside[:, 1]) < D / 2).all()
    assert ((inside[:, 2] > 0) & (inside[:, 2] < H)).all()
    names = s["object_names"]
    light_normals = normal[lights] / area[lights][:, None]
    assert np.allclose(light_normals, [0, 0, -1])
    floor = s["object_index"] == names.index("Floor")
    assert np.allclose(normal[floor] / area[floor][:, None], [0, 0, 1])


def test_classroom_desks_and_chairs_stand_on_the_floor():
    s = scalable_scene.make_scene(1000, layout="classroom")
    names, obj = s["object_names"], s["object_index"]
    assert not (obj == names.index("Monitors")).any()
    stations = scalable_scene.plan(1000, "classroom")["stations"]
    assert (obj == names.index("Desks")).sum() == stations * 22          # top and four legs
    assert (obj == names.index("Chairs")).sum() == stations * 28         # seat, back and four legs
    # Four legs per desk and per chair, each four side quads with two corners on the floor (no vertex is
    # shared between quads): the contact configuration the convolution links have to handle.
    furniture = np.isin(obj, [names.index("Desks"), names.index("Chairs")])
    z = s["vertices"][s["polygons"][furniture]][:, :, 2]
    assert (np.abs(z) < 1e-6).sum() == stations * 8 * 4 * 2
    # Rows: every desk top is axis-aligned (no per-station rotation, unlike the office).
    tops = s["vertices"][s["polygons"][obj == names.index("Desks")]]
    edges = tops[:, 1] - tops[:, 0]
    assert np.all(np.isclose(edges, 0, atol=1e-6).sum(axis=1) >= 2)


def test_deterministic_and_seeded():
    a, b = scalable_scene.make_scene(1000), scalable_scene.make_scene(1000)
    for k in a:
        if k != "object_names":
            assert np.array_equal(a[k], b[k]), k
    c = scalable_scene.make_scene(1000, seed=1)
    assert len(c["polygons"]) == len(a["polygons"]) and not np.array_equal(c["vertices"], a["vertices"])


def test_too_small_a_target_is_refused():
    with pytest.raises(ValueError):
        scalable_scene.make_scene(scalable_scene.MIN_POLYGONS - 1)


def test_a_1k_scene_solves_to_finite_nonnegative_radiance():
    s = scalable_scene.make_scene(1000)
    # A coarse epsilon keeps the test short; the scene, not the refinement, is under test here.
    sol = _native.solve(**s, settings={"epsilon": 0.002})
    v, p = s["vertices"], s["polygons"]
    corners = v[p]
    normal = np.cross(corners[:, 1] - corners[:, 0], corners[:, 3] - corners[:, 0])
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    receivers = s["flags"] == 0
    pts = np.ascontiguousarray((corners.mean(axis=1) + 1e-4 * normal)[receivers], np.float32)
    rad = sol.radiance(pts, np.ascontiguousarray(normal[receivers], np.float32))
    assert np.isfinite(rad).all() and (rad >= 0).all()
    # Every object is lit (directly or by a bounce): the lights face the room and nothing is sealed off.
    obj = s["object_index"][receivers]
    for k, name in enumerate(s["object_names"][:len(scalable_scene.MESH_OBJECTS)]):
        assert rad[obj == k].max() > 0, name
    assert sol.report["polygons"] == len(p)

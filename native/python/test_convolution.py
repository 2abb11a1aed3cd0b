"""The convolution soft-shadow entry point of _native, against exact and ray-traced visibility.

Run with Debian's interpreter:
    PENUMBRA_ADDON_DIR=$PWD/build/addon /usr/bin/python3 -m pytest -q native/python/test_convolution.py
"""
import os
import sys
import threading

import numpy as np
import pytest

_stage = os.environ.get("PENUMBRA_ADDON_DIR",
                        os.path.join(os.path.dirname(__file__), "..", "..", "build", "addon"))
sys.path.insert(0, os.path.join(os.path.abspath(_stage), "penumbra"))

import _native  # noqa: E402


# ----------------------------------------------------------------------------- helpers
def rect(x0, y0, x1, y1, z=0.0):
    return np.array([[x0, y0, z], [x1, y0, z], [x1, y1, z], [x0, y1, z]], float)


def square_blocker(cx, cy, half, z):
    a, b, c, d = rect(cx - half, cy - half, cx + half, cy + half, z)
    return [[a, b, c], [a, c, d]]


def overlap(r, s):
    """Area of the intersection of axis-aligned rectangles (x0, y0, x1, y1)."""
    w = min(r[2], s[2]) - max(r[0], s[0])
    h = min(r[3], s[3]) - max(r[1], s[1])
    return max(w, 0.0) * max(h, 0.0)


def shadow_rect(blk, x, y, zr):
    """Square blocker (cx, cy, half, z) projected from receiver point (x, y, zr) onto z = 0."""
    cx, cy, half, z = blk
    k = zr / (zr - z)
    return (x + (cx - half - x) * k, y + (cy - half - y) * k, x + (cx + half - x) * k, y + (cy + half - y) * k)


def exact_visibility(source_rects, blockers, x, y, zr):
    """Exact visible fraction of a source made of disjoint rectangles at z = 0, behind one or two
    parallel square blockers: polygon clipping reduces to rectangle intersections here."""
    area = sum(overlap(r, r) for r in source_rects)
    shadows = [shadow_rect(b, x, y, zr) for b in blockers]
    hidden = 0.0
    for r in source_rects:
        hidden += sum(overlap(r, s) for s in shadows)
        if len(shadows) == 2:
            both = (max(shadows[0][0], shadows[1][0]), max(shadows[0][1], shadows[1][1]),
                    min(shadows[0][2], shadows[1][2]), min(shadows[0][3], shadows[1][3]))
            if both[2] > both[0] and both[3] > both[1]:
                hidden -= overlap(r, both)
    return 1.0 - hidden / area


def receiver_grid(half, z, count=41):
    g = np.linspace(-0.98 * half, 0.98 * half, count)
    X, Y = np.meshgrid(g, g, indexing="ij")
    return np.stack([X.ravel(), Y.ravel(), np.full(X.size, z)], 1)


def errors(result, points, exact):
    got = _native.lookup(result, points)
    d = np.abs(got - exact)
    return d.max(), d.mean()


def ray_traced_visibility(src_samples, triangles, points):
    """Fraction of source samples visible from each point: segments vs triangles (Moller-Trumbore)."""
    tri = np.asarray(triangles, float)
    out = np.empty(len(points))
    for k, y in enumerate(points):
        d = src_samples - y                     # from receiver point to source samples
        blocked = np.zeros(len(src_samples), bool)
        for a, b, c in tri:
            e1, e2 = b - a, c - a
            pvec = np.cross(d, e2)
            det = pvec @ e1
            ok = np.abs(det) > 1e-14
            inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
            tvec = y - a
            u = (pvec @ tvec) * inv
            qvec = np.cross(tvec, e1)
            v = (d * qvec).sum(1) * inv
            t = (qvec @ e2) * inv
            blocked |= ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 1e-9) & (t < 1 - 1e-9)
        out[k] = 1.0 - blocked.mean()
    return out


def stratified_polygon_samples(corner, e1, e2, count):
    """count x count cell-centred samples of the parallelogram corner + [0,1] e1 + [0,1] e2."""
    g = (np.arange(count) + 0.5) / count
    S, T = np.meshgrid(g, g, indexing="ij")
    return corner + S.ravel()[:, None] * e1 + T.ravel()[:, None] * e2


SQUARE = rect(-0.5, -0.5, 0.5, 0.5)
RECEIVER = rect(-3, -3, 3, 3, 3.0)


# ----------------------------------------------------------------------------- parallel, exact
def test_parallel_square_against_exact_clipping():
    blk = (0.15, -0.1, 0.5, 1.0)
    r = _native.soft_shadow_texture(SQUARE, RECEIVER, square_blocker(*blk), resolution=128)
    assert r["visibility"].shape == (128, 128) and r["visibility"].dtype == np.float32
    assert r["matrix"].shape == (4, 4) and r["matrix"].dtype == np.float64
    assert r["sub_blockers"] == 1
    assert r["error"] == pytest.approx(0.0, abs=1e-9)
    assert r["alpha_min"] == pytest.approx(2.0)
    pts = receiver_grid(3.0, 3.0)
    exact = np.array([exact_visibility([(-0.5, -0.5, 0.5, 0.5)], [blk], x, y, 3.0) for x, y, _ in pts])
    mx, mean = errors(r, pts, exact)
    assert mx <= 0.02
    assert mean <= 0.005


def test_l_shaped_source_catches_a_missing_reflection():
    # An L is not centrally symmetric: the reflected L casts a different penumbra.
    L = np.array([[-0.5, -0.5, 0], [0.5, -0.5, 0], [0.5, -0.1, 0], [-0.1, -0.1, 0],
                  [-0.1, 0.5, 0], [-0.5, 0.5, 0]], float)
    # The frame's origin is the L's area centroid; rectangles below are in world coordinates.
    L_rects = [(-0.5, -0.5, 0.5, -0.1), (-0.5, -0.1, -0.1, 0.5)]
    blk = (0.2, 0.1, 0.45, 1.2)
    r = _native.soft_shadow_texture(L, RECEIVER, square_blocker(*blk), resolution=128)
    pts = receiver_grid(3.0, 3.0)
    exact = np.array([exact_visibility(L_rects, [blk], x, y, 3.0) for x, y, _ in pts])
    mx, mean = errors(r, pts, exact)
    assert mx <= 0.02
    assert mean <= 0.005
    # The same L reflected through its centroid: what a missing flip would compute.
    c = np.array(r["frame"]["origin"])[:2]
    refl = [(2 * c[0] - x1, 2 * c[1] - y1, 2 * c[0] - x0, 2 * c[1] - y0) for x0, y0, x1, y1 in L_rects]
    wrong = np.array([exact_visibility(refl, [blk], x, y, 3.0) for x, y, _ in pts])
    assert np.abs(wrong - exact).max() > 0.1


def test_umbra_exactly_zero_and_full_light_exactly_one():
    small = rect(-0.1, -0.1, 0.1, 0.1)
    r = _native.soft_shadow_texture(small, rect(-4, -4, 4, 4, 2.0), square_blocker(0, 0, 1.0, 1.0),
                                    resolution=200)
    V = r["visibility"]
    p = 8.0 / 200
    c = -4 + (np.arange(200) + 0.5) * p
    X, Y = np.meshgrid(c, c, indexing="xy")       # V is indexed [t, s] = [row along v, column along u]
    ring = np.maximum(np.abs(X), np.abs(Y))
    umbra, light = ring < 1.9 - 2 * p, ring > 2.1 + 2 * p
    assert umbra.sum() > 5000 and light.sum() > 5000
    assert np.all(V[umbra] == 0.0)
    assert np.all(V[light] == 1.0)
    got = _native.lookup(r, [[0, 0, 2], [3.5, -3.5, 2]])
    assert got[0] == 0.0 and got[1] == 1.0


def test_two_slab_error_falls_as_n_grows():
    blks = [(-0.5, 0.0, 0.3, 1.0), (0.9, 0.2, 0.25, 2.0)]
    tris = square_blocker(*blks[0]) + square_blocker(*blks[1])
    pts = receiver_grid(3.0, 3.0)
    exact = np.array([exact_visibility([(-0.5, -0.5, 0.5, 0.5)], blks, x, y, 3.0) for x, y, _ in pts])
    res = {}
    for n_max in (1, 2):
        r = _native.soft_shadow_texture(SQUARE, RECEIVER, tris, resolution=128, e_max=0.5, n_max=n_max)
        res[n_max] = (r, *errors(r, pts, exact))
    (r1, max1, mean1), (r2, max2, mean2) = res[1], res[2]
    assert r1["sub_blockers"] == 1 and r2["sub_blockers"] == 2
    assert r2["error"] < r1["error"]
    assert max2 < 0.5 * max1 and mean2 < 0.5 * mean1
    assert max1 <= r1["visibility_error"] + 0.02       # N = 1 stays inside its estimate
    assert max2 <= 0.03


# ----------------------------------------------------------------------------- general case
def tilted_scene():
    # Source: 0.6 x 0.5 rectangle around the origin, tilted 25 degrees about the x axis.
    a = np.radians(25)
    e1 = np.array([0.6, 0, 0])
    e2 = 0.5 * np.array([0, np.cos(a), np.sin(a)])
    s0 = -0.5 * (e1 + e2)
    source = np.array([s0, s0 + e1, s0 + e1 + e2, s0 + e2])
    # Blocker: two tilted triangles between depths 0.95 and 1.1.
    blockers = [[[-0.3, -0.35, 0.95], [0.45, -0.2, 1.05], [0.1, 0.4, 1.0]],
                [[0.45, -0.2, 1.05], [0.7, 0.3, 1.1], [0.1, 0.4, 1.0]]]
    # Receiver: 3 x 3 quad around (0, 0, 3) tilted 15 degrees about the y axis.
    b = np.radians(15)
    r1 = np.array([np.cos(b), 0, np.sin(b)]) * 3.0
    r2 = np.array([0, 3.0, 0])
    r0 = np.array([0, 0, 3.0]) - 0.5 * (r1 + r2)
    receiver = np.array([r0, r0 + r1, r0 + r1 + r2, r0 + r2])
    return source, (s0, e1, e2), blockers, receiver, (r0, r1, r2)


@pytest.mark.parametrize("direction", ["auto", "source_to_receiver", "source_normal"])
def test_tilted_source_and_receiver_inside_the_estimate(direction):
    source, (s0, e1, e2), blockers, receiver, (r0, r1, r2) = tilted_scene()
    r = _native.soft_shadow_texture(source, receiver, blockers, resolution=128, n_max=1, direction=direction)
    g = np.linspace(0.02, 0.98, 25)
    S, T = np.meshgrid(g, g, indexing="ij")
    pts = r0 + S.ravel()[:, None] * r1 + T.ravel()[:, None] * r2
    truth = ray_traced_visibility(stratified_polygon_samples(s0, e1, e2, 96), blockers, pts)
    assert truth.min() < 0.1 and (truth < 1).mean() > 0.2   # the grid does see umbra and penumbra
    got = _native.lookup(r, pts)
    err = np.abs(got - truth)
    # "Inside the estimate": the largest measured error does not exceed the predicted maximum
    # visibility error r["visibility_error"] (= 1.25 E_rr / kernel width, brief 4.2) plus 0.02, the
    # error bound of an exact (parallel) configuration, which also covers the ray-traced
    # reference's own sampling error (96 x 96 source samples, about 0.01).
    assert err.max() <= r["visibility_error"] + 0.02, (err.max(), r["visibility_error"], r["error"])
    assert r["visibility_error"] < 0.95            # and the estimate says something
    assert err.mean() <= 0.025


# ----------------------------------------------------------------------------- other behaviour
def test_emission_image_orientation():
    # s runs along the first edge (v0 -> v1 = +x): columns with s > 1/2 emit, the rest are dark,
    # which must equal a uniform source covering x > 0 only.
    img = np.zeros((8, 64), np.float32)
    img[:, 32:] = 1.0
    blk = square_blocker(0.1, 0.0, 0.5, 1.0)
    textured = _native.soft_shadow_texture(SQUARE, RECEIVER, blk, resolution=128, emission_image=img,
                                           direction="source_normal")
    half = _native.soft_shadow_texture(rect(0, -0.5, 0.5, 0.5), RECEIVER, blk, resolution=128,
                                       direction="source_normal")
    pts = receiver_grid(3.0, 3.0, 31)
    assert np.abs(_native.lookup(textured, pts) - _native.lookup(half, pts)).max() < 0.03


def test_no_blocker_is_full_light_and_lookup_behind_source_is_nan():
    r = _native.soft_shadow_texture(SQUARE, RECEIVER, np.zeros((0, 3, 3)))
    assert r["sub_blockers"] == 0 and r["error"] == 0.0
    assert np.all(r["visibility"] == 1.0)
    assert np.isnan(_native.lookup(r, [[0, 0, -1.0]])[0])


def test_automatic_resolution_from_alpha_min():
    r = _native.soft_shadow_texture(SQUARE, RECEIVER, square_blocker(0, 0, 0.5, 2.9), max_resolution=1024)
    # alpha_min = (3 - 2.9) / 2.9, L_S = 1: texels of half the narrowest penumbra over a 6-wide window.
    assert r["resolution"] == int(np.ceil(6.0 / (0.1 / 2.9 / 2)))
    assert r["alpha_min"] == pytest.approx(0.1 / 2.9)


def test_osmesa_rasterizer_agrees():
    blk = square_blocker(0.15, -0.1, 0.5, 1.0)
    a = _native.soft_shadow_texture(SQUARE, RECEIVER, blk, resolution=96, rasterizer="span")
    try:
        b = _native.soft_shadow_texture(SQUARE, RECEIVER, blk, resolution=96, rasterizer="osmesa")
    except RuntimeError as e:
        pytest.skip(f"OSMesa unavailable: {e}")
    assert b["rasterizer"] == "osmesa"
    assert np.abs(a["visibility"] - b["visibility"]).max() < 0.02


def test_concurrent_calls_give_the_serial_answer():
    source, _, blockers, receiver, _ = tilted_scene()
    ref = _native.soft_shadow_texture(source, receiver, blockers, resolution=96)["visibility"]
    out = [None] * 4

    def work(i):
        out[i] = _native.soft_shadow_texture(source, receiver, blockers, resolution=96)["visibility"]

    th = [threading.Thread(target=work, args=(i,)) for i in range(4)]
    for t in th:
        t.start()
    for t in th:
        t.join()
    for o in out:
        np.testing.assert_array_equal(o, ref)


@pytest.mark.parametrize("kwargs, message", [
    (dict(source=[[0, 0, 0], [1, 0, 0], [np.nan, 1, 0]]), "non-finite"),
    (dict(source=[[0, 0, 0], [1, 0, 0], [2, 0, 0]]), "degenerate"),
    (dict(source=[[0, 0, 0], [1, 0, 0]]), "at least 3"),
    (dict(source=np.zeros((4, 2))), "shape"),
    (dict(source=[[-.5, -.5, 0], [.5, -.5, 0], [.5, .5, 0.4], [-.5, .5, 0]]), "planar"),
    (dict(blockers=np.zeros((2, 3))), "shape"),
    (dict(blockers=[[[0, 0, 1], [1, 0, 1], [0, np.inf, 1]]]), "non-finite"),
    (dict(receiver=[[0, 0, 3], [1, 0, 3]]), "at least 3"),
    (dict(receiver=[[-1, -1, -1], [1, -1, 3], [1, 1, 3]]), "one side"),
    (dict(blockers=[[[-2, -2, 0.5], [2, -2, 3.5], [0, 2, 3.5]]]), "not a valid convolution"),
    (dict(rasterizer="gpu"), "rasterizer"),
    (dict(resolution=0), "resolution"),
    (dict(e_max=-1.0), "e_max"),
    (dict(emission_image=np.zeros((4, 4))), "zero everywhere"),
    (dict(emission_image=-np.ones((4, 4))), "non-negative"),
    (dict(source="abc"), "numeric"),
])
def test_bad_input_raises_value_error(kwargs, message):
    args = dict(source=SQUARE, receiver=RECEIVER, blockers=square_blocker(0, 0, 0.5, 1.0))
    args.update(kwargs)
    with pytest.raises(ValueError, match=message):
        _native.soft_shadow_texture(**args)


def test_lookup_validates_its_input():
    r = _native.soft_shadow_texture(SQUARE, RECEIVER, square_blocker(0, 0, 0.5, 1.0), resolution=32)
    with pytest.raises(ValueError):
        _native.lookup(r, [[0, 0]])
    with pytest.raises(ValueError):
        _native.lookup({"visibility": r["visibility"]}, [[0, 0, 3]])


def _edge_profile(s):
    """Visible share of a unit disk whose centre is s radii on the lit side of a straight edge."""
    s = np.clip(s, -1, 1)
    return 1 - (np.arccos(s) - s * np.sqrt(1 - s * s)) / np.pi


def test_sun_shadow_of_a_straight_edge_is_the_disk_segment():
    """A half-plane 1 m above the receiver under a 4 degree sun 30 degrees off the normal in the edge's plane:
    across the edge the penumbra is the visible segment of a disk of radius (1 / cos 30) tan 2 degrees."""
    tilt, angle = np.radians(30.0), np.radians(4.0)
    direction = [0.0, np.sin(tilt), -np.cos(tilt)]
    a, b, c, d = np.array([[-3, -3, 1], [0, -3, 1], [0, 3, 1], [-3, 3, 1]], float)
    rec = np.array([[-0.5, -0.5, 0], [0.5, -0.5, 0], [0.5, 0.5, 0], [-0.5, 0.5, 0]], float)
    r = _native.sun_shadow_texture(direction, angle, rec, [[a, b, c], [a, c, d]], resolution=400)
    rho = np.tan(angle / 2) / np.cos(tilt)
    x = np.linspace(-1.2 * rho, 1.2 * rho, 61)
    pts = np.stack([x, np.full_like(x, 0.1), np.zeros_like(x)], axis=1)
    got = _native.lookup(r, pts)
    assert r["sub_blockers"] == 1
    assert np.abs(got - _edge_profile(x / rho)).max() < 0.02
    assert _native.lookup(r, [[-0.3, 0, 0]])[0] == 0 and _native.lookup(r, [[0.3, 0, 0]])[0] == 1


def test_sun_shadow_bad_input():
    rec = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], float)
    tri = [[[-1, -1, 1], [0, -1, 1], [0, 1, 1]]]
    for direction, angle in (([0, 0, 0], 0.1), ([0, 0, -1], 0.0), ([0, 0, -1], np.pi), ([0, 0, np.nan], 0.1)):
        with pytest.raises(ValueError):
            _native.sun_shadow_texture(direction, angle, rec, tri)
    with pytest.raises(ValueError):
        _native.sun_shadow_texture([0, 0, -1, 0], 0.1, rec, tri)
    with pytest.raises(ValueError):   # a card through the receiver: no depth order
        _native.sun_shadow_texture([0, 0, -1], 0.1, rec, [[[-1, 0, -0.5], [1, 0, -0.5], [1, 0, 0.5]]])

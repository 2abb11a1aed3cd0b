"""`solve(..., min_edge=...)`: the finest element edge per face in metres (issue 14, item 2), against an exact
direct-light answer computed here: a large floor, a small lamp and a small blocker whose umbra is finer than
1 % of the scene's diagonal. Also the refusal of a soft shadow texture too coarse to show that umbra."""
import numpy as np
import pytest

import _native

LAMP, LAMP_Z, BLOCK, BLOCK_Z, EMIT, RHO = 0.1, 1.0, 0.1, 0.5, 50.0, 0.5   # half sides, heights


def _quad(cx, cy, h, z, down=False):
    v = [(cx - h, cy - h, z), (cx + h, cy - h, z), (cx + h, cy + h, z), (cx - h, cy + h, z)]
    return v[::-1] if down else v


def plane_scene(side):
    """A side x side floor (one face), a 0.2 m blocker (two faces) at 0.5 m, a 0.2 m lamp at 1 m facing down.
    The blocker is black, so the floor's light under it is the lamp's direct light only."""
    faces = [_quad(0, 0, side / 2, 0), _quad(0, 0, LAMP, LAMP_Z, down=True),
             _quad(0, 0, BLOCK, BLOCK_Z), _quad(0, 0, BLOCK, BLOCK_Z, down=True)]
    verts = np.array([p for f in faces for p in f], np.float32)
    polys = np.arange(16, dtype=np.int32).reshape(4, 4)
    refl = np.array([[RHO] * 3, [0] * 3, [0] * 3, [0] * 3], np.float32)
    emis = np.array([[0] * 3, [EMIT] * 3, [0] * 3, [0] * 3], np.float32)
    flags = np.array([0, _native.LIGHT_ONLY, 0, 0], np.uint8)
    return verts, polys, refl, emis, flags, np.array([0, 1, 2, 2], np.int32), ["Floor", "Lamp", "Blocker"]


def _point_to_square(p, h, z):
    """Exact form factor from an upward-facing point to the square of half side h at height z (Lambert)."""
    c = np.array([[-h, -h, z], [h, -h, z], [h, h, z], [-h, h, z]]) - p
    s = 0.0
    for i in range(4):
        a, b = c[i] / np.linalg.norm(c[i]), c[(i + 1) % 4] / np.linalg.norm(c[(i + 1) % 4])
        g = np.cross(a, b)
        s += g[2] / np.linalg.norm(g) * np.arccos(np.clip(a @ b, -1, 1))
    return abs(s) / (2 * np.pi)


def exact_radiance(points):
    """RHO * EMIT / pi times the unoccluded form factor times the seen share of the lamp: 128 x 128 lamp points,
    each tested against the blocker's square in closed form."""
    g = (np.arange(128) + 0.5) / 128 * 2 * LAMP - LAMP
    lx, ly = np.meshgrid(g, g)
    out = []
    for p in points:
        t = (BLOCK_Z - p[2]) / (LAMP_Z - p[2])
        hx, hy = p[0] + t * (lx - p[0]), p[1] + t * (ly - p[1])
        seen = 1 - np.mean((np.abs(hx) < BLOCK) & (np.abs(hy) < BLOCK))
        out.append(RHO * EMIT / np.pi * _point_to_square(p, LAMP, LAMP_Z) * seen)
    return np.array(out)


XS = np.linspace(-0.6, 0.6, 121)
POINTS = np.array([[x, 0.013, 0] for x in XS], np.float32)
NORMALS = np.tile(np.array([0, 0, 1], np.float32), (len(XS), 1))
EXACT = exact_radiance(POINTS.astype(float))


def _error(sol):
    return np.abs(sol.radiance(POINTS, NORMALS)[:, 0] - EXACT).max() / EXACT.max()


def test_min_edge_resolves_an_umbra_finer_than_the_scenes_min_size():
    """On a 100 m floor min_size 0.01 is 1.4 m: the 0.2 m blocker's shadow vanishes into one element (the umbra's
    centre comes out lit at 0.9 of the peak). With a 5 cm floor for the floor's face it is within 12 % of the
    peak everywhere along the line and dark at the centre; the lamp and blocker keep the min_size rule (0)."""
    scene = plane_scene(100.0)
    settings = {"epsilon": 0.002}
    coarse = _native.solve(*scene, settings=settings)
    fine = _native.solve(*scene, settings=settings, min_edge=np.array([0.05, 0, 0, 0], np.float32))
    assert _error(coarse) > 0.5
    assert _error(fine) < 0.12
    centre = fine.radiance(POINTS[60:61], NORMALS[60:61])[0, 0]
    assert centre < 0.01 * EXACT.max()
    assert fine.report["elements"] > 20 * coarse.report["elements"]


def test_min_size_follows_the_pieces_when_they_are_small_beside_the_scene():
    """min_size is a share of the smaller of the diagonal and 35 median pieces (faces joined by shared corners):
    four grey 0.2 m cards far out on the 100 m floor make the median piece 0.28 m, so the floor may be cut to
    0.099 m instead of 1.41 m, and the blocker's umbra (which the diagonal's floor loses, the test above) comes
    out without any min_edge. The cards stand 30 m away: they change the floor, not the light on the line."""
    verts, polys, refl, emis, flags, obj, names = plane_scene(100.0)
    cards = [_quad(30.0 + 2 * k, 30.0, BLOCK, 0.3) for k in range(4)]
    verts = np.vstack([verts, np.array([p for f in cards for p in f], np.float32)])
    polys = np.vstack([polys, 16 + np.arange(16, dtype=np.int32).reshape(4, 4)])
    refl = np.vstack([refl, np.full((4, 3), RHO, np.float32)])
    emis = np.vstack([emis, np.zeros((4, 3), np.float32)])
    flags = np.concatenate([flags, np.zeros(4, np.uint8)])
    obj = np.concatenate([obj, np.full(4, 3, np.int32)])
    sol = _native.solve(verts, polys, refl, emis, flags, obj, names + ["Cards"], settings={"epsilon": 0.002})
    assert sol.report["min_edge"] == pytest.approx(0.01 * 35 * 2 * BLOCK * np.sqrt(2), rel=1e-6)
    assert _error(sol) < 0.25
    centre = sol.radiance(POINTS[60:61], NORMALS[60:61])[0, 0]
    assert centre < 0.05 * EXACT.max()
    # Without the cards the floor's own size decides (one piece besides the black blocker): the diagonal's floor.
    alone = _native.solve(*plane_scene(100.0), settings={"epsilon": 0.002})
    assert alone.report["min_edge"] == pytest.approx(0.01 * np.sqrt(100.0 ** 2 * 2 + LAMP_Z ** 2), rel=1e-6)


def test_an_open_floor_is_refined_only_where_a_small_lamp_lights_it():
    """Epsilon's scale was bounded by 200 times the mean exitance the lamp gives the whole 100 m floor, so tiny
    that every element within ~15 m of a 20 cm lamp was cut to the 5 cm floor (38,912 elements); the bound is
    now never below the brightest irradiance the lamp gives the face in front of it: 5,808 elements, and the
    light out to 40 m still within 0.2 % of the exact answer (the final gather carries it)."""
    fine = _native.solve(*plane_scene(100.0), settings={"epsilon": 0.002},
                         min_edge=np.array([0.05, 0, 0, 0], np.float32))
    assert fine.report["elements"] < 12000
    far = np.array([[x, 0.3, 0] for x in (1, 2, 5, 10, 20, 40)], np.float32)
    up = np.tile(np.array([0, 0, 1], np.float32), (len(far), 1))
    np.testing.assert_allclose(fine.radiance(far, up)[:, 0], exact_radiance(far.astype(float)), rtol=2e-3)


def test_min_edge_of_zero_is_the_min_size_rule():
    scene = plane_scene(4.0)
    a = _native.solve(*scene)
    b = _native.solve(*scene, min_edge=np.zeros(4, np.float32))
    assert a.report["elements"] == b.report["elements"] and a.report["links"] == b.report["links"]
    assert np.array_equal(a.radiance(POINTS, NORMALS), b.radiance(POINTS, NORMALS))


@pytest.mark.parametrize("bad, what", [(np.array([-1, 0, 0, 0], np.float32), "negative or not finite"),
                                       (np.array([np.nan, 0, 0, 0], np.float32), "negative or not finite"),
                                       (np.zeros(3, np.float32), "min_edge"),
                                       (np.zeros(4, np.float64), "min_edge")])
def test_bad_min_edge_is_refused_by_name(bad, what):
    with pytest.raises(ValueError, match=what):
        _native.solve(*plane_scene(4.0), min_edge=bad)


def test_a_texture_coarser_than_half_the_narrowest_penumbra_is_refused():
    """A 4 m floor takes the blocker's soft shadow texture (its texels are 8 mm, the narrowest penumbra 0.1 m);
    on a 100 m floor the 512 texels would be 0.2 m, so the pair is refused as too coarse and refined instead:
    before, such a texture was made (on a 200 m floor it lit the umbra's centre at 0.68 of the peak)."""
    small = _native.solve(*plane_scene(4.0))
    assert small.report["convolution_links"] == 1
    assert _error(small) < 0.12
    large = _native.solve(*plane_scene(100.0), settings={"epsilon": 0.002})
    assert large.report["convolution_links"] == 0
    assert large.report["convolution_refused"]["too_coarse"] == 1

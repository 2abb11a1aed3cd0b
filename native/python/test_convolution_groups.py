"""Convolution links whose receiver is several coplanar faces or whose source is several lamps (issue 12, item 2
and the first half of item 3), against a direct-light integral computed here independently of the solver and
against the same scene with one face or one lamp.

The scene is the parallel-planes case of solve/convolution_link_test.cpp: a 4 x 4 m white floor at z = 0, a black
square blocker facing down at z = 1, square lamps of side 0.5 facing down at z = 2. Only the floor reflects, so
its light is direct and the integral is the exact answer."""
import numpy as np
import pytest

import _native

RHO, EMIT = 0.5, 10.0


class Scene:
    def __init__(self):
        self.verts, self.polys, self.refl, self.emis, self.flags, self.obj = [], [], [], [], [], []
        self.lamps, self.blockers = [], []     # axis-aligned rectangles, for the reference

    def poly(self, corners, rho, emit, obj, flag=0):
        self.polys.append([len(self.verts) + k for k in range(len(corners))] + [-1] * (4 - len(corners)))
        self.verts.extend(corners)
        self.refl.append([rho] * 3)
        self.emis.append([emit] * 3)
        self.obj.append(obj)
        self.flags.append(flag)
        return len(self.polys) - 1

    def floor(self, n):
        """The floor in n x n quads, or in two triangles for n = 'tri'; returns the faces' indices."""
        if n == "tri":
            return [self.poly([(-2, -2, 0), (2, -2, 0), (2, 2, 0)], RHO, 0, 0),
                    self.poly([(-2, -2, 0), (2, 2, 0), (-2, 2, 0)], RHO, 0, 0)]
        h = 4 / n
        return [self.poly([(x, y, 0), (x + h, y, 0), (x + h, y + h, 0), (x, y + h, 0)], RHO, 0, 0)
                for x in -2 + h * np.arange(n) for y in -2 + h * np.arange(n)]

    def blocker(self, half):
        self.poly([(-half, -half, 1), (-half, half, 1), (half, half, 1), (half, -half, 1)], 0, 0, 1)
        self.blockers.append((-half, -half, half, half, 1.0))

    def lamp(self, cx, z=2.0, emit=EMIT, obj=2):
        a = 0.25
        self.lamps.append((cx - a, -a, cx + a, a, z, emit))
        return self.poly([(cx - a, -a, z), (cx - a, a, z), (cx + a, a, z), (cx + a, -a, z)], 0, emit, obj,
                         _native.LIGHT_ONLY)

    def args(self):
        return (np.array(self.verts, np.float32), np.array(self.polys, np.int32), np.array(self.refl, np.float32),
                np.array(self.emis, np.float32), np.array(self.flags, np.uint8), np.array(self.obj, np.int32),
                ["Floor", "Blocker", "Lamp", "Lamp 2"])

    def exact(self, points, m=96):
        """rho/pi * sum over lamps of E * the form factor of the lamp's visible part: midpoint rule on m x m lamp
        cells, each cell's ray from the point tested against every blocker."""
        out = np.zeros(len(points))
        u = (np.arange(m) + 0.5) / m
        for x0, y0, x1, y1, zl, e in self.lamps:
            lx, ly = [a.ravel() for a in np.meshgrid(x0 + (x1 - x0) * u, y0 + (y1 - y0) * u)]
            da = (x1 - x0) * (y1 - y0) / (m * m)
            for i, (x, y) in enumerate(points[:, :2].astype(np.float64)):
                dx, dy = lx - x, ly - y
                r2 = dx * dx + dy * dy + zl * zl
                seen = np.ones(len(lx), bool)
                for bx0, by0, bx1, by1, bz in self.blockers:
                    px, py = x + dx * bz / zl, y + dy * bz / zl
                    seen &= ~((px > bx0) & (px < bx1) & (py > by0) & (py < by1))
                out[i] += RHO * e * (zl * zl / (np.pi * r2 * r2) * da * seen).sum() / np.pi
        return out


XS = np.linspace(-1.9, 1.9, 39)
POINTS = np.array([(x, y, 0) for y in XS for x in XS], np.float32)
NORMALS = np.tile(np.float32([0, 0, 1]), (len(POINTS), 1))


def floor_scene(n, blocker=0.3):
    s = Scene()
    faces = s.floor(n)
    s.blocker(blocker)
    s.lamp(0.0)
    return s, faces


def radiance(sol):
    return sol.radiance(POINTS, NORMALS)[:, 0].astype(np.float64)


def against(got, ref, peak):
    return float(np.abs(got - ref).max() / peak), float(np.abs(got - ref).mean() / peak)


@pytest.fixture(scope="module")
def one_quad():
    s, _ = floor_scene(1)
    sol = _native.solve(*s.args(), {})
    return sol, radiance(sol), s.exact(POINTS)


@pytest.mark.parametrize("n", [4, 8])
def test_a_floor_of_many_faces_takes_one_texture_and_equals_the_one_quad_floor(n, one_quad):
    """A floor object of n x n quads is a planar cluster: one link per lamp lights every face through one set of
    textures over the floor's box, the same box as the one-quad floor's, so the answer is the same."""
    s, faces = floor_scene(n)
    sol = _native.solve(*s.args(), {})
    links = sol.convolution_links
    assert len(links) == 1 and sorted(links[0]["receiver_polygons"]) == faces
    got = radiance(sol)
    _, ref, exact = one_quad
    peak = exact.max()
    worst, mean = against(got, exact, peak)
    print(f"{n} x {n} faces: against the exact worst {worst:.4f}, mean {mean:.4f}; "
          f"against one quad {against(got, ref, peak)[0]:.2e}")
    assert against(got, ref, peak)[0] <= 1e-6          # measured 0: bit-identical
    assert worst <= 0.025 and mean <= 0.003           # measured 1.88 %, 0.13 %


@pytest.mark.parametrize("planar", [False, True])
def test_a_floor_of_two_triangles_is_lit_once_per_face(planar, one_quad):
    """Two triangles hang from the scene's only cluster beside the blocker and the lamp, which is not planar:
    each triangle takes its own link. With planar_clusters they are split off into a cluster of their own and
    take one link. Either way each face is lit once and the answer is the one-quad floor's."""
    s, faces = floor_scene("tri")
    sol = _native.solve(*s.args(), {"planar_clusters": planar})
    assert len(sol.convolution_links) == (1 if planar else 2)
    lit = sorted(p for l in sol.convolution_links for p in l["receiver_polygons"])
    assert lit == faces
    _, ref, exact = one_quad
    assert against(radiance(sol), ref, exact.max())[0] <= 1e-6    # measured 0


def test_the_lightmap_of_a_floor_of_many_faces_holds_the_exact_shadow(one_quad):
    """The bake asks every texel of every face's triangles: each gets the link's texture at its own position."""
    s, faces = floor_scene(8)
    sol = _native.solve(*s.args(), {})
    verts = np.array(s.verts, np.float32)
    tris = []
    for p in faces:
        q = s.polys[p]
        tris += [verts[[q[0], q[1], q[2]]], verts[[q[0], q[2], q[3]]]]
    positions = np.array(tris, np.float32)
    uvs = ((positions[:, :, :2] + 2) / 4).astype(np.float32)
    size = 48
    img = sol.bake_lightmap(positions, uvs, size, size, 0)[:, :, 0].astype(np.float64)
    c = -2 + 4 * (np.arange(size) + 0.5) / size          # texel centres; rows run bottom to top (y)
    texels = np.array([(x, y, 0) for y in c for x in c], np.float32)
    exact = s.exact(texels)
    worst = float(np.abs(img.ravel() - exact).max() / exact.max())
    one = one_quad[0].bake_lightmap(np.array([[(-2, -2, 0), (2, -2, 0), (2, 2, 0)], [(-2, -2, 0), (2, 2, 0), (-2, 2, 0)]],
                                             np.float32),
                                    np.array([[(0, 0), (1, 0), (1, 1)], [(0, 0), (1, 1), (0, 1)]], np.float32),
                                    size, size, 0)[:, :, 0]
    apart = float(np.abs(img - one).max() / exact.max())
    print(f"lightmap {size}^2 of 128 triangles: against the exact worst {worst:.4f}; against the one-quad floor's "
          f"{apart:.2e}")
    assert worst <= 0.025       # measured 1.65 %
    assert apart <= 1e-6        # measured 8e-8 (float32)


def lamps_scene(second_emit=EMIT, z=2.0, second_z=None, gap=0.3, blocker=0.5):
    """Two 0.5 m lamps side by side, `gap` apart, as two objects; with second_z None both are `z` up, one plane."""
    s = Scene()
    s.floor(4)
    s.blocker(blocker)
    half = (0.5 + gap) / 2
    a = s.lamp(-half, z=z)
    b = s.lamp(half, z=z if second_z is None else second_z, emit=second_emit, obj=3)
    return s, a, b


def single_lamp(which, **kw):
    """lamps_scene's first or second lamp alone."""
    s, a, b = lamps_scene(**kw)
    keep = a if which == 0 else b
    drop = b if which == 0 else a
    s.emis[drop] = [0.0] * 3
    s.flags[drop] = _native.LIGHT_ONLY
    s.lamps = [s.lamps[which]]
    return _native.solve(*s.args(), {})


@pytest.mark.parametrize("second_emit", [EMIT, EMIT / 2])
def test_two_coplanar_lamps_are_one_source_and_match_each_lamp_alone(second_emit):
    """4 m up, the cluster of the two lamps is a planar group of emitters small enough against its distance for
    the parts: one link, its source image holding both lamps (an emission image with nothing between them and
    each lamp's own exitance). It must give the sum of the two single-lamp links and the exact shadow of both."""
    s, a, b = lamps_scene(second_emit, z=4.0)
    sol = _native.solve(*s.args(), {})
    links = sol.convolution_links
    assert len(links) == 1 and sorted(links[0]["source_polygons"]) == [a, b]
    got = radiance(sol)
    exact = s.exact(POINTS)
    peak = exact.max()
    alone = radiance(single_lamp(0, second_emit=second_emit, z=4.0)) + \
        radiance(single_lamp(1, second_emit=second_emit, z=4.0))
    worst, mean = against(got, exact, peak)
    sum_worst, _ = against(got, alone, peak)
    print(f"two lamps 4 m up (second at {second_emit}): {len(links[0]['textures'])} textures; against the exact "
          f"worst {worst:.4f}, mean {mean:.4f}; against the single lamps' sum worst {sum_worst:.4f}")
    # Measured: exact 1.10 % / 0.04 % (1.25 % / 0.04 % with the second lamp at half); the single lamps (one part
    # each) 0.89 % and 0.95 % from the exact, erring the other way in the penumbrae, so 1.99 % (2.20 %) apart.
    assert worst <= 0.02 and mean <= 0.003
    assert sum_worst <= 0.03


@pytest.mark.parametrize("gap", [-0.25, -0.1])
def test_overlapping_coplanar_lamps_add_up_in_the_source_image(gap):
    """Two lamps overlapping by half or a fifth (a lamp doubled in place): where they overlap the source image must
    hold both exitances, as the form factors of both faces do."""
    s, a, b = lamps_scene(gap=gap, z=4.0)
    sol = _native.solve(*s.args(), {})
    assert [sorted(l["source_polygons"]) for l in sol.convolution_links] == [[a, b]]
    exact = s.exact(POINTS)
    worst, mean = against(radiance(sol), exact, exact.max())
    print(f"lamps overlapping by {-gap} m: against the exact worst {worst:.4f}, mean {mean:.4f}")
    # Measured 1.31 % and 0.84 % worst (7.34 % and 4.30 % when the image counted one face where two overlap).
    assert worst <= 0.02 and mean <= 0.002


@pytest.mark.parametrize("gap", [0.3, 1.0])
def test_lamps_too_far_apart_for_one_source_take_a_link_each(gap):
    """2 m up, the two lamps' rectangle (1.3 or 2 m) would need more than 4 x 4 parts of 1/8 of the distance: the
    pair is refused as one source and each lamp takes its own link, the same as with each lamp alone."""
    s, a, b = lamps_scene(gap=gap)
    sol = _native.solve(*s.args(), {})
    links = sol.convolution_links
    assert sorted(tuple(l["source_polygons"]) for l in links) == [(a,), (b,)]
    assert sol.report["convolution_refused"]["too_coarse"] >= 1
    got = radiance(sol)
    exact = s.exact(POINTS)
    peak = exact.max()
    alone = radiance(single_lamp(0, gap=gap)) + radiance(single_lamp(1, gap=gap))
    worst, mean = against(got, exact, peak)
    print(f"lamps {gap} m apart, 2 m up: against the exact worst {worst:.4f}, mean {mean:.4f}; against the single "
          f"lamps' sum {against(got, alone, peak)[0]:.2e}")
    assert against(got, alone, peak)[0] <= 1e-5      # measured 6e-8
    # Measured 1.85 % / 0.19 % and 2.23 % / 0.16 %. As one source (before this refusal) the pair was cut into
    # 4 x 4 parts of 0.33 x 0.13 m and 0.5 x 0.13 m: 1.38 % and 3.02 % worst.
    assert worst <= 0.025 and mean <= 0.003


def test_two_lamps_at_different_heights_are_two_sources():
    """Lamps 2 m and 2.4 m up share no plane, so their cluster is no emitter group: the refiner narrows the source
    down to each lamp, and the floor takes one link per lamp, the same links as with each lamp alone."""
    s, a, b = lamps_scene(second_z=2.4)
    sol = _native.solve(*s.args(), {})
    links = sol.convolution_links
    assert sorted(tuple(l["source_polygons"]) for l in links) == [(a,), (b,)]
    got = radiance(sol)
    exact = s.exact(POINTS)
    peak = exact.max()
    alone = radiance(single_lamp(0, second_z=2.4)) + radiance(single_lamp(1, second_z=2.4))
    worst, mean = against(got, exact, peak)
    print(f"lamps at 2 and 2.4 m: against the exact worst {worst:.4f}, mean {mean:.4f}; against the single lamps' "
          f"sum {against(got, alone, peak)[0]:.2e}")
    assert against(got, alone, peak)[0] <= 1e-5      # measured 6e-8 (float32 sums)
    assert worst <= 0.025 and mean <= 0.003          # measured 1.61 %, 0.16 %

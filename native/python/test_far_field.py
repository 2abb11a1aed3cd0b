"""far_field (issue 14): cluster sources linked whole up to half their distance (0.5) or 0.3 of it (the default since
stop 30) instead of a fifth (0.2, the default before) give the same light within 0.5 % on the Cornell box and the
office. Measured: the Cornell box at the
default epsilon 0.35 % RMS, 0.14 % in the mean; the office 0.33 % and 0.07 % at the default epsilon, 0.44 % and 0.15 %
at epsilon 0.0005 (run here, for half the time), 0.57 % and 0.15 % at 0.002. The office takes fewer links (482k ->
441k at 0.0005; 2.37M -> 0.97M for the 10k office at 0.002); the Cornell box, too small for its clusters to be far
from anything, 3 % more (70k -> 72k). At 0.3 (stop 30): the Cornell box 0.071 % RMS and 0.012 % in the mean, the office
0.188 % and 0.049 % at epsilon 0.0005 (links 482k -> 454k).

The light compared is the radiance at a 3 x 3 grid of points on every face, as a relative RMS over the points
and as the difference of the means, both relative to the mean. The office is examples/scalable_scene.py's
1000-polygon office; the Cornell box is the classic room of 0.5 m tiles with its two blocks and ceiling lamp.
"""
import os
import sys

import numpy as np
import pytest

import _native
from corpus import Builder

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "examples"))
import scalable_scene  # noqa: E402

TOLERANCE = 0.005


def _cornell():
    b = Builder()
    n, size, height = 4, 2.0, 2.0
    step = size / n
    # Floor, ceiling and walls in n x n tiles, so that the walls' tiles form clusters of their own.
    for i in range(n):
        for j in range(n):
            x0, y0 = -1 + i * step, -1 + j * step
            b.face([(x0, y0, 0), (x0 + step, y0, 0), (x0 + step, y0 + step, 0), (x0, y0 + step, 0)], "Floor", rho=0.7)
            b.face([(x0, y0, height), (x0, y0 + step, height), (x0 + step, y0 + step, height), (x0 + step, y0, height)],
                   "Ceiling", rho=0.7)
            z0 = j * step
            b.face([(-1, x0, z0), (-1, x0 + step, z0), (-1, x0 + step, z0 + step), (-1, x0, z0 + step)], "Red", rho=0.5)
            b.face([(1, x0, z0), (1, x0, z0 + step), (1, x0 + step, z0 + step), (1, x0 + step, z0)], "Green", rho=0.5)
            b.face([(x0, 1, z0), (x0, 1, z0 + step), (x0 + step, 1, z0 + step), (x0 + step, 1, z0)], "Back", rho=0.7)
    b.box((-0.6, -0.5, 0.0), (-0.05, 0.3, 1.2), "Tall", rho=0.7)
    b.box((0.1, -0.7, 0.0), (0.65, -0.15, 0.6), "Short", rho=0.7)
    b.lamp(0.0, 0.0, height - 0.01, 0.5, 30.0)
    keys = ("vertices", "polygons", "reflectance", "emission", "flags", "object_index", "object_names")
    return dict(zip(keys, b.arrays()))


def _office():
    return scalable_scene.make_scene(1000, seed=0)


EPSILON = {"_cornell": 0.0002, "_office": 0.0005}


def _probe(scene):
    v, polys = np.asarray(scene["vertices"], np.float64), scene["polygons"]
    pts, nrm = [], []
    for f in polys:
        c = v[[i for i in f if i >= 0]]
        if len(c) == 3:
            c = np.vstack([c, c[2:3]])
        n = np.cross(c[1] - c[0], c[2] - c[0])
        n /= np.linalg.norm(n)
        for s in (1 / 6, 1 / 2, 5 / 6):
            for t in (1 / 6, 1 / 2, 5 / 6):
                q = (1 - s) * (1 - t) * c[0] + s * (1 - t) * c[1] + s * t * c[2] + (1 - s) * t * c[3]
                pts.append(q + 1e-4 * n)
                nrm.append(n)
    return np.ascontiguousarray(pts, np.float32), np.ascontiguousarray(nrm, np.float32)


@pytest.mark.parametrize("make", [_cornell, _office], ids=["cornell", "office"])
def test_far_clusters_give_the_same_light_with_fewer_links(make):
    scene = make()
    pts, nrm = _probe(scene)
    out = {}
    for far in (0.2, 0.3, 0.5):
        sol = _native.solve(**scene, settings={"far_field": far, "epsilon": EPSILON[make.__name__],
                                                    "threads": 2})
        rad = np.asarray(sol.radiance(pts, nrm))
        out[far] = (rad[:, :3].mean(axis=1), dict(sol.report))
    a = out[0.2][0]
    mean = a.mean()
    # 0.3 is the default since stop 30, 0.2 the default before it: the default's answer may not move either.
    for far in (0.3, 0.5):
        b = out[far][0]
        rms = np.sqrt(np.mean((b - a) ** 2)) / mean
        shift = abs(b.mean() - mean) / mean
        print(f"\n{make.__name__} at {far}: links {out[0.2][1]['links']} -> {out[far][1]['links']}, "
              f"RMS {100 * rms:.3f} %, mean {100 * shift:.3f} %")
        assert rms <= TOLERANCE
        assert shift <= TOLERANCE
        if make is _office:
            assert out[far][1]["links"] < 0.99 * out[0.2][1]["links"]

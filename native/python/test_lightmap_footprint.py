"""A lightmap texel across a shadow's edge takes the mean over its footprint (`texel_samples`, bake/lightmap.h).

A sun straight down (angle 0: one hard shadow ray per point) and a black bar 0.1 m wide at 1 m over a 6 m floor:
the bar's shadow is exactly the strip under it, narrower than the 0.25 m texels of a 24 x 24 lightmap, and one
column of texels has its centre inside it. Blender 3.4's bake spreads a texel's samples over a square half a texel
wide about its centre (measured, stop 49), so that column's value in Cycles is the lit share of that square; from
its centre alone it is 0. `texel_samples` is 1 (the centre) by default.
"""
import numpy as np
import pytest

import _native

RHO = 0.5
SUN = 2.0        # W/m^2 straight down
RES = 24         # texels of 0.25 m over the 6 m floor
BAR = (0.30, 0.40)  # the bar's (and its shadow's) x extent; texel column 13 spans 0.25..0.50, centre 0.375


def _scene(bar=True):
    v = [[-3, -3, 0], [3, -3, 0], [3, 3, 0], [-3, 3, 0]]
    polys = [[0, 1, 2, 3]]
    if bar:
        v += [[BAR[0], -3, 1], [BAR[1], -3, 1], [BAR[1], 3, 1], [BAR[0], 3, 1]]
        polys.append([4, 5, 6, 7])
    n = len(polys)
    rho = np.zeros((n, 3), np.float32)
    rho[0] = RHO  # the bar is black: the floor takes the sun alone
    return (np.array(v, np.float32), np.array(polys, np.int32), rho, np.zeros((n, 3), np.float32),
            np.zeros(n, np.uint8), np.arange(n, dtype=np.int32), ["Floor", "Bar"][:n])


def _bake(texel_samples, bar=True):
    sun = {"type": "SUN", "value": (SUN, SUN, SUN), "direction": (0.0, 0.0, -1.0), "angle": 0.0}
    sol = _native.solve(*_scene(bar), settings={"texel_samples": texel_samples}, lights=[sun])
    pos = np.array([[(-3, -3, 0), (3, -3, 0), (3, 3, 0)], [(-3, -3, 0), (3, 3, 0), (-3, 3, 0)]], np.float32)
    uv = (pos[:, :, :2] + 3) / 6
    return sol.bake_lightmap(pos, uv, RES, RES, 0)[:, :, 0].astype(np.float64)


def _box_lit_share(col):
    """The lit share of texel column `col`'s footprint: a square half a texel wide about its centre."""
    w = 6 / RES
    c = -3 + (col + 0.5) * w
    lo, hi = c - w / 4, c + w / 4
    shadow = max(0.0, min(hi, BAR[1]) - max(lo, BAR[0]))
    return 1 - shadow / (hi - lo)


def test_a_texel_across_a_shadow_narrower_than_itself_takes_its_footprints_lit_share():
    lit = RHO * SUN / np.pi
    col = 13
    centre = _bake(1)
    mean = _bake(4)
    rows = slice(2, RES - 2)  # away from the floor's edge, where the strip ends
    # From its centre the column is in full shadow; the neighbours are lit.
    assert np.all(centre[rows, col] < 0.01 * lit), centre[rows, col]
    assert np.allclose(centre[rows, col - 1], lit, rtol=1e-3) and np.allclose(centre[rows, col + 1], lit, rtol=1e-3)
    # As its footprint's mean: the lit share of the half-texel square (0.30 here), to within what four points
    # per side can resolve of a straight edge (an eighth of the texel's light).
    want = _box_lit_share(col) * lit
    assert want == pytest.approx(0.30 * lit)
    off = [r for r in range(rows.start, rows.stop) if r != col]
    assert np.all(np.abs(mean[off, col] - want) <= lit / 8), (mean[off, col], want)
    # The texel on the floor's diagonal: its points stay on its own triangle, as Cycles keeps them, those
    # off it mirrored through the centre, which turns the square's other half over: within a quarter.
    assert abs(mean[col, col] - want) <= lit / 4, (mean[col, col], want)
    # Texels whose footprint the shadow does not reach keep their light.
    assert np.allclose(mean[rows, col - 1], lit, rtol=1e-3) and np.allclose(mean[rows, col + 1], lit, rtol=1e-3)


def test_where_no_shadow_falls_the_footprints_change_nothing():
    # Without the bar the floor is lit evenly: no texel bends, and both bakes are the same to the last bit.
    one, four = _bake(1, bar=False), _bake(4, bar=False)
    assert np.array_equal(one, four)
    assert np.allclose(one, RHO * SUN / np.pi, rtol=1e-4)

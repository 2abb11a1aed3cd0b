"""radiance(..., irradiance=True) and bake_lightmap(..., irradiance=True): the light arriving at a surface, E/pi,
without its albedo -- what the add-on multiplies by a per-texel albedo, and what an irradiance bake stores."""
import math

import numpy as np
import pytest

import _native
from test_solver import lambert_irradiance_factor, plane_and_lamp

UP = np.array([0, 0, 1], np.float32)


def _floor_wall_lamp(rho_left, rho_right, wall_rho=(0.7, 0.7, 0.7)):
    """A 4 x 2 floor cut into two quads of different albedo meeting at x = 0, a wall at x = 2 facing -x, and a
    0.5 m lamp 1 m above the floor centre."""
    verts = np.array([[-2, -1, 0], [0, -1, 0], [0, 1, 0], [-2, 1, 0], [2, -1, 0], [2, 1, 0],
                      [2, -1, 0], [2, 1, 0], [2, 1, 1.5], [2, -1, 1.5],
                      [-.25, -.25, 1], [-.25, .25, 1], [.25, .25, 1], [.25, -.25, 1]], np.float32)
    polys = np.array([[0, 1, 2, 3], [1, 4, 5, 2], [9, 8, 7, 6], [10, 11, 12, 13]], np.int32)
    refl = np.array([rho_left, rho_right, wall_rho, [0, 0, 0]], np.float32)
    emis = np.array([[0, 0, 0]] * 3 + [[10, 10, 10]], np.float32)
    fl = np.array([0, 0, 0, _native.LIGHT_ONLY], np.uint8)
    obj = np.array([0, 0, 1, 2], np.int32)
    return verts, polys, refl, emis, fl, obj, ["Floor", "Wall", "Lamp"]


@pytest.mark.parametrize("settings", [{}, {"final_gather": False}, {"convolution": False}])
def test_irradiance_times_albedo_is_the_radiance(settings):
    rho_l, rho_r = (0.6, 0.3, 0.1), (0.2, 0.5, 0.8)
    sol = _native.solve(*_floor_wall_lamp(rho_l, rho_r), settings=settings)
    xs = np.array([-1.7, -1.1, -0.5, -0.2, 0.3, 0.9, 1.6])
    pts = np.array([[x, y, 0] for x in xs for y in (-0.6, 0.0, 0.4)], np.float32)
    nrm = np.tile(UP, (len(pts), 1))
    rad = sol.radiance(pts, nrm)
    irr = sol.radiance(pts, nrm, irradiance=True)
    rho = np.where(pts[:, :1] < 0, rho_l, rho_r)
    np.testing.assert_allclose(irr * rho, rad, rtol=2e-5, atol=1e-7)
    # The irradiance does not depend on the albedo of the point's own face: it is grey light here.
    assert np.ptp(irr, axis=1).max() < 0.02 * irr.max()


def test_irradiance_is_continuous_across_a_seam_between_two_albedos():
    """Leaves are divided by their own albedo before the blend, so the blend across the seam does not mix a
    dark face's albedo into a bright face's light."""
    sol = _native.solve(*_floor_wall_lamp((0.9, 0.9, 0.9), (0.05, 0.05, 0.05)))
    pts = np.array([[-0.01, 0.2, 0], [0.01, 0.2, 0]], np.float32)
    irr = sol.radiance(pts, np.tile(UP, (2, 1)), irradiance=True)
    assert irr[0] == pytest.approx(irr[1], rel=0.01)
    rad = sol.radiance(pts, np.tile(UP, (2, 1)))
    assert rad[0][0] / rad[1][0] == pytest.approx(0.9 / 0.05, rel=0.02)


def test_irradiance_under_a_lamp_is_lamberts_whatever_the_albedo():
    for rho in (0.1, 0.5, 0.9):
        args = plane_and_lamp(rho=rho)
        sol = _native.solve(*args)
        lamp = args[0][4:8].astype(np.float64)
        pts = np.array([[x, y, 0] for x in (-0.3, 0.0, 0.45) for y in (-0.25, 0.35)], np.float32)
        got = sol.radiance(pts, np.tile(UP, (len(pts), 1)), irradiance=True)
        for p, g in zip(pts, got):
            # A 4 m plane under a 0.5 m lamp: its own bounce is nil (nothing above reflects it back).
            direct = 10.0 * lambert_irradiance_factor(p.astype(np.float64), np.array([0, 0, 1.0]), lamp) / math.pi
            assert g == pytest.approx([direct] * 3, rel=0.01)


def test_wall_light_follows_the_floor_albedo():
    """The irradiance on the wall is mostly what the floor bounces: a darker floor darkens it."""
    p = np.array([[2.0, 0.0, 0.3], [2.0, 0.5, 0.8]], np.float32)
    n = np.tile(np.array([-1, 0, 0], np.float32), (2, 1))
    bright = _native.solve(*_floor_wall_lamp((0.8,) * 3, (0.8,) * 3))
    dark = _native.solve(*_floor_wall_lamp((0.2,) * 3, (0.2,) * 3))
    assert np.all(dark.radiance(p, n, irradiance=True) < 0.8 * bright.radiance(p, n, irradiance=True))
    np.testing.assert_allclose(dark.radiance(p, n, irradiance=True) * 0.7, dark.radiance(p, n), rtol=2e-5)


def test_lightmap_irradiance_texels_are_the_point_irradiance():
    args = plane_and_lamp(rho=0.4)
    sol = _native.solve(*args, settings={"epsilon": 0.002})
    P = args[0][:4]
    pos = np.array([[P[0], P[1], P[2]], [P[0], P[2], P[3]]], np.float32)
    uv = np.array([[[0.0, 0.0], [1.0, 0.0], [1.0, 1.0]], [[0.0, 0.0], [1.0, 1.0], [0.0, 1.0]]], np.float32)
    rad = sol.bake_lightmap(pos, uv, 16, 16, 2)
    irr = sol.bake_lightmap(pos, uv, 16, 16, 2, irradiance=True)
    np.testing.assert_allclose(irr[..., :3] * 0.4, rad[..., :3], rtol=2e-5, atol=1e-8)
    x = y = -2 + 4 * (5.5 / 16)
    ref = sol.radiance(np.array([[x, y, 0]], np.float32), UP[None], irradiance=True)[0]
    assert irr[5, 5, :3] == pytest.approx(ref, rel=1e-5)
    assert np.all(irr[..., 3] == 1)

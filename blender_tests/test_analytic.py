"""Direct light from each kind of emitter onto a Lambert plane, against Lambert's exact polygon formula.

Nothing but the plane reflects, so the plane's reflected radiance is exactly rho*E/pi, with E from the
emitter's radiance (blender-facts §1: area light P/(4A) one-sided toward local -Z; mesh emitter S*C).
"""
import math

import bpy
import numpy as np
import pytest

import helpers

ALBEDO = (0.5, 0.6, 0.7)
RES = 64
# The error-driven refinement needs a fine threshold for 1 % accuracy pointwise (1e-4 gives 1.5 % near the
# light's corners, 1e-5 gives 0.05 %).
SOLVER = {"epsilon": 2e-5}
# Texels under the light: within this distance of the plane's centre (the light is centred above it).
REGION = 0.45


def _check_plane(penumbra, scene, emitter_polygon, radiance):
    plane = bpy.data.objects["Plane"]
    report = penumbra.bake(scene, resolution=RES, targets={"LIGHTMAP"}, **SOLVER)
    assert "Plane" in report["objects_baked"]
    px = helpers.image_pixels(bpy.data.images[report["outputs"]["Plane"]["image"]])
    mask, pos = helpers.texel_world_positions(plane, plane["penumbra"]["uv_map"], RES, RES)
    under = mask & (np.hypot(pos[..., 0], pos[..., 1]) < REGION)
    assert under.sum() > 100
    pts = pos[under]
    normals = np.tile([0.0, 0.0, 1.0], (len(pts), 1))
    e = helpers.lambert_irradiance_factor(emitter_polygon, pts, normals)[:, None] * np.asarray(radiance)[None, :]
    expected = np.asarray(ALBEDO)[None, :] * e / math.pi
    got = px[under][:, :3]
    rel = np.abs(got / expected - 1)
    print(f"max rel. error {rel.max():.4f}, mean {rel.mean():.5f} over {len(pts)} texels; "
          f"centre expected {expected[np.argmin(np.hypot(pts[:, 0], pts[:, 1]))]}")
    assert rel.max() < 0.01
    return report


CASES = {
    "SQUARE": dict(size=1.0),
    "RECTANGLE": dict(size=0.6, size_y=1.2, rotation=(0, 0, 0.5), scale=(1.5, 1.0, 1.0)),
    "DISK": dict(size=1.0),
    "ELLIPSE": dict(size=0.7, size_y=1.3, rotation=(0, 0, -0.4)),
}


@pytest.mark.parametrize("shape", list(CASES))
def test_area_light_over_plane(empty_scene, penumbra, shape):
    kw = dict(CASES[shape])
    helpers.quad_object("Plane", 1.5, 1.5, material=helpers.diffuse_material("Lambert", ALBEDO))
    energy, color = 80.0, (1.0, 0.8, 0.6)
    ob = helpers.area_light("Light", shape, kw.pop("size"), kw.pop("size_y", None), energy=energy, color=color,
                            location=(0, 0, 0.8), **kw)
    bpy.context.view_layer.update()
    light = ob.data
    m = np.array(ob.matrix_world)
    sx = light.size
    sy = light.size_y if shape in ("RECTANGLE", "ELLIPSE") else light.size
    poly = helpers.ellipse_polygon(m, sx, sy) if shape in ("DISK", "ELLIPSE") else helpers.rect_polygon(m, sx, sy)
    area = helpers.polygon_area(poly)
    if shape in ("DISK", "ELLIPSE"):
        area = math.pi / 4 * sx * sy * abs(np.linalg.det(m[:2, :2]))     # the true ellipse, not the 4096-gon
    # Cycles' radiance P / (4A) before 4.0, P / (pi A) since (compat.area_light_exitance).
    radiance = energy * np.asarray(color) / ((4 if bpy.app.version < (4, 0, 0) else math.pi) * area)
    _check_plane(penumbra, empty_scene, poly, radiance)


def test_emissive_quad_over_plane(empty_scene, penumbra):
    helpers.quad_object("Plane", 1.5, 1.5, material=helpers.diffuse_material("Lambert", ALBEDO))
    strength, color = 6.0, (0.9, 1.0, 0.5)
    helpers.quad_object("Emitter", 0.5, 0.4, z=0.7, flip=True, cuts=2,
                        material=helpers.emission_material("Glow", color, strength))
    poly = np.array([[-0.5, -0.4, 0.7], [0.5, -0.4, 0.7], [0.5, 0.4, 0.7], [-0.5, 0.4, 0.7]])
    report = _check_plane(penumbra, empty_scene, poly, strength * np.asarray(color))
    assert "Emitter" in report["objects_baked"]


def test_area_light_faces_local_minus_z(empty_scene, penumbra):
    """A light turned upside down (emitting toward +Z) leaves the plane below it dark."""
    helpers.quad_object("Plane", 1.5, 1.5, material=helpers.diffuse_material("Lambert", ALBEDO))
    helpers.quad_object("Ceiling", 1.5, 1.5, z=2.0, flip=True, material=helpers.diffuse_material("W", ALBEDO))
    helpers.area_light("Up", "SQUARE", 0.5, location=(0, 0, 1.0), rotation=(math.pi, 0, 0))
    report = penumbra.bake(empty_scene, resolution=32, targets={"LIGHTMAP"})
    ceiling = helpers.image_pixels(bpy.data.images[report["outputs"]["Ceiling"]["image"]])[..., :3]
    plane = helpers.image_pixels(bpy.data.images[report["outputs"]["Plane"]["image"]])[..., :3]
    # The plane is lit only by what the ceiling reflects; directly lit, the ceiling is far brighter.
    assert ceiling.max() > 5 * plane.max() > 0

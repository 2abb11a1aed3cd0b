"""Analytic lights (point, spot, sun, world) through the module's `lights` argument."""
import math

import numpy as np
import pytest

import _native

RHO = 0.5


def _floor():
    v = np.array([[-3, -3, 0], [3, -3, 0], [3, 3, 0], [-3, 3, 0]], np.float32)
    return (v, np.array([[0, 1, 2, 3]], np.int32), np.full((1, 3), RHO, np.float32), np.zeros((1, 3), np.float32),
            np.zeros(1, np.uint8), np.zeros(1, np.int32), ["Floor", "Lamp"])


def _irradiance(sol, pts):
    p = np.asarray(pts, np.float32)
    n = np.tile(np.array([0, 0, 1], np.float32), (len(p), 1))
    return sol.radiance(p, n)[:, 0] * math.pi / RHO


def test_lights_alone_light_the_scene_in_cycles_units():
    pts = [(0.0, 0.0, 0.0), (1.0, -0.5, 0.0), (2.5, 2.0, 0.0)]
    lamp = {"type": "POINT", "value": (80.0, 80.0, 80.0), "position": (0.2, 0.1, 1.5), "radius": 0.2, "object": 1}
    sun = {"type": "SUN", "value": (2.0, 2.0, 2.0), "direction": (0.0, math.sin(0.5), -math.cos(0.5)),
           "angle": math.radians(30)}
    world = {"type": "WORLD", "value": (0.25, 0.25, 0.25)}
    sol = _native.solve(*_floor(), lights=[lamp, sun, world])
    got = _irradiance(sol, pts)
    t = math.tan(math.radians(15))
    expect = []
    for p in pts:
        d = np.array(lamp["position"]) - p
        d2 = d @ d
        e = 80.0 * d[2] / math.sqrt(d2) / (4 * math.pi * (d2 + 0.04))
        e += 2.0 * 2 * (math.sqrt(1 + t * t) - 1) / (t * t) * math.cos(0.5)
        e += math.pi * 0.25
        expect.append(e)
    assert np.allclose(got, expect, rtol=1e-4), (got, expect)
    assert sol.report["lights"] == 3 and sol.report["light_rays"] > 0


@pytest.mark.parametrize("light, message", [
    ({"type": "AREA", "value": (1, 1, 1)}, "type must be POINT, SPOT, SUN or WORLD"),
    ({"type": "POINT"}, "missing 'value'"),
    ({"type": "POINT", "value": (1, 1, 1), "colour": (1, 1, 1)}, "unknown key 'colour'"),
    ({"type": "POINT", "value": (-1, 1, 1), "object": 1}, "light 'Lamp': negative power"),
    ({"type": "SPOT", "value": (1, 1, 1), "spot_size": 0.0}, "spot size"),
    ({"type": "SUN", "value": (1, 1, 1), "angle": 4.0}, "sun angle"),
    ({"type": "POINT", "value": (1, 1, 1), "position": (0, float("nan"), 1)}, "NaN"),
    ({"type": "POINT", "value": (1, 1, 1), "environment": np.ones((2, 4, 3), np.float32)}, "only the world"),
    ({"type": "WORLD", "value": (1, 1, 1), "environment": np.ones((2, 4, 3))}, "dtype float32"),
    ({"type": "WORLD", "value": (1, 1, 1), "environment": -np.ones((2, 4, 3), np.float32)}, "negative"),
])
def test_bad_lights_are_refused_by_name(light, message):
    with pytest.raises(ValueError, match=message):
        _native.solve(*_floor(), lights=[light])


def test_a_dark_scene_still_says_nothing_emits():
    with pytest.raises(ValueError, match="nothing emits light"):
        _native.solve(*_floor(), lights=[{"type": "WORLD", "value": (0, 0, 0)}])

"""A receiver that cannot split, standing on a large source whose light varies (refiner.cpp refineElements): it
takes the light of the source's parts, not the source's mean. A 2 x 2 cm card (under min_size) stands on a 4 m
floor lit by a small lamp and faces the lamp, so its own shadow falls behind it and the floor it sees is lit
unshadowed; its light is compared with the exact answer computed here (Lambert's formula per 1 cm floor cell).
Found on the scaling office, where monitor stands on desks took the whole desk's mean light (the desk's corner
on the stand's plane made the form factor's spread outweigh the desk's deviation)."""
import numpy as np
import pytest

import _native

EMIT, RHO, LAMP, LX, LZ = 50.0, 0.5, 0.1, 0.5, 0.5   # lamp half side, centre x, height
CH, CW = 0.02, 0.01                                   # card height, half width
LAMP_QUAD = np.array([[LX - LAMP, -LAMP, LZ], [LX + LAMP, -LAMP, LZ], [LX + LAMP, LAMP, LZ], [LX - LAMP, LAMP, LZ]])


def scene(card_x):
    faces = [[(0, -0.5, 0), (4, -0.5, 0), (4, 0.5, 0), (0, 0.5, 0)],
             LAMP_QUAD[::-1].tolist(),
             [(card_x, CW, 0), (card_x, -CW, 0), (card_x, -CW, CH), (card_x, CW, CH)]]   # faces -x
    return dict(vertices=np.array([p for f in faces for p in f], np.float32),
                polygons=np.arange(12, dtype=np.int32).reshape(3, 4),
                reflectance=np.array([[RHO] * 3, [0] * 3, [RHO] * 3], np.float32),
                emission=np.array([[0] * 3, [EMIT] * 3, [0] * 3], np.float32),
                flags=np.array([0, _native.LIGHT_ONLY, 0], np.uint8),
                object_index=np.array([0, 1, 2], np.int32), object_names=["Floor", "Lamp", "Card"])


def form_factors(points, normal, quads):
    """Lambert's formula from each point (K,3) to each quad (K,4,3), all in front of the points' plane."""
    c = quads - points[:, None, :]
    c /= np.linalg.norm(c, axis=2, keepdims=True)
    total = np.zeros(len(points))
    for i in range(4):
        a, b = c[:, i], c[:, (i + 1) % 4]
        g = np.cross(a, b)
        total += (g @ normal) / np.linalg.norm(g, axis=1) * np.arccos(np.clip(np.sum(a * b, axis=1), -1, 1))
    return np.abs(total) / (2 * np.pi)


def exact(card_x, cell=0.01):
    """E/pi on the card, averaged over 4 x 4 points: the lamp's direct light and the floor's first bounce (the
    floor in front of the card is unshadowed, its radiosity RHO * EMIT * F(point -> lamp))."""
    xs = np.arange(0, card_x - 1e-9, cell)
    X, Y = [a.ravel() for a in np.meshgrid(xs, np.arange(-0.5, 0.5 - 1e-9, cell), indexing="ij")]
    X1 = np.minimum(X + cell, card_x)
    z = np.zeros_like(X)
    quads = np.stack([np.stack(q, 1) for q in ((X, Y, z), (X1, Y, z), (X1, Y + cell, z), (X, Y + cell, z))], 1)
    centres = np.stack([(X + X1) / 2, Y + cell / 2, z], 1)
    B = RHO * EMIT * form_factors(centres, np.array([0, 0, 1.0]), np.broadcast_to(LAMP_QUAD, (len(X), 4, 3)).copy())
    direct, bounce = [], []
    n = np.array([-1.0, 0, 0])
    for h in (np.arange(4) + 0.5) / 4 * CH:
        for y in (np.arange(4) + 0.5) / 4 * 2 * CW - CW:
            p = np.array([[card_x, y, h]])
            direct.append(EMIT / np.pi * form_factors(p, n, LAMP_QUAD[None].copy())[0])
            bounce.append(B @ form_factors(np.repeat(p, len(X), 0), n, quads) / np.pi)
    return np.mean(direct), np.mean(bounce)


@pytest.mark.parametrize("card_x", [0.8, 1.0])
def test_a_card_on_a_floor_takes_the_light_of_the_floors_parts(card_x):
    direct, bounce = exact(card_x)
    sol = _native.solve(**scene(card_x), settings={})
    got = sol.radiance(np.array([[card_x - 1e-5, 0, CH / 2]], np.float32), np.array([[-1, 0, 0]], np.float32),
                       irradiance=True)[0]
    # The floor's bounce is 31 % (at 0.8 m) and 22 % of the card's light. Measured: 0.93 and 1.01 of it; with the
    # floor taken whole at the card (before stop 35), 0.75 and 1.32.
    assert (got - direct) / bounce == pytest.approx(np.ones(3), abs=0.1)

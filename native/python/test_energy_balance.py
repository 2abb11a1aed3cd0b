"""A closed room absorbs exactly the light its lamps emit, whatever stands in it: the surfaces' absorbed power
sum(A (1 - rho) E) over the lamps' sum(A M) is 1 for the exact answer. A shortfall is light the solver lost
between bounces, and it shows against Cycles as a bias of every surface lit by reflection (the scaling office's
ceiling was 2.9 % dark at epsilon 0.002, docs/scaling.md, stop 38).

Measured by this file at stop 37 (before each link's visibility was the form factor's visible share, and before a
reflector's rays from its part inside a solid stopped counting, refiner.cpp estimateVisibility): the 2 m room with
two boxes standing on its floor absorbed 97.61 % of the light at epsilon 0.002 and 98.68 % at the default, the 1k
scaling office 99.00 % at 0.002; then 98.80 %, 99.42 % and 99.49 %, and with a cluster source's faces drawn by their
parts' light too (refiner.cpp, drawFromSampler) 99.21 %, 99.38 % and 99.54 %. With the boxes lifted 30 cm off the floor
the room kept 99.7 % before, so most of what was lost was where things stand on others.
Stop 42: a face's kernel beyond its near field is the point kernel with its second-order term rather than the disc
estimate (hierarchy/node.cpp, faceKernel), which read oblique transfers low: 99.44 %, 99.37 % and 99.86 %.
Stop 43: a link kept from an earlier refinement pass whose light could move by a tenth of the threshold is weighted
again by its source's parts' present light before the last solve (refiner.cpp, rerefine); its weights had been those
of the pass that made it, or none, while the links made later into the same source took the parts' new light, so the
receivers no longer took from each part what it sends: 100.22 %, 99.56 % and 100.02 %; the empty room without
clustering 98.92 -> 100.05 %. (Every kept link weighted again: 99.55 %, 99.54 %, 99.90 % and 99.98 %.)
Stop 46: the `seed` setting draws every ray anew, and the balance moves with the pattern alone: over seeds 0-5 the
boxes room at epsilon 0.002 absorbed 100.22 / 99.83 / 99.91 / 100.74 / 101.01 / 100.21 % (mean 100.32, standard
deviation 0.46), at the default 99.61 +- 0.09, the 1k office 100.04 +- 0.08, the dark 5k office 100.05 +- 0.65 (one seed
101.31 %). One pattern passing or failing said little: each case is now judged by its mean over several seeds (what
the method loses), every seed within a looser band (what one bake may show).
"""
import os
import sys

import numpy as np
import pytest

import _native
from corpus import Builder

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "examples"))
import scalable_scene  # noqa: E402


def _room_with_boxes(n=4, rho=0.7, boxes=True):
    """A closed 2 m room of n x n tiles a wall, every tile facing in, two boxes on the floor (unless `boxes` is
    false), a lamp under the ceiling."""
    b = Builder()
    centre = np.array([0.0, 0.0, 1.0])
    walls = (((-1, -1, 0), (2, 0, 0), (0, 2, 0), "Floor"), ((-1, -1, 2), (2, 0, 0), (0, 2, 0), "Ceiling"),
             ((-1, -1, 0), (0, 2, 0), (0, 0, 2), "Left"), ((1, -1, 0), (0, 2, 0), (0, 0, 2), "Right"),
             ((-1, -1, 0), (2, 0, 0), (0, 0, 2), "Front"), ((-1, 1, 0), (2, 0, 0), (0, 0, 2), "Back"))
    for origin, u, v, name in walls:
        o, u, v = np.array(origin, float), np.array(u, float) / n, np.array(v, float) / n
        if np.dot(np.cross(u, v), centre - o) < 0:
            u, v = v, u
        for i in range(n):
            for j in range(n):
                a = o + i * u + j * v
                b.face([a, a + u, a + u + v, a + v], name, rho=rho)
    if boxes:
        b.box((-0.6, -0.5, 0.0), (-0.05, 0.3, 1.2), "Tall", rho=rho)
        b.box((0.1, -0.7, 0.0), (0.65, -0.15, 0.6), "Short", rho=rho)
    b.lamp(0.0, 0.0, 1.99, 0.5, 30.0)
    keys = ("vertices", "polygons", "reflectance", "emission", "flags", "object_index", "object_names")
    return dict(zip(keys, b.arrays()))


def _office():
    return scalable_scene.make_scene(1000, seed=0)


def _face_grids(scene, m, faces=None):
    """Per face (of `faces`, default all): an m x m grid of points lifted 0.1 mm off it, its normal repeated, and
    its area."""
    v = np.asarray(scene["vertices"], np.float64)
    s = (np.arange(m) + 0.5) / m
    s, t = (a.ravel()[:, None] for a in np.meshgrid(s, s))
    pts, nrm, area = [], [], []
    for k in range(len(scene["polygons"])) if faces is None else faces:
        c = v[[i for i in scene["polygons"][k] if i >= 0]]
        if len(c) == 3:
            c = np.vstack([c, c[2:3]])
        n = np.cross(c[2] - c[0], c[3] - c[1])
        area.append(0.5 * np.linalg.norm(n))
        n /= np.linalg.norm(n)
        q = (1 - s) * (1 - t) * c[0] + s * (1 - t) * c[1] + s * t * c[2] + (1 - s) * t * c[3]
        pts.append(q + 1e-4 * n)
        nrm.append(np.repeat(n[None], m * m, axis=0))
    return pts, nrm, np.array(area)


def absorbed_over_emitted(scene, settings, m=8):
    """Mean over the colours of the absorbed over the emitted power, the irradiance averaged over an m x m grid
    of points on each face."""
    rho = np.asarray(scene["reflectance"], np.float64)
    emit = np.asarray(scene["emission"], np.float64)
    lamp = (np.asarray(scene["flags"]) & _native.LIGHT_ONLY) != 0
    pts, nrm, area = _face_grids(scene, m)
    sol = _native.solve(**scene, settings={"threads": 2, **settings})
    e = np.pi * np.asarray(sol.radiance(np.float32(np.vstack(pts)), np.float32(np.vstack(nrm)), irradiance=True))
    e = e[:, :3].reshape(len(area), m * m, 3).mean(axis=1)
    absorbed = (e[~lamp] * (1 - rho[~lamp]) * area[~lamp, None]).sum(axis=0)
    emitted = (emit[lamp] * area[lamp, None]).sum(axis=0)
    return float((absorbed / emitted).mean())


def _empty_room():
    return _room_with_boxes(boxes=False)


def balance_over_seeds(scene, settings, seeds):
    """absorbed_over_emitted for each seed of `seeds`: the same room and settings drawn with other rays."""
    return np.array([absorbed_over_emitted(scene, {**settings, "seed": seed}) for seed in seeds])


def check_balance(name, scene, settings, seeds, mean_tolerance, each_tolerance):
    ratios = balance_over_seeds(scene, settings, seeds)
    print(f"\n{name} with {settings}: absorbed / emitted over seeds {list(seeds)}: "
          + " ".join(f"{r:.4f}" for r in ratios) + f", mean {ratios.mean():.4f}")
    assert abs(ratios.mean() - 1) <= mean_tolerance
    assert np.all(np.abs(ratios - 1) <= each_tolerance)


@pytest.mark.parametrize("make, settings, seeds, mean_tolerance, each_tolerance", [
    # Seeds 0-5 at stop 46: mean 100.32 %, 99.83-101.01 % (seed 0 alone: was 2.39 % short, then 0.79 %, 0.56 %, 0.22 % over).
    # Stop 48 (a floor element's mean form factor from a box side standing across it taken over its part in front,
    # refiner.cpp meanPoints): mean 100.85 %, 100.29-101.63 %. Of that, the grid points under the boxes, where no
    # light arrives, hold 0.51 % (seeds 0-3); and with clustering off the same room reads 99.14 % (98.94 % before the
    # change): the added light is the element links' due, and the excess is the cluster paths' (docs/scaling.md).
    (_room_with_boxes, {"epsilon": 0.002}, range(6), 0.01, 0.02),
    # Mean 99.61 %, 99.49-99.71 % (seed 0: 1.32 % short, then 0.62 %, 0.44 %); stop 48: 99.77 %
    (_room_with_boxes, {"epsilon": 0.0002}, range(4), 0.006, 0.01),
    # Mean 100.04 %, 99.95-100.18 % (seed 0: 1.00 % short, then 0.46 %, 0.14 %, 0.02 % over)
    (_office, {"epsilon": 0.002}, range(4), 0.004, 0.006),
    # Element links alone: kept links' parts weights stale by a pass lost 1.08 %; refreshed, 0.05 % over (stop 43).
    # No ray is cast in an empty room: one seed is every seed.
    (_empty_room, {"epsilon": 0.002, "clustering": False}, range(1), 0.003, 0.003),
], ids=["boxes-0.002", "boxes-default", "office-0.002", "empty-no-clusters"])
def test_a_closed_room_absorbs_the_light_its_lamps_emit(make, settings, seeds, mean_tolerance, each_tolerance):
    check_balance(make.__name__, make(), settings, seeds, mean_tolerance, each_tolerance)


def test_a_dark_room_keeps_its_direct_light():
    """With every albedo a hundredth of its own the 5k office is lit almost only by its lamps, and its links are
    coarse: the floor's faces take their light through shared cluster links, each face's share from four rays.
    Counted alike, the rays under-read the floor (furniture hides the low, oblique directions, which carry little
    light): 98.42 % absorbed. Weighted by the kernel over the density they were drawn with: 99.65 % (seed 0); over
    seeds 0-5 a mean of 100.05 %, one seed 101.31 % (the ratio of sums over four rays a face is what moves)."""
    scene = scalable_scene.make_scene(5000, seed=0)
    rho = np.asarray(scene["reflectance"])
    scene["reflectance"] = np.ascontiguousarray(rho * 0.01, dtype=rho.dtype)
    check_balance("dark 5k office", scene, {"epsilon": 0.002}, range(6), 0.0075, 0.015)


def test_seeds_draw_other_rays():
    """The measure above sees the pattern: two seeds of the boxes room differ (else the means would be of one bake)."""
    r = balance_over_seeds(_room_with_boxes(), {"epsilon": 0.002}, [0, 1])
    assert r[0] != r[1]


def test_the_measure_sees_lost_light():
    """The balance is no identity: a room with a window (one ceiling tile gone) lets light out, and the measure
    says so (3.8 % of the lamp's light leaves through a sixteenth of the ceiling)."""
    scene = _room_with_boxes()
    names = scene["object_names"]
    ceiling = np.nonzero(np.asarray(scene["object_index"]) == names.index("Ceiling"))[0]
    keep = np.ones(len(scene["polygons"]), bool)
    keep[ceiling[5]] = False
    open_room = dict(scene)
    for k in ("polygons", "reflectance", "emission", "flags", "object_index"):
        open_room[k] = np.ascontiguousarray(np.asarray(scene[k])[keep])
    ratio = absorbed_over_emitted(open_room, {"epsilon": 0.0002})
    print(f"\nopen room: absorbed / emitted {ratio:.4f}")
    assert ratio < 0.98


def _floor_with_slabs(n=6, cover=0.5):
    """A closed 3 x 3 x 2 m room whose floor is n x n tiles (albedo 0.8), each with a closed 1 cm slab standing on its
    middle over `cover` of its area, walls and ceiling of 3 x 3 tiles (0.3), a lamp under the ceiling shining down."""
    b = Builder()
    w = 3.0 / n
    h = w * np.sqrt(cover) / 2
    for i in range(n):
        for j in range(n):
            x0, y0 = -1.5 + i * w, -1.5 + j * w
            b.face([(x0, y0, 0), (x0 + w, y0, 0), (x0 + w, y0 + w, 0), (x0, y0 + w, 0)], "Floor", rho=0.8)
            cx, cy = x0 + w / 2, y0 + w / 2
            b.box((cx - h, cy - h, 0.0), (cx + h, cy + h, 0.01), "Slabs", rho=0.8)
    for name, o, u, v in (("Ceiling", (-1.5, -1.5, 2), (0, 3, 0), (3, 0, 0)), ("Walls", (-1.5, -1.5, 0), (0, 3, 0), (0, 0, 2)),
                          ("Walls", (1.5, -1.5, 0), (0, 0, 2), (0, 3, 0)), ("Walls", (-1.5, -1.5, 0), (0, 0, 2), (3, 0, 0)),
                          ("Walls", (-1.5, 1.5, 0), (3, 0, 0), (0, 0, 2))):
        o, u, v = np.array(o, float), np.array(u, float) / 3, np.array(v, float) / 3
        for i in range(3):
            for j in range(3):
                a = o + i * u + j * v
                b.face([a, a + u, a + u + v, a + v], name, rho=0.3)
    b.lamp(0.0, 0.0, 1.95, 1.0, 30.0)
    keys = ("vertices", "polygons", "reflectance", "emission", "flags", "object_index", "object_names")
    return dict(zip(keys, b.arrays()))


def _ceiling_radiance(scene, settings):
    ceiling = np.nonzero(np.asarray(scene["object_index"]) == list(scene["object_names"]).index("Ceiling"))[0]
    pts, nrm, _ = _face_grids(scene, 4, ceiling)
    sol = _native.solve(**scene, settings={"threads": 2, **settings})
    radiance = np.asarray(sol.radiance(np.float32(np.vstack(pts)), np.float32(np.vstack(nrm))))
    return float(radiance[:, :3].mean()), sol.report["cluster_links"]


def test_light_from_under_a_slab_is_not_cut_twice_by_cluster_links():
    """Half of every floor tile lies under a slab: it receives nothing, so the tile's radiosity, its mean, already
    holds that dark half, and what the tile reflects leaves from the other half. A ray from the hidden half meets the
    slab's inside; counted as shadow, it cuts that light a second time. The element links have left such rays out
    since stop 38 (so the solve without clustering is the yardstick here); the cluster links, face shares and source
    shares counted them until stop 47: the ceiling, lit mostly by the floor, read 0.806 of the element links' answer
    at epsilon 0.002, then 0.929; with a tile's four rays all from under its slab (one time in sixteen) taking the
    share of the link's other rays instead of none, 0.953. The rest: every tile was taken for buried (its centre and
    the points halfway to its corners lie under the slab), and a buried face takes no light from cluster links;
    tested near its corners too, 1.004 (seeds 1, 2: 1.005, 0.999; the default epsilon 1.012, 0.958 before)."""
    scene = _floor_with_slabs()
    on, cluster_links = _ceiling_radiance(scene, {"epsilon": 0.002})
    off, _ = _ceiling_radiance(scene, {"epsilon": 0.002, "clustering": False})
    print(f"\nslabs room: ceiling with clusters over without {on / off:.4f} ({cluster_links} cluster links)")
    assert cluster_links > 500
    assert abs(on / off - 1) < 0.02

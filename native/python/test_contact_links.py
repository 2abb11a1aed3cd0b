"""Convolution links where the blocker stands on its receiver (issue 12): a box on a floor and a table on a floor
under a square lamp, against the exact direct light of contact_scenes.py. Before contact sub-blockers these pairs
were refused (E_rr unbounded in units of a penumbra that vanishes at the contact) and fell to standard
refinement."""
import numpy as np
import pytest

import _native
import contact_scenes


def radiance(sol, scene, pts):
    normals = np.tile(scene.normal.astype(np.float32), (len(pts), 1))
    return sol.radiance(pts.astype(np.float32), normals)[:, 0].astype(np.float64)


def errors(got, exact):
    return (float(np.sqrt(((got - exact) ** 2).sum() / (exact ** 2).sum())),
            float(np.abs(got - exact).max() / exact.max()))


# contact_slabs is off by default (settings.h): on the Cornell box it measured less accurate. t_max is set far
# above any predicted FFT time: whether a link fits the default 0.05 s hangs on the FFT cost timed at start-up,
# so on the machine's load (these tests failed while the ASan build ran beside them); what they measure is the
# texture's accuracy, and test_convolution_links checks that t_max refuses.
CONTACT = {"contact_slabs": True, "t_max": 1e6}


@pytest.fixture(scope="module", params=["box_on_floor", "table_on_floor"])
def case(request):
    scene = getattr(contact_scenes, request.param)()
    pts = scene.sample_points(48)
    return request.param, scene, pts, scene.exact_radiance(pts)


def test_contact_pairs_take_a_convolution_link(case):
    name, scene, pts, exact = case
    sol = _native.solve(*scene.args, CONTACT)
    rep = sol.report
    assert rep["convolution_links"] >= 1 and rep["rays"] == 0, rep
    assert rep["convolution_refused"]["too_coarse"] == 0
    links = sol.convolution_links
    assert all(l["sub_blockers"] >= 2 for l in links)      # the contact slab and the slabs above it


def test_contact_shadow_matches_the_exact_light_better_than_standard_refinement(case):
    name, scene, pts, exact = case
    conv = _native.solve(*scene.args, CONTACT)
    std = _native.solve(*scene.args, {"convolution": False})
    c_rms, c_worst = errors(radiance(conv, scene, pts), exact)
    s_rms, s_worst = errors(radiance(std, scene, pts), exact)
    print(f"{name}: convolution {c_rms:.4f} RMS, {c_worst:.4f} worst; standard {s_rms:.4f}, {s_worst:.4f}")
    # Measured on this 48 x 48 grid: box 0.71 % / 3.1 % against standard 2.4 % / 24 %; table 1.1 % / 4.7 %
    # against 1.5 % / 12 %. The table's worst points are in the penumbra of its top, which shares the top slab
    # with the upper legs (a kernel up to e_max halves of a penumbra off); the standard refiner's RMS there
    # moves with the grid (0.9 % on 40 x 40), its worst misses do not.
    assert c_rms < 0.02 and c_worst < 0.08
    assert c_worst < s_worst


def test_no_light_under_the_object(case):
    """The floor a leg or the box covers gets no direct light: the contact slab carries the object's
    cross-section, so its map is dark there whatever the slabs above let through."""
    name, scene, pts, exact = case
    under = scene.under_points()
    assert len(under) > 0 and np.all(scene.exact_radiance(under) == 0)
    got = radiance(_native.solve(*scene.args, CONTACT), scene, under)
    assert got.max() <= 0.01 * exact.max(), got.max() / exact.max()

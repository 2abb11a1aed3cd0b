"""The Cornell box bake against the stored Cycles reference (examples/make_cycles_reference.py)."""
import json
import os

import bpy
import numpy as np
import pytest

import cornell_box
from conftest import HERE

REFERENCE = os.path.join(HERE, "data", "cornell_reference.json")
# Issue 2 asks for 5 % now; the product goal is 2 %.
# The issue accepts 5 % for now; the measured 1.8 % is guarded more tightly so regressions show.
MAX_RELATIVE_RMS = 0.025
# The solver's defaults (epsilon 0.0002): 1.8 % in about 0.4 s here.
SOLVER = {}


def lightmap_face_averages(report, name):
    ob = bpy.data.objects[name]
    img = bpy.data.images[report["outputs"][name]["image"]]
    w, h = img.size
    px = np.empty(w * h * 4, np.float32)
    img.pixels.foreach_get(px)
    mean, _, count = cornell_box.face_texel_averages(ob.data, ob["penumbra"]["uv_map"], px.reshape(h, w, 4))
    assert (count > 0).all(), f"{name}: faces without texels"
    return mean


def _relative_rms(scene, penumbra, ref, **solver):
    report = penumbra.bake(scene, resolution=ref["settings"]["resolution"], targets={"LIGHTMAP"}, **solver)
    diff2 = ref2 = noise2 = 0.0
    lines = []
    for name in cornell_box.RECEIVERS:
        r = np.array(ref["objects"][name]["radiance"])
        se = np.array(ref["objects"][name]["stderr"])
        p = lightmap_face_averages(report, name)
        assert p.shape == r.shape, name
        diff2 += ((p - r) ** 2).sum()
        ref2 += (r ** 2).sum()
        noise2 += (se ** 2).sum()
        lines.append(f"{name:10s} mean ratio {p.sum() / r.sum():.4f}  rel RMS "
                     f"{np.sqrt(((p - r) ** 2).sum() / (r ** 2).sum()):.4f}")
    print("\n".join(lines))
    return float(np.sqrt(diff2 / ref2)), float(np.sqrt(noise2 / ref2)), report


@pytest.fixture(scope="module")
def reference():
    with open(REFERENCE) as f:
        return json.load(f)


@pytest.fixture(scope="module")
def default_bake(penumbra, reference):
    """The box baked at the solver's defaults (clustering on): what both tests below compare, baked once (the
    clustering test baked it a second time with clustering=True, the default)."""
    bpy.ops.wm.read_homefile(use_empty=True)
    cornell_box.build()
    return _relative_rms(bpy.context.scene, penumbra, reference, **SOLVER)


def test_cornell_box_matches_cycles(default_bake):
    rel, noise, report = default_bake
    print(f"Cornell box vs Cycles: relative RMS {rel:.4f} over per-face averages (reference noise {noise:.4f}); "
          f"solve {report['times']['solve']:.2f} s, {report['elements']} elements, {report['links']} links")
    assert noise < 0.01
    assert rel < MAX_RELATIVE_RMS


def test_clustering_is_no_worse_on_the_cornell_box(empty_scene, penumbra, reference, default_bake):
    """Issue 3: clusters must not cost accuracy where every face pair could be linked directly."""
    on, _, report = default_bake
    assert report["settings"].get("clustering", True) is True
    cornell_box.build()
    off, _, _ = _relative_rms(empty_scene, penumbra, reference, clustering=False, **SOLVER)
    print(f"Cornell box vs Cycles: clustering on {on:.4f} ({report['clusters']} clusters, {report['cluster_links']} cluster links, {report['links']} links), off {off:.4f}")
    assert report["clusters"] > 1
    # Half a tenth of a percent of slack: the two link structures sample visibility differently.
    assert on <= off + 0.0005

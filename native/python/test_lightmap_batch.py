"""bake_lightmaps (many lightmaps in one call, spread over the threads) against bake_lightmap one at a time, and
uv_overlaps: the write-back's batched calls must give the very texels the object-by-object calls give."""
import numpy as np
import pytest

import _native
import corpus


@pytest.fixture(scope="module")
def room():
    args = corpus.room().arrays()
    pos, uv = corpus.atlas(args)
    return args, pos, uv


def _objects(pos, uv):
    """The atlas's triangles cut into lightmaps of different sizes (one of them empty), each with its own UVs."""
    cuts = [0, 1, 9, 9, 40, 100, len(pos)]
    out = []
    for a, b in zip(cuts, cuts[1:]):
        p = np.ascontiguousarray(pos[a:b])
        u = np.ascontiguousarray(uv[a:b])
        if len(u):
            # Each object's triangles spread over its own UV square, as an unwrap gives them.
            u = (u - u.min(axis=(0, 1))) / max(float(np.ptp(u)), 1e-6) * 0.98 + 0.01
        out.append((p, u.astype(np.float32)))
    return out


@pytest.mark.parametrize("threads", [1, 2, 3])
def test_batch_is_bit_identical_to_one_call_per_lightmap(room, threads):
    args, pos, uv = room
    sol = _native.solve(*args, settings={"threads": threads})
    objs = _objects(pos, uv)
    irr = [False, True, False, True, False, False]
    for res, margin in [(16, 2), (37, 3)]:
        batch = sol.bake_lightmaps([p for p, _ in objs], [u for _, u in objs], res, res, margin, irradiance=irr)
        assert batch.shape == (len(objs), res, res, 4) and batch.dtype == np.float32
        for k, (p, u) in enumerate(objs):
            one = sol.bake_lightmap(p, u, res, res, margin, irradiance=irr[k])
            np.testing.assert_array_equal(batch[k], one)
        assert batch[..., :3].max() > 0 and np.all(batch[2, ..., :3] == 0)   # lit; the empty one black
    one_flag = sol.bake_lightmaps([p for p, _ in objs], [u for _, u in objs], 16, 16, 2, irradiance=True)
    for k, (p, u) in enumerate(objs):
        np.testing.assert_array_equal(one_flag[k], sol.bake_lightmap(p, u, 16, 16, 2, irradiance=True))
    assert sol.bake_lightmaps([], [], 8, 8, 1).shape == (0, 8, 8, 4)


def test_batch_is_the_same_for_any_thread_count(room):
    args, pos, uv = room
    objs = _objects(pos, uv)
    out = [_native.solve(*args, settings={"threads": t}).bake_lightmaps([p for p, _ in objs], [u for _, u in objs],
                                                                        24, 24, 2) for t in (1, 2, 4)]
    np.testing.assert_array_equal(out[0], out[1])
    np.testing.assert_array_equal(out[0], out[2])


def test_batch_refuses_bad_input_by_index(room):
    args, pos, uv = room
    sol = _native.solve(*args)
    with pytest.raises(ValueError, match="differ in length"):
        sol.bake_lightmaps([pos], [uv, uv], 8, 8, 1)
    with pytest.raises(ValueError, match=r"uvs\[1\]"):
        sol.bake_lightmaps([pos, pos], [uv, uv.astype(np.float64)], 8, 8, 1)
    bad = pos.copy()
    bad[0, 0, 0] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        sol.bake_lightmaps([pos, bad], [uv, uv], 8, 8, 1)
    with pytest.raises(ValueError, match="one bool per lightmap"):
        sol.bake_lightmaps([pos, pos], [uv, uv], 8, 8, 1, irradiance=[True])
    with pytest.raises(ValueError, match="width"):
        sol.bake_lightmaps([pos], [uv], 0, 8, 1)
    small = _native.solve(*args, settings={"max_texels": 100})
    with pytest.raises(_native.BudgetExceeded, match="max_texels"):
        small.bake_lightmaps([pos], [uv], 16, 16, 1)


def _uv_overlap_reference(uvs, grid):
    """The add-on's numpy uv_overlap (writeback.py), written out again: texel centres strictly inside more than
    one triangle over the texels inside any."""
    counts = np.zeros((grid, grid), np.int64)
    t = np.asarray(uvs, np.float64) * grid - 0.5
    for a, b, c in t:
        det = (b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1])
        if not abs(det) > 1e-12:
            continue
        lo = np.clip(np.ceil(np.minimum(np.minimum(a, b), c)), 0, grid - 1).astype(int)
        hi = np.clip(np.floor(np.maximum(np.maximum(a, b), c)), -1, grid - 1).astype(int)
        for py in range(lo[1], hi[1] + 1):
            for px in range(lo[0], hi[0] + 1):
                l1 = ((px - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (py - a[1])) / det
                l2 = ((b[0] - a[0]) * (py - a[1]) - (px - a[0]) * (b[1] - a[1])) / det
                if l1 > 1e-6 and l2 > 1e-6 and 1.0 - l1 - l2 > 1e-6:
                    counts[py, px] += 1
    covered = int((counts > 0).sum())
    return float((counts > 1).sum()) / covered if covered else 0.0


def test_uv_overlaps_match_the_reference():
    rng = np.random.default_rng(7)
    sets = [rng.random((n, 3, 2)).astype(np.float32) for n in (1, 4, 30)]
    sets.append((rng.random((20, 3, 2)) * 1.6 - 0.3).astype(np.float32))      # partly outside [0, 1]
    sets.append(np.zeros((0, 3, 2), np.float32))
    quad = np.array([[[0.1, 0.1], [0.9, 0.1], [0.9, 0.9]], [[0.1, 0.1], [0.9, 0.9], [0.1, 0.9]]], np.float32)
    sets.append(quad)                                   # two triangles sharing an edge: no overlap
    sets.append(np.concatenate([quad, quad]))           # the same island twice: all shared
    for grid in (8, 32):
        got = _native.uv_overlaps(sets, grid)
        assert got.dtype == np.float64 and len(got) == len(sets)
        assert list(got) == [_uv_overlap_reference(u, grid) for u in sets]
    assert _native.uv_overlaps([quad], 32)[0] == 0.0
    assert _native.uv_overlaps([np.concatenate([quad, quad])], 32)[0] == 1.0

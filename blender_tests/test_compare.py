"""penumbra.compare_cycles: figures that agree with Cycles, detect a wrong bake, and leave the .blend as it was."""
import os

import bpy
import numpy as np
import pytest

import cornell_box
from helpers import assert_same_state, blend_state, image_pixels


def render_settings(scene):
    c = scene.cycles
    return (scene.render.engine, c.samples, c.seed, c.diffuse_bounces, c.max_bounces, c.sample_clamp_indirect,
            c.use_denoising, c.use_adaptive_sampling, scene.render.film_transparent, scene.render.filepath,
            scene.render.image_settings.file_format, scene.render.image_settings.color_depth,
            scene.render.use_file_extension, scene.render.resolution_x,
            tuple((vl.cycles.use_denoising, vl.use_pass_emit) for vl in scene.view_layers))


@pytest.fixture
def baked_box(empty_scene, penumbra):
    cornell_box.build()
    empty_scene.render.resolution_x = empty_scene.render.resolution_y = 64
    penumbra.bake(empty_scene, resolution=32)
    return empty_scene


def test_camera_comparison_agrees_and_restores(baked_box, penumbra, tmp_path):
    scene = baked_box
    penumbra.preview(scene, True)        # the user had the preview on: it must stay on
    before, settings = blend_state(), render_settings(scene)
    figs = penumbra.compare_cycles(scene, samples=64, out_dir=str(tmp_path))
    assert_same_state(before, blend_state())
    assert render_settings(scene) == settings
    print({k: v for k, v in figs.items() if k != "files"})
    # Emitters and background are excluded: the lamp and the open front leave about 60 % of the frame.
    assert 0.4 * 64 * 64 < figs["pixels"] < 0.9 * 64 * 64
    assert 0 < figs["noise_relative_rms"] < figs["relative_rms"]
    # The bake is 2-3 % off per face; per pixel the rest is the reference's noise, which is removed here.
    assert figs["relative_rms_corrected"] < 0.08
    assert abs(figs["mean_bias"]) < 0.04
    assert figs["noise_p95_relative"] > 0 and figs["p95_relative_error"] > 0
    for key in ("cycles_exr", "penumbra_exr", "heatmap_png", "side_by_side_png"):
        assert os.path.getsize(figs["files"][key]) > 0, key
    img = bpy.data.images.load(figs["files"]["side_by_side_png"])
    assert img.size[1] == 64 and img.size[0] > 3 * 64
    bpy.data.images.remove(img)


def test_camera_comparison_detects_a_wrong_bake(baked_box, penumbra):
    """A bake made 25 % too bright must show as a +25 % bias, well outside the reference's noise."""
    scene = baked_box
    for ob in scene.objects:
        st = ob.get("penumbra")
        if st is None:
            continue
        img = bpy.data.images[st["image"]]
        px = image_pixels(img)
        px[..., :3] *= 1.25
        img.pixels.foreach_set(px.ravel())
    figs = penumbra.compare_cycles(scene, samples=32)
    print({k: v for k, v in figs.items() if k != "files"})
    assert 0.18 < figs["mean_bias"] < 0.32
    assert figs["relative_rms_corrected"] > 0.15


def test_lightmap_comparison(baked_box, penumbra, tmp_path):
    from penumbra import compare
    scene = baked_box
    before, settings = blend_state(), render_settings(scene)
    figs = penumbra.compare_cycles(scene, samples=16, space="LIGHTMAP", out_dir=str(tmp_path))
    assert_same_state(before, blend_state())
    assert render_settings(scene) == settings
    print(compare.summary(figs))
    assert set(figs["objects"]) == set(cornell_box.RECEIVERS)     # the lamp emits, so it is not compared
    faces = figs["faces"]
    assert 0 < faces["noise_relative_rms"] < 0.05
    assert faces["relative_rms_corrected"] < 0.05
    assert abs(faces["mean_bias"]) < 0.04
    assert figs["texels"]["samples"] > 1000
    assert os.path.exists(figs["objects"]["Floor"]["files"]["cycles_exr"])


def test_operator_and_errors(baked_box, penumbra):
    scene = baked_box
    assert bpy.ops.penumbra.compare_cycles(samples=4, space="LIGHTMAP") == {"FINISHED"}
    with pytest.raises(ValueError, match="samples"):
        penumbra.compare_cycles(scene, samples=1)
    penumbra.clear(scene)
    with pytest.raises(ValueError, match="baked"):
        penumbra.compare_cycles(scene, samples=4)
    scene.camera = None
    with pytest.raises(ValueError, match="camera"):
        penumbra.compare_cycles(scene, samples=4)


def test_uv_owner_claims_the_texels_a_cycles_bake_writes(empty_scene, penumbra):
    """uv_owner decides which texels the benchmark and these tests score. A texel it claims but Cycles leaves
    unbaked reads as black and is scored as a wrong bake. Islands whose edges fall on texel centres (exactly,
    or a sliver narrower than a texel ending on one) are where the two rules part; every texel must agree."""
    from penumbra.compare import cycles_lightmaps, uv_owner
    from helpers import diffuse_material
    W = H = 16
    # (u0, u1, v0, v1) in texel units; the mesh is one row of unit quads facing +Z, each with its own island.
    islands = [(2.5, 5.5, 1.5, 4.5),      # every edge on a column or row of centres
               (7.3, 7.5, 1.0, 6.0),      # a sliver ending on a centre: Cycles bakes none of it
               (9.5, 9.7, 1.0, 6.0),      # a sliver starting on one
               (1.0, 6.0, 8.3, 8.5),      # the same across rows
               (8.2, 13.9, 8.1, 14.7)]    # an ordinary island
    verts, faces, uvs = [], [], []
    for k, (u0, u1, v0, v1) in enumerate(islands):
        x = 2.0 * k
        verts += [(x, 0, 0), (x + 1, 0, 0), (x + 1, 1, 0), (x, 1, 0)]
        faces.append((4 * k, 4 * k + 1, 4 * k + 2, 4 * k + 3))
        uvs += [(u0 / W, v0 / H), (u1 / W, v0 / H), (u1 / W, v1 / H), (u0 / W, v1 / H)]
    me = bpy.data.meshes.new("Islands")
    me.from_pydata(verts, [], faces)
    me.uv_layers.new(name="UVMap").data.foreach_set("uv", np.array(uvs, np.float32).ravel())
    me.materials.append(diffuse_material("White", (0.8, 0.8, 0.8)))
    ob = bpy.data.objects.new("Islands", me)
    empty_scene.collection.objects.link(ob)
    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN"))
    sun.data.energy = 3.0
    empty_scene.collection.objects.link(sun)
    empty_scene.render.engine = "CYCLES"
    maps, _ = cycles_lightmaps(empty_scene, {"Islands": ("UVMap", W, H)}, samples=1, margin=0)
    baked = maps["Islands"][..., :3].sum(axis=-1) > 0
    owner = uv_owner(me, "UVMap", W, H)
    assert baked.sum() > 30
    assert (owner == 1).sum() == 0 and (owner == 3).sum() == 0
    assert np.array_equal(owner >= 0, baked), (
        f"claimed but not baked {np.argwhere((owner >= 0) & ~baked).tolist()}, "
        f"baked but not claimed {np.argwhere(~(owner >= 0) & baked).tolist()}")

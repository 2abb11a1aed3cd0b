"""Bake the Cornell box with Cycles and store per-face radiance averages as the reference for the tests.

    blender -b --factory-startup --python-exit-code 1 --python examples/make_cycles_reference.py -- \
        [--samples 1024] [--resolution 128] [--out blender_tests/data/cornell_reference.json]

The bake is Cycles' DIFFUSE pass with Direct + Indirect + Color, which holds the outgoing diffuse radiance
B/pi that Penumbra's lightmaps hold as well. Each receiver gets its own smart-project UV map and image; the
per-face average over the texels inside each face is stored with a standard error from the texel noise.
Bounces are high and clamping is off because both bias a converged radiosity comparison (blender-facts
§2 and §8). About 5 minutes on two cores at the defaults.
"""
import argparse
import json
import os
import sys
import time

import bpy
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import cornell_box  # noqa: E402

sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "bench"))
from lightmap_uv import unwrap  # noqa: E402  (the same unwrap as the benchmarks')

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def parse_args():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    ap = argparse.ArgumentParser(prog="make_cycles_reference.py")
    ap.add_argument("--samples", type=int, default=1024)
    ap.add_argument("--resolution", type=int, default=128)
    ap.add_argument("--bounces", type=int, default=32)
    ap.add_argument("--out", default=os.path.join(REPO, "blender_tests", "data", "cornell_reference.json"))
    return ap.parse_args(argv)


def main():
    args = parse_args()
    t0 = time.time()
    cornell_box.clear_scene()
    obs = cornell_box.build()
    sc = bpy.context.scene
    sc.render.engine = "CYCLES"
    sc.cycles.device = "CPU"
    sc.cycles.samples = args.samples
    sc.cycles.use_adaptive_sampling = False
    sc.cycles.use_denoising = False
    for vl in sc.view_layers:
        vl.cycles.use_denoising = False
    sc.cycles.diffuse_bounces = args.bounces
    sc.cycles.max_bounces = args.bounces
    sc.cycles.sample_clamp_direct = 0.0
    sc.cycles.sample_clamp_indirect = 0.0
    sc.cycles.light_sampling_threshold = 0.0
    sc.cycles.seed = 0

    uv_name = "Lightmap"
    res = args.resolution
    result = {}
    for name in cornell_box.RECEIVERS:
        ob = obs[name]
        unwrap(ob, uv_name)
        img = bpy.data.images.new("Ref_" + name, res, res, alpha=False, float_buffer=True)
        for mat in ob.data.materials:
            nt = mat.node_tree
            node = nt.nodes.get("PenumbraRefTarget") or nt.nodes.new("ShaderNodeTexImage")
            node.name = "PenumbraRefTarget"
            node.image = img
            nt.nodes.active = node
        for o in bpy.context.view_layer.objects:
            o.select_set(False)
        ob.select_set(True)
        bpy.context.view_layer.objects.active = ob
        t = time.time()
        r = bpy.ops.object.bake(type="DIFFUSE", pass_filter={"DIRECT", "INDIRECT", "COLOR"}, margin=4,
                                margin_type="EXTEND", use_clear=True, target="IMAGE_TEXTURES", uv_layer=uv_name)
        if r != {"FINISHED"}:
            raise RuntimeError(f"Cycles bake of {name} returned {r}")
        px = np.empty(res * res * 4, np.float32)
        img.pixels.foreach_get(px)
        mean, se, count = cornell_box.face_texel_averages(ob.data, uv_name, px.reshape(res, res, 4))
        if (count == 0).any():
            raise RuntimeError(f"{name}: faces {np.nonzero(count == 0)[0].tolist()} cover no texel centre")
        rel = se.max(axis=1) / np.maximum(mean.max(axis=1), 1e-12)
        print(f"{name}: {len(count)} faces, {time.time() - t:.1f} s, texels/face {count.min()}..{count.max()}, "
              f"median rel. stderr {np.median(rel):.4f}, max {rel.max():.4f}", file=sys.stderr, flush=True)
        result[name] = {
            "radiance": np.round(mean, 6).tolist(),
            "stderr": np.round(se, 7).tolist(),
            "texels": count.tolist(),
        }

    all_mean = np.concatenate([np.array(v["radiance"]) for v in result.values()])
    all_se = np.concatenate([np.array(v["stderr"]) for v in result.values()])
    noise_rel_rms = float(np.sqrt((all_se ** 2).sum() / (all_mean ** 2).sum()))
    doc = {
        "what": "Cornell box (examples/cornell_box.py): per-face average of Cycles' DIFFUSE bake "
                "(Direct+Indirect+Color) over the texels whose centres lie inside each face; radiance in "
                "W m^-2 sr^-1 per colour unit (B/pi); stderr from adjacent-texel differences.",
        "generator": "examples/make_cycles_reference.py",
        "blender": bpy.app.version_string,
        "settings": {"samples": args.samples, "resolution": res, "diffuse_bounces": args.bounces,
                     "max_bounces": args.bounces, "sample_clamp_direct": 0, "sample_clamp_indirect": 0,
                     "adaptive_sampling": False, "denoising": False, "uv": "smart_project 66 deg, margin 0.02",
                     "seed": 0},
        "noise_relative_rms": noise_rel_rms,
        "seconds": round(time.time() - t0, 1),
        "objects": result,
    }
    os.makedirs(os.path.dirname(os.path.abspath(args.out)), exist_ok=True)
    with open(args.out, "w") as f:
        json.dump(doc, f, separators=(",", ":"))
    print(f"wrote {args.out}: reference noise (relative RMS of the face averages) {noise_rel_rms:.4f}, "
          f"{doc['seconds']} s", file=sys.stderr)


main()

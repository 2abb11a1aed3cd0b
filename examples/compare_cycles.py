"""Compare a scene's Penumbra bake with Cycles, headless.

    blender -b scene.blend --python-exit-code 1 --python examples/compare_cycles.py -- --out DIR [--samples N]
        [--space CAMERA|LIGHTMAP|BOTH] [--bake] [--resolution N] [--epsilon E] [--scene-script office]

If nothing in the file is baked (or with --bake) the scene is baked first with the given settings; the .blend on
disk is never written. DIR receives the EXRs, the difference and side-by-side PNGs and figures.json; the figures
are printed as one line per space. --scene-script builds one of examples/scenes.py's scenes instead of
using the opened file. The add-on comes from $PENUMBRA_ADDON_DIR (default <repo>/build/addon).
"""
import argparse
import json
import os
import sys

import bpy

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
from addon_env import enable_addon  # noqa: E402


def parse_args():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    ap = argparse.ArgumentParser(prog="blender -b file.blend --python examples/compare_cycles.py --")
    ap.add_argument("--out", required=True)
    ap.add_argument("--samples", type=int, default=256)
    ap.add_argument("--space", choices=("CAMERA", "LIGHTMAP", "BOTH"), default="CAMERA")
    ap.add_argument("--bake", action="store_true", help="bake even if the file holds a bake")
    ap.add_argument("--resolution", type=int, default=None, help="lightmap resolution when baking")
    ap.add_argument("--epsilon", type=float, default=None, help="refinement threshold when baking")
    ap.add_argument("--scene-script", default=None, help="build a scene from examples/scenes.py first")
    ap.add_argument("--render-size", type=int, default=None, help="render width and height in pixels")
    return ap.parse_args(argv)


def main():
    args = parse_args()
    penumbra = enable_addon("compare_cycles")
    from penumbra import compare
    if args.scene_script:
        import scenes
        bpy.ops.wm.read_homefile(use_empty=True)
        scenes.build(args.scene_script)
    scene = bpy.context.scene
    if args.render_size:
        scene.render.resolution_x = scene.render.resolution_y = args.render_size
        scene.render.resolution_percentage = 100
    out = os.path.abspath(args.out)
    os.makedirs(out, exist_ok=True)
    baked = any(o.get("penumbra") is not None for o in scene.objects)
    result = {}
    if args.bake or not baked:
        settings = {k: v for k, v in (("resolution", args.resolution), ("epsilon", args.epsilon)) if v is not None}
        report = penumbra.bake(scene, **settings)
        print(penumbra.summary(report), flush=True)
        result["bake"] = report
    spaces = ("CAMERA", "LIGHTMAP") if args.space == "BOTH" else (args.space,)
    for space in spaces:
        figs = penumbra.compare_cycles(scene, samples=args.samples, out_dir=out, space=space,
                                       progress=lambda s, f: print(f"compare: {s} {100 * f:.0f} %",
                                                                   file=sys.stderr, flush=True))
        result[space.lower()] = figs
        print(compare.summary(figs), flush=True)
    with open(os.path.join(out, "figures.json"), "w") as f:
        json.dump(result, f, indent=1)


main()

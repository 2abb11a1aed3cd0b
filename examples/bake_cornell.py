"""The main job: build the Cornell box (or another example scene), bake it with Penumbra, write the results.

    blender -b --factory-startup --python-exit-code 1 --python examples/bake_cornell.py -- --out out/cornell
    blender -b --factory-startup --python-exit-code 1 --python examples/bake_cornell.py -- --scene window \
        --out out/window

Writes to the output folder: the lightmaps (Penumbra_<object>.exr), <scene>_baked.blend, <scene>.png (the
camera view rendered by Cycles with the bake shown) and report.json, and prints a one-line summary.
--scene names one of examples/scenes.py's scenes (default cornell; "window" is issue 13's sun, sky and lamp).
The add-on is enabled from $PENUMBRA_ADDON_DIR (default <repo>/build/addon, made by scripts/build.sh).
"""
import argparse
import json
import os
import sys
import time

import bpy

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(HERE)
sys.path.insert(0, HERE)
import cornell_box  # noqa: E402
import scenes  # noqa: E402
from addon_env import enable_addon  # noqa: E402


def parse_args():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    ap = argparse.ArgumentParser(prog="blender -b --factory-startup --python examples/bake_cornell.py --")
    ap.add_argument("--scene", default="cornell", help="a scene of examples/scenes.py (default cornell)")
    ap.add_argument("--out", default=None, help="output folder (default out/<scene>)")
    ap.add_argument("--resolution", type=int, default=256)
    ap.add_argument("--epsilon", type=float, default=None,
                    help="refinement threshold (default: the solver's, 0.0002)")
    ap.add_argument("--render-size", type=int, default=400)
    ap.add_argument("--samples", type=int, default=16)
    return ap.parse_args(argv)


def render_png(scene, path, size, samples):
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = samples
    scene.cycles.use_adaptive_sampling = False
    # This Cycles has no OpenImageDenoise: with both flags on (the factory default) the render fails.
    scene.cycles.use_denoising = False
    for vl in scene.view_layers:
        vl.cycles.use_denoising = False
    scene.render.resolution_x = scene.render.resolution_y = size
    scene.render.resolution_percentage = 100
    scene.render.image_settings.file_format = "PNG"
    scene.render.image_settings.color_depth = "8"
    scene.render.filepath = path
    bpy.ops.render.render(write_still=True)


def main():
    args = parse_args()
    penumbra = enable_addon("bake_cornell")
    out = os.path.abspath(args.out or os.path.join(REPO, "out", args.scene))
    os.makedirs(out, exist_ok=True)
    cornell_box.clear_scene()
    scenes.build(args.scene)
    scene = bpy.context.scene

    def progress(stage, frac):
        print(f"penumbra: {stage} {100 * frac:5.1f} %", file=sys.stderr, flush=True)
        return True

    solver = {} if args.epsilon is None else {"epsilon": args.epsilon}
    report = penumbra.bake(scene, progress=progress, resolution=args.resolution, output_dir=out, **solver)
    blend = os.path.join(out, f"{args.scene}_baked.blend")
    t = time.perf_counter()
    bpy.ops.wm.save_as_mainfile(filepath=blend, copy=True)
    report["times"]["save_blend"] = time.perf_counter() - t

    penumbra.preview(scene, True)
    png = os.path.join(out, f"{args.scene}.png")
    t = time.perf_counter()
    render_png(scene, png, args.render_size, args.samples)
    report["times"]["render_png"] = time.perf_counter() - t
    penumbra.preview(scene, False)

    report["files"] = {"blend": blend, "png": png,
                       "exr": [o["exr"] for o in report["outputs"].values() if "exr" in o]}
    with open(os.path.join(out, "report.json"), "w") as f:
        json.dump(report, f, indent=1)
    for x in report["skipped"]:
        print(f"penumbra: skipped {x['name']}: {x['reason']}", file=sys.stderr)
    for w in report["warnings"]:
        print(f"penumbra: warning: {w}", file=sys.stderr)
    print(penumbra.summary(report) + f"; outputs in {out}", flush=True)


main()

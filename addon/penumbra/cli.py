"""Headless bake of a .blend:

    blender -b scene.blend --python-exit-code 1 --python <addon>/penumbra/cli.py -- --out DIR [options]

Progress goes to stderr, the report to DIR/report.json; the exit code is non-zero when the bake fails.
Run with `-- --help` for the options.
"""
import argparse
import json
import os
import sys
import time


def parse(argv):
    ap = argparse.ArgumentParser(
        prog="blender -b FILE.blend --python-exit-code 1 --python penumbra/cli.py --",
        description="Bake the scene's diffuse global illumination with Penumbra.")
    ap.add_argument("--out", required=True, help="output folder: report.json and the lightmaps as EXR")
    ap.add_argument("--resolution", type=int, default=256, help="lightmap size in texels (default 256)")
    ap.add_argument("--margin", type=int, default=4, help="texels filled past the UV islands (default 4)")
    ap.add_argument("--uv-map", default=None, help="existing UV map for the lightmaps (default: unwrap "
                    "'PenumbraLightmap')")
    ap.add_argument("--targets", default="LIGHTMAP,COLOR_ATTRIBUTE",
                    help="comma-separated subset of LIGHTMAP,COLOR_ATTRIBUTE")
    ap.add_argument("--selection-only", action="store_true", help="export only the selected objects")
    ap.add_argument("--epsilon", type=float, help="solver refinement threshold")
    ap.add_argument("--min-size", type=float, help="smallest element edge, relative to the scene diagonal")
    ap.add_argument("--max-iterations", type=int)
    ap.add_argument("--tolerance", type=float)
    ap.add_argument("--threads", type=int, help="solver threads (0 = all cores)")
    ap.add_argument("--save", metavar="FILE.blend", help="save the baked .blend here (default: DIR/baked.blend; "
                    "'none' to skip)")
    ap.add_argument("--scene", help="scene name (default: the active scene)")
    return ap.parse_args(argv)


def main():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    args = parse(argv)      # --help and bad options exit here, before Blender data is touched

    import bpy
    here = os.path.dirname(os.path.abspath(__file__))
    if os.path.dirname(here) not in sys.path:
        sys.path.insert(0, os.path.dirname(here))
    import addon_utils
    mod = addon_utils.enable(os.path.basename(here), default_set=True)
    if mod is None:
        raise SystemExit("penumbra: the add-on could not be enabled (see the error above)")
    import penumbra

    scene = bpy.data.scenes[args.scene] if args.scene else bpy.context.scene
    out = os.path.abspath(args.out)
    os.makedirs(out, exist_ok=True)
    t0 = time.perf_counter()
    last = {"stage": None, "t": 0.0}

    def progress(stage, frac):
        now = time.perf_counter()
        if stage != last["stage"] or now - last["t"] > 1.0:
            print(f"penumbra: {stage} {100 * frac:5.1f} % ({now - t0:.1f} s)", file=sys.stderr, flush=True)
            last.update(stage=stage, t=now)
        return True

    settings = {"resolution": args.resolution, "margin": args.margin, "uv_map": args.uv_map,
                "targets": {t.strip().upper() for t in args.targets.split(",") if t.strip()},
                "selection_only": args.selection_only, "output_dir": out, "epsilon": args.epsilon,
                "min_size": args.min_size, "max_iterations": args.max_iterations, "tolerance": args.tolerance,
                "threads": args.threads}
    try:
        report = penumbra.bake(scene, progress=progress, **settings)
    except Exception as e:
        print(f"penumbra: bake failed: {e}", file=sys.stderr, flush=True)
        with open(os.path.join(out, "report.json"), "w") as f:
            json.dump({"error": str(e), "type": type(e).__name__}, f, indent=1)
        sys.exit(2)
    save = args.save or os.path.join(out, "baked.blend")
    if save.lower() != "none":
        bpy.ops.wm.save_as_mainfile(filepath=os.path.abspath(save), copy=True)
        report["outputs_blend"] = os.path.abspath(save)
    with open(os.path.join(out, "report.json"), "w") as f:
        json.dump(report, f, indent=1)
    for x in report["skipped"]:
        print(f"penumbra: skipped {x['name']}: {x['reason']}", file=sys.stderr)
    for w in report["warnings"]:
        print(f"penumbra: warning: {w}", file=sys.stderr)
    print(penumbra.summary(report), flush=True)


if __name__ == "__main__":
    main()

"""Headless bake of a .blend:

    blender -b scene.blend --python-exit-code 1 --python <addon>/penumbra/cli.py -- --out DIR [options]

<addon> is ~/.config/blender/3.4/scripts/addons when the add-on was installed from the zip, or build/addon in a
build. The settings saved in the file's Penumbra panel are used; every option below overrides one of them.
Progress goes to stderr, the report to DIR/report.json. Exit codes: 0 baked, 2 bad option or setting,
3 the scene cannot be baked (the message says why and names the object), 4 any other failure.
Run with `-- --help` for the options.
"""
import argparse
import json
import os
import sys
import time

try:
    from . import settings_table
except ImportError:
    # Run as a script (blender --python .../penumbra/cli.py): options are parsed before the add-on can be
    # imported, so the table of settings (plain data) is loaded from the file beside this one.
    import importlib.util
    _spec = importlib.util.spec_from_file_location(
        "_penumbra_cli_settings_table", os.path.join(os.path.dirname(os.path.abspath(__file__)),
                                                     "settings_table.py"))
    settings_table = importlib.util.module_from_spec(_spec)
    sys.modules[_spec.name] = settings_table      # dataclasses look their module up while building the class
    _spec.loader.exec_module(settings_table)

EXIT_OK, EXIT_USAGE, EXIT_SCENE, EXIT_FAILED = 0, 2, 3, 4
# penumbra.MAX_RESOLUTION, repeated because options are parsed before the add-on can be imported (tested equal).
MAX_RESOLUTION = 8192
QUALITY = ("draft", "medium", "high")
TARGETS = {"lightmap": {"LIGHTMAP"}, "color": {"COLOR_ATTRIBUTE"}, "both": {"LIGHTMAP", "COLOR_ATTRIBUTE"}}


def _ranged(kind, lo, hi):
    def parse(text):
        try:
            v = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected {'an integer' if kind is int else 'a number'}, got "
                                             f"{text!r}")
        if not (lo <= v <= hi) or v != v:
            raise argparse.ArgumentTypeError(f"must be between {lo} and {hi}, got {text}")
        return v
    return parse


def _solver_value(setting):
    """A solver setting's value: refused (exit 2) exactly when the solver would refuse it, with the solver's
    range from settings_table (which native/python/test_settings_table.py holds equal to the solver's)."""
    kind = setting.type

    def parse(text):
        try:
            v = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected {'an integer' if kind is int else 'a number'}, got "
                                             f"{text!r}")
        if not setting.contains(v):
            raise argparse.ArgumentTypeError(f"must be {setting.describe()}, got {text}")
        return v
    return parse


def _targets(text):
    t = text.strip().lower()
    if t in TARGETS:
        return TARGETS[t]
    parts = {p.strip().upper() for p in text.split(",") if p.strip()}
    if parts and parts <= {"LIGHTMAP", "COLOR_ATTRIBUTE"}:
        return parts          # the older spelling LIGHTMAP,COLOR_ATTRIBUTE
    raise argparse.ArgumentTypeError(f"must be lightmap, color or both, got {text!r}")


def parser():
    ap = argparse.ArgumentParser(
        prog="blender -b FILE.blend --python-exit-code 1 --python <addon>/penumbra/cli.py --",
        description="Bake the scene's diffuse global illumination with Penumbra. Unless an option says "
                    "otherwise, the settings saved in the file's Penumbra panel are used.",
        epilog="Exit codes: 0 baked; 2 bad option or setting; 3 the scene cannot be baked (no mesh, nothing "
               "emits light, missing UV map, bad geometry: the message names the object); 4 other failure.")
    ap.add_argument("--out", required=True, metavar="DIR",
                    help="output folder: report.json, the lightmaps as EXR and baked.blend")
    ap.add_argument("--quality", choices=QUALITY, type=str.lower,
                    help="solver preset: draft (fastest), medium, high (the panel's Quality); --epsilon and "
                         "--min-size override its thresholds")
    ap.add_argument("--targets", type=_targets, metavar="{lightmap,color,both}",
                    help="bake into lightmap images, color attributes or both")
    ap.add_argument("--resolution", type=_ranged(int, 8, MAX_RESOLUTION), metavar="N",
                    help=f"lightmap width and height in pixels, at most {MAX_RESOLUTION}")
    ap.add_argument("--margin", type=_ranged(int, 0, 64), metavar="N", help="pixels filled around UV islands")
    ap.add_argument("--patch-texels", dest="patch_texels", type=_ranged(float, 0, 64), metavar="X",
                    help="cut lightmapped surfaces no finer than X of their texels instead of --min-size of the "
                         "scene (0: off, the default)")
    ap.add_argument("--uv-map", metavar="NAME",
                    help="existing UV map for the lightmaps (default: create and unwrap 'PenumbraLightmap')")
    sel = ap.add_mutually_exclusive_group()
    sel.add_argument("--selection-only", dest="selection_only", action="store_const", const=True,
                     help="bake only the objects selected in the file (the others are left out of the solve)")
    sel.add_argument("--all", dest="selection_only", action="store_const", const=False,
                     help="bake every visible mesh object")
    ap.add_argument("--irradiance", action=argparse.BooleanOptionalAction, default=None,
                    help="bake the arriving light without the albedo (Cycles' Diffuse Direct + Indirect without "
                         "Color), for engines that multiply by their own albedo (the panel's Irradiance Only)")
    ap.add_argument("--instance-lightmaps", dest="instance_lightmaps", action=argparse.BooleanOptionalAction,
                    default=None, help="give every collection instance of an object a tile of its own in the "
                                       "object's lightmap (the panel's Instance Lightmaps)")
    # One flag per panel setting of the solver, from settings_table (--visibility-rays N, --no-clustering, ...).
    for s in settings_table.PANEL:
        if s.type is bool:
            ap.add_argument(s.flag, action=argparse.BooleanOptionalAction, default=None,
                            help=f"{s.help} (the panel's {s.label}; default: the file's setting, else "
                                 f"{'on' if s.default else 'off'})")
        else:
            ap.add_argument(s.flag, type=_solver_value(s), metavar=s.metavar or ("N" if s.type is int else "X"),
                            help=f"{s.help} (the panel's {s.label}; {s.describe()})")
    ap.add_argument("--save", metavar="FILE.blend",
                    help="save the baked .blend here (default: DIR/baked.blend; 'none' to skip)")
    ap.add_argument("--scene", help="scene name (default: the active scene)")
    return ap


def settings_from(panel, args):
    """The bake settings: the panel's (if the file has them), overridden by the options given."""
    s = dict(panel.as_settings()) if panel is not None else {}
    if args.quality:
        s.update(settings_table.PRESETS[args.quality.upper()])
    for key in ("resolution", "margin", "uv_map", "selection_only", "irradiance",
                "instance_lightmaps", "patch_texels") + settings_table.SOLVER_KEYS:
        v = getattr(args, key)
        if v is not None:
            s[key] = v
    if args.targets is not None:
        s["targets"] = args.targets
    return s


def main():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    args = parser().parse_args(argv)      # --help and bad options exit here (0 and 2), before Blender data

    import bpy
    here = os.path.dirname(os.path.abspath(__file__))
    if os.path.dirname(here) not in sys.path:
        sys.path.insert(0, os.path.dirname(here))
    import addon_utils
    mod = addon_utils.enable(os.path.basename(here), default_set=True)
    if mod is None:
        print("penumbra: error: the add-on could not be enabled (see the error above)", file=sys.stderr)
        sys.exit(EXIT_FAILED)
    import penumbra

    if args.scene and args.scene not in bpy.data.scenes:
        print(f"penumbra: error: no scene named '{args.scene}' in {bpy.data.filepath or 'the file'}; scenes: "
              f"{', '.join(s.name for s in bpy.data.scenes)}", file=sys.stderr)
        sys.exit(EXIT_USAGE)
    scene = bpy.data.scenes[args.scene] if args.scene else bpy.context.scene
    out = os.path.abspath(args.out)
    if os.path.exists(out) and not os.path.isdir(out):
        # There is no folder to hold report.json, so the message is all there is.
        print(f"penumbra: error: --out {args.out} is a file; it must name a folder", file=sys.stderr)
        sys.exit(EXIT_USAGE)
    try:
        os.makedirs(out, exist_ok=True)
    except OSError as e:
        print(f"penumbra: error: cannot create the --out folder {out}: {e}", file=sys.stderr)
        sys.exit(EXIT_USAGE)
    settings = settings_from(getattr(scene, "penumbra", None), args)
    settings["output_dir"] = out
    t0 = time.perf_counter()
    last = {"stage": None, "t": 0.0}

    def progress(stage, frac):
        now = time.perf_counter()
        if stage != last["stage"] or now - last["t"] > 1.0:
            print(f"penumbra: {stage} {100 * min(max(frac, 0.0), 1.0):5.1f} % ({now - t0:.1f} s)",
                  file=sys.stderr, flush=True)
            last.update(stage=stage, t=now)
        return True

    def fail(code, e):
        print(f"penumbra: error: {e}", file=sys.stderr, flush=True)
        with open(os.path.join(out, "report.json"), "w") as f:
            json.dump({"error": str(e), "type": type(e).__name__, "exit_code": code,
                       "settings": penumbra._jsonable(settings)}, f, indent=1)
        sys.exit(code)

    save = args.save or os.path.join(out, "baked.blend")
    if save.lower() != "none":
        save = os.path.abspath(save)
        folder = os.path.dirname(save)
        # Checked before the bake: finding out after a long solve, with the lightmaps already written,
        # would waste the solve and leave files behind for a run that failed.
        if os.path.isdir(save) or not os.path.isdir(folder) or not os.access(folder, os.W_OK) or \
                (os.path.exists(save) and not os.access(save, os.W_OK)):
            fail(EXIT_USAGE, ValueError(f"--save {args.save}: cannot write {save} (missing or read-only folder, "
                                        f"or a folder of that name)"))
    try:
        report = penumbra.bake(scene, progress=progress, **settings)
    except (TypeError, penumbra.BakeError, ValueError) as e:
        # Bad settings are caught by the options above; what reaches here is about the scene.
        fail(EXIT_SCENE, e)
    except Exception as e:
        fail(EXIT_FAILED, e)
    if save.lower() != "none":
        try:
            bpy.ops.wm.save_as_mainfile(filepath=save, copy=True)
        except Exception as e:
            fail(EXIT_FAILED, RuntimeError(f"baked, but the .blend could not be saved to {save}: {e}"))
        report["outputs_blend"] = save
    with open(os.path.join(out, "report.json"), "w") as f:
        json.dump(report, f, indent=1)
    for x in report["skipped"]:
        print(f"penumbra: skipped {x['name']}: {x['reason']}", file=sys.stderr)
    for w in report["warnings"]:
        print(f"penumbra: warning: {w}", file=sys.stderr)
    print(penumbra.summary(report), flush=True)


if __name__ == "__main__":
    main()

"""Each light type against Cycles (issue 13): run time against error on one scene per light.

    PENUMBRA_ADDON_DIR=$PWD/build/addon blender -b --factory-startup --python-exit-code 1 \
        --python bench/lights_vs_cycles.py -- [--lights point,spot,sun,world,sky,area] [--out docs] \
        [--ref-samples 512] [--cache bench/cache]

The scene (examples/scenes.py, `light_<kind>`) is the same for every light: a 4 m x 4 m floor, a back wall and
a 0.6 m box, lit by one POINT (10 cm radius), SPOT (70 degrees, blend 0.3, 10 cm radius), SUN (3 degrees), uniform
world, Sky Texture world (sun disc off) or AREA light, and nothing else, so the light type is the only
difference. Method, scoring and caching are bench/run_time_vs_error.py's (its functions are used as they are):
a two-half Cycles DIFFUSE bake reference (Direct + Indirect + Color, 32 bounces), Penumbra's default (hybrid)
bake at three settings, Cycles' bake at 4-256 samples, each scored per face and per texel with the reference's
own noise removed in quadrature. The reference's sample count is lower than run_time_vs_error's 1024 so that
the six references finish on a loaded 2-core machine; its noise is measured and stated.

Writes <out>/bench_lights.json and <out>/bench_lights.png (per-texel error against time, one panel per light)
and prints the markdown tables of docs/benchmark.md.
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
import run_time_vs_error as rte  # noqa: E402
from addon_env import enable_addon  # noqa: E402  (run_time_vs_error put examples/ on sys.path)

LIGHTS = ("point", "spot", "sun", "world", "sky", "area")
# (epsilon, min_size): coarse, the default, fine.
SETTINGS = [(0.002, 0.01), (0.0002, 0.01), (5e-5, 0.002)]


def parse_args():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    ap = argparse.ArgumentParser(prog="lights_vs_cycles.py")
    ap.add_argument("--lights", default=",".join(LIGHTS))
    ap.add_argument("--out", default=os.path.join(REPO, "docs"))
    ap.add_argument("--cache", default=os.path.join(HERE, "cache"))
    ap.add_argument("--ref-samples", type=int, default=512)
    ap.add_argument("--cycles-samples", default="4,16,64,256")
    ap.add_argument("--penumbra-timeout", type=float, default=60.0)
    ap.add_argument("--keep", action="store_true", help="keep the other lights' results from bench_lights.json")
    a = ap.parse_args(argv)
    # What rte.run_scene reads besides these.
    a.quick, a.methods, a.hybrid = False, "hybrid", "{}"
    return a


def plot(results, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    n = len(results)
    cols = min(n, 3)
    rows = (n + cols - 1) // cols
    fig, axes = plt.subplots(rows, cols, figsize=(4.2 * cols, 3.6 * rows), squeeze=False)
    for ax, r in zip(axes.ravel(), results):
        for metric, style, what in (("texel_corrected", "-", "per texel"), ("face_corrected", ":", "per face")):
            pen = [p for p in r["penumbra"] if "stopped" not in p and p[metric] > 0]
            cyc = [c for c in r["cycles"] if c[metric] > 0]
            ax.loglog([p["seconds"] for p in pen], [100 * p[metric] for p in pen], "o" + style,
                      color="tab:blue", label=f"Penumbra, {what}")
            ax.loglog([c["seconds"] for c in cyc], [100 * c[metric] for c in cyc], "s" + style,
                      color="tab:red", label=f"Cycles bake, {what}")
            if metric == "texel_corrected":
                for p in pen:
                    ax.annotate(f"ε {p['epsilon']:g}", (p["seconds"], 100 * p[metric]), fontsize=7,
                                color="tab:blue", textcoords="offset points", xytext=(4, 4))
                for c in cyc:
                    ax.annotate(f"{c['samples']}", (c["seconds"], 100 * c[metric]), fontsize=7,
                                color="tab:red", textcoords="offset points", xytext=(4, 4))
        ax.set_title(r["scene"].replace("light_", "") + " light", fontsize=10)
        ax.set_xlabel("time (s, 2 shared cores)", fontsize=8)
        ax.set_ylabel("relative RMS error (%)", fontsize=8)
        ax.grid(True, which="both", alpha=0.3)
        ax.tick_params(labelsize=7)
    for ax in axes.ravel()[n:]:
        ax.axis("off")
    axes.ravel()[0].legend(fontsize=6)
    fig.suptitle("Each light type: error against Cycles' converged bake (reference noise removed)", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def main():
    args = parse_args()
    penumbra = enable_addon("bench_lights")
    os.makedirs(args.out, exist_ok=True)
    saved = os.path.join(args.out, "bench_lights.json")
    names = [f"light_{k}" for k in args.lights.split(",")]
    results = []
    if args.keep and os.path.exists(saved):
        with open(saved) as f:
            results = [r for r in json.load(f)["results"] if r["scene"] not in names]
    t0 = time.perf_counter()
    for name in names:
        results.append(rte.run_scene(penumbra, name, args, penumbra_settings=SETTINGS))
        results.sort(key=lambda r: LIGHTS.index(r["scene"][len("light_"):]))
        with open(saved, "w") as f:
            json.dump({"blender": bpy.app.version_string, "results": results,
                       "seconds": time.perf_counter() - t0}, f, indent=1)
        plot(results, os.path.join(args.out, "bench_lights.png"))
    print(rte.tables(results))
    rte.log(f"light benchmark took {time.perf_counter() - t0:.0f} s")


main()

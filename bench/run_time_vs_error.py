"""Run time against error: Penumbra and Cycles' own DIFFUSE bake on the same scenes, the same lightmaps, the
same machine.

    PENUMBRA_ADDON_DIR=$PWD/build/addon blender -b --factory-startup --python-exit-code 1 \
        --python bench/run_time_vs_error.py -- [--scenes cornell,office,blockers] [--out docs] [--quick]

For each scene (examples/cornell_box.py, examples/scenes.py; "scalable20k" and the like size the scaling office):
1. every receiver gets a smart-project UV map "Lightmap" (the same for all bakes) and its own materials, so Cycles
   bakes all receivers in one call;
2. the reference is a Cycles DIFFUSE bake (Direct + Indirect + Color, 32 bounces, clamping and denoising off) with
   --ref-samples samples made of two seeded halves. It is cached in bench/cache/ (rebuilt when missing or when
   the UV maps, resolution or sample count differ). The half difference measures the reference's own noise;
3. Penumbra bakes at several quality settings (epsilon, min_size) and Cycles bakes at 4, 16, 64, 256 samples,
   each timed (Penumbra: the whole penumbra.bake call; Cycles: the bpy.ops.object.bake call) and scored by
   relative RMS error over per-face averages and over texels. The reference's noise is removed in quadrature
   (sqrt(err^2 - noise^2)); for Cycles the noise of the half-sample reference is the relevant one.
Writes <out>/bench_<scene>.png (error against time, log-log) and <out>/bench_results.json, and prints the
markdown tables that docs/benchmark.md holds, with the speed-up at equal error interpolated in log-log.
"""
import argparse
import json
import math
import os
import re
import sys
import time

import bpy
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from lightmap_uv import UV, unwrap, uv_array  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(HERE)
REFERENCES = os.path.join(HERE, "references")
sys.path.insert(0, os.path.join(REPO, "examples"))
import cornell_box  # noqa: E402
import scenes  # noqa: E402
from addon_env import enable_addon  # noqa: E402

BOUNCES = 32
# (epsilon, min_size): the default is the third; finer settings need a smaller min_size to take effect.
PENUMBRA_SETTINGS = [(0.002, 0.01), (0.0005, 0.01), (0.0002, 0.01), (0.0001, 0.005), (5e-5, 0.002)]
# Each setting runs twice: standard refinement only, and hybrid with convolution links (the default); "contact"
# is the hybrid with contact sub-blockers (furniture standing on the floor), "flat" the hybrid whose receivers must be
# flat (cluster_receivers off, the default before stop 33), each run only when asked (--methods).
METHODS = [("standard", {"convolution": False}), ("hybrid", {"convolution": True}),
           ("contact", {"convolution": True, "contact_slabs": True}),
           ("flat", {"convolution": True, "cluster_receivers": False})]
CYCLES_SAMPLES = [4, 16, 64, 256]
RESOLUTION = {"cornell": 128, "office": 128, "office5k": 128, "blockers": 128, "lattice": 128, "classroom": 128,
              "uplight": 128, "vault": 128,
              "scalable": 256}  # the scaling office: at 128² most of its furniture faces hold no texel centre
# "scalable20k" and the like: the scaling office at that many thousand polygons (5k is "scalable"), at its resolution.
SIZED_SCALABLE = re.compile(r"scalable(\d+)k")


def build_scene(name):
    m = SIZED_SCALABLE.fullmatch(name)
    return scenes.build("scalable", polygons=int(m.group(1)) * 1000) if m else scenes.build(name)


def resolution(name):
    return RESOLUTION["scalable"] if SIZED_SCALABLE.fullmatch(name) else RESOLUTION.get(name, 128)


def parse_args():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    ap = argparse.ArgumentParser(prog="run_time_vs_error.py")
    ap.add_argument("--scenes", default="cornell,office,blockers,lattice")
    ap.add_argument("--out", default=os.path.join(REPO, "docs"))
    ap.add_argument("--cache", default=os.path.join(HERE, "cache"))
    ap.add_argument("--ref-samples", type=int, default=1024)
    ap.add_argument("--cycles-samples", default=",".join(map(str, CYCLES_SAMPLES)))
    ap.add_argument("--penumbra-timeout", type=float, default=120.0,
                    help="cancel a Penumbra setting after this many seconds")
    ap.add_argument("--quick", action="store_true", help="64 reference samples, 2 settings each: a smoke run")
    ap.add_argument("--keep", action="store_true",
                    help="keep the other scenes' results from <out>/bench_results.json (re-run some scenes only)")
    ap.add_argument("--methods", default="standard,hybrid", help="Penumbra series to run: standard, hybrid")
    ap.add_argument("--hybrid", default="{}", help="JSON of extra solver settings for the hybrid and contact "
                                                  "series, e.g. '{\"e_max\": 4}'")
    ap.add_argument("--settings", default=None, help="Penumbra (epsilon:min_size) list replacing the default, "
                                                     "e.g. 0.002:0.01,0.0005:0.01")
    ap.add_argument("--clock", choices=("wall", "cpu"), default="wall",
                    help="what the tables and plots call time: wall seconds, or the process's CPU seconds "
                         "(both are kept in the JSON); cpu for a machine shared with other jobs")
    ap.add_argument("--json", default="bench_results.json", help="results file name inside --out")
    ap.add_argument("--save-maps", default=None, help="folder for every bake's lightmaps and the reference "
                                                     "(npz per bake), for side-by-side images")
    return ap.parse_args(argv)


def log(*a):
    print(*a, file=sys.stderr, flush=True)


def prepare(name):
    """Build the scene, unwrap the receivers, give each object its own materials; returns receiver names."""
    from penumbra.compare import _material_emits
    bpy.ops.wm.read_homefile(use_empty=True)
    obs = build_scene(name)
    receivers = [n for n, o in obs.items() if o.type == "MESH" and not _material_emits(o)]
    for n in receivers:
        ob = bpy.data.objects[n]
        for i, m in enumerate(ob.data.materials):
            if m is not None and m.users > 1:
                ob.data.materials[i] = m.copy()
    # Penumbra bakes every mesh (emitters too) into the named UV map, so every mesh needs one.
    for o in obs.values():
        if o.type == "MESH":
            unwrap(o)
    return receivers


class Scorer:
    """Errors of a set of lightmaps against the two-half reference, per texel and per face."""

    def __init__(self, receivers, ref_a, ref_b, res):
        from penumbra.compare import face_means, uv_owner
        self.face_means = face_means
        self.parts = []
        for n in receivers:
            me = bpy.data.objects[n].data
            owner = uv_owner(me, UV, res, res)
            ref = 0.5 * (ref_a[n] + ref_b[n])
            noise = 0.5 * (ref_a[n] - ref_b[n])
            fr, cnt = face_means(ref, owner, len(me.polygons))
            fn, _ = face_means(noise, owner, len(me.polygons))
            self.parts.append((n, owner, ref, noise, fr, fn, cnt > 0))
        mask_ref = np.concatenate([p[2][p[1] >= 0][:, :3].ravel() for p in self.parts])
        mask_noise = np.concatenate([p[3][p[1] >= 0][:, :3].ravel() for p in self.parts])
        face_ref = np.concatenate([p[4][p[6]].ravel() for p in self.parts])
        face_noise = np.concatenate([p[5][p[6]].ravel() for p in self.parts])
        self.ref2_texel = float((mask_ref ** 2).sum())
        self.ref2_face = float((face_ref ** 2).sum())
        self.noise_texel = math.sqrt(float((mask_noise ** 2).sum()) / self.ref2_texel)
        self.noise_face = math.sqrt(float((face_noise ** 2).sum()) / self.ref2_face)
        self.faces = int(sum(p[6].sum() for p in self.parts))
        self.texels = int(mask_ref.size // 3)

    def score(self, maps):
        d2t = d2f = bias = rsum = 0.0
        parts = {}
        for n, owner, ref, noise, fr, fn, keep in self.parts:
            m = owner >= 0
            d = maps[n][m][:, :3].astype(np.float64) - ref[m][:, :3]
            d2t += float((d ** 2).sum())
            bias += float(d.sum())
            rsum += float(ref[m][:, :3].sum())
            fp, _ = self.face_means(maps[n], owner, len(fr))
            df2 = float(((fp[keep] - fr[keep]) ** 2).sum())
            d2f += df2
            # Each receiver's own figures, relative to its own light: where the error and the bias sit.
            parts[n] = {"face": math.sqrt(df2 / max(float((fr[keep] ** 2).sum()), 1e-300)),
                        "bias": float(d.sum()) / max(float(ref[m][:, :3].sum()), 1e-300),
                        "share": df2}  # of the per-face error's square; made a fraction below
        for v in parts.values():
            v["share"] /= max(d2f, 1e-300)
        t = math.sqrt(d2t / self.ref2_texel)
        f = math.sqrt(d2f / self.ref2_face)
        return {"texel": t, "face": f, "bias": bias / rsum, "receivers": parts,
                "texel_corrected": math.sqrt(max(t * t - self.noise_texel ** 2, 0.0)),
                "face_corrected": math.sqrt(max(f * f - self.noise_face ** 2, 0.0))}


def reference(name, receivers, res, samples, cache_dir):
    from penumbra.compare import cycles_lightmaps
    os.makedirs(cache_dir, exist_ok=True)
    path = os.path.join(cache_dir, f"{name}_{res}_{samples}.npz")
    uvs = {n: uv_array(bpy.data.objects[n]) for n in receivers}
    # bench/references/ holds the converged references that take a quarter of an hour each to render (the scaling
    # offices at 4096 samples); a cached file of the same name comes first.
    for found in (path, os.path.join(REFERENCES, os.path.basename(path))):
        if not os.path.exists(found):
            continue
        z = np.load(found, allow_pickle=False)
        ok = all(f"uv_{n}" in z and np.array_equal(z[f"uv_{n}"], uvs[n]) for n in receivers)
        if ok:
            log(f"{name}: cached reference {found}")
            return ({n: z[f"a_{n}"] for n in receivers}, {n: z[f"b_{n}"] for n in receivers},
                    float(z["seconds"]))
        log(f"{name}: reference {found} does not match the UV maps")
    jobs = {n: (UV, res, res) for n in receivers}
    log(f"{name}: Cycles reference, {samples} samples as two seeded halves ...")
    a, ta = cycles_lightmaps(bpy.context.scene, jobs, samples // 2, seed=101, bounces=BOUNCES)
    b, tb = cycles_lightmaps(bpy.context.scene, jobs, samples // 2, seed=202, bounces=BOUNCES)
    arrays = {"seconds": np.float64(ta + tb)}
    for n in receivers:
        arrays[f"a_{n}"], arrays[f"b_{n}"], arrays[f"uv_{n}"] = a[n], b[n], uvs[n]
    np.savez_compressed(path, **arrays)
    log(f"{name}: reference took {ta + tb:.1f} s, cached in {path}")
    return a, b, ta + tb


def penumbra_maps(penumbra, receivers, report):
    out = {}
    for n in receivers:
        img = bpy.data.images[report["outputs"][n]["image"]]
        w, h = img.size
        px = np.empty(w * h * 4, np.float32)
        img.pixels.foreach_get(px)
        out[n] = px.reshape(h, w, 4)
    return out


def run_scene(penumbra, name, args, penumbra_settings=None):
    """Reference, Penumbra series and Cycles series of one scene; `penumbra_settings` replaces the
    (epsilon, min_size) list (bench/lights_vs_cycles.py runs fewer)."""
    from penumbra.compare import cycles_lightmaps
    res = resolution(name)
    receivers = prepare(name)
    ref_samples = 64 if args.quick else args.ref_samples
    a, b, ref_seconds = reference(name, receivers, res, ref_samples, args.cache)
    scorer = Scorer(receivers, a, b, res)
    log(f"{name}: {len(receivers)} receivers, {scorer.faces} faces, {scorer.texels} texels; reference noise "
        f"{100 * scorer.noise_face:.2f} % per face, {100 * scorer.noise_texel:.2f} % per texel")
    result = {"scene": name, "resolution": res, "receivers": receivers, "reference_samples": ref_samples,
              "reference_seconds": ref_seconds, "noise_face": scorer.noise_face, "noise_texel": scorer.noise_texel,
              "faces": scorer.faces, "texels": scorer.texels, "penumbra": [], "cycles": []}
    if getattr(args, "settings", None):
        penumbra_settings = [tuple(float(x) for x in st.split(":")) for st in args.settings.split(",")]
    settings = penumbra_settings or PENUMBRA_SETTINGS
    settings = settings[::2] if args.quick else settings
    cpu_clock = getattr(args, "clock", "wall") == "cpu"
    result["clock"] = "cpu" if cpu_clock else "wall"
    save_maps = getattr(args, "save_maps", None)
    if save_maps:
        os.makedirs(save_maps, exist_ok=True)
        np.savez_compressed(os.path.join(save_maps, f"{name}_reference.npz"),
                            **{n: 0.5 * (a[n] + b[n]) for n in receivers})
    scene = bpy.context.scene
    methods = [(m, {**extra, **(json.loads(args.hybrid) if m != "standard" else {})})
               for m, extra in METHODS if m in args.methods.split(",")]
    for (method, extra), (eps, min_size) in ((m, st) for m in methods for st in settings):
        deadline = time.perf_counter() + args.penumbra_timeout

        def progress(stage, frac):
            return time.perf_counter() < deadline
        try:
            cpu0 = time.process_time()
            rep = penumbra.bake(scene, progress=progress, resolution=res, uv_map=UV, targets={"LIGHTMAP"},
                                epsilon=eps, min_size=min_size, **extra)
            cpu = time.process_time() - cpu0
        except Exception as e:
            log(f"{name}: Penumbra {method} eps {eps} min_size {min_size}: stopped ({e})")
            result["penumbra"].append({"method": method, "epsilon": eps, "min_size": min_size, "stopped": str(e)})
            continue
        maps = penumbra_maps(penumbra, receivers, rep)
        s = scorer.score(maps)
        if save_maps:
            np.savez_compressed(os.path.join(save_maps, f"{name}_{method}_{eps:g}.npz"), **maps)
        row = {"method": method, "epsilon": eps, "min_size": min_size,
               "seconds": cpu if cpu_clock else rep["times"]["total"], "cpu_seconds": cpu,
               "wall_seconds": rep["times"]["total"],
               "solve_seconds": rep["times"]["solve"], "elements": rep.get("elements"), "links": rep.get("links"),
               "convolution_links": rep.get("convolution_links", 0), "iterations": rep.get("iterations"), **s}
        result["penumbra"].append(row)
        log(f"{name}: Penumbra {method} eps {eps:g} min_size {min_size:g}: {row['seconds']:.2f} s, "
            f"{row['convolution_links']} convolution links, face "
            f"{100 * s['face']:.2f} %, texel {100 * s['texel']:.2f} %, bias {100 * s['bias']:+.2f} %")
        log("    per receiver (face, bias, share): " + ", ".join(
            f"{n} {100 * v['face']:.2f} % {100 * v['bias']:+.2f} % ({100 * v['share']:.0f} % of the error)"
            for n, v in s["receivers"].items()))
    penumbra.clear(scene)
    jobs = {n: (UV, res, res) for n in receivers}
    samples_list = [int(x) for x in args.cycles_samples.split(",") if x]  # "" runs no Cycles bake
    for spp in (samples_list[:2] if args.quick else samples_list):
        cpu0 = time.process_time()
        maps, sec = cycles_lightmaps(scene, jobs, spp, seed=7 + spp, bounces=BOUNCES)
        cpu = time.process_time() - cpu0
        s = scorer.score(maps)
        if save_maps:
            np.savez_compressed(os.path.join(save_maps, f"{name}_cycles_{spp}.npz"), **maps)
        result["cycles"].append({"samples": spp, "seconds": cpu if cpu_clock else sec, "cpu_seconds": cpu,
                                 "wall_seconds": sec, **s})
        log(f"{name}: Cycles {spp} spp: {sec:.2f} s, face {100 * s['face']:.2f} %, texel {100 * s['texel']:.2f} %")
    return result


# ---------------------------------------------------------------------------------------------- analysis

def envelope(points):
    """(time, error) sorted by time with the error made non-increasing: a slower setting that is no better
    than a faster one is never the one to pick."""
    pts = sorted(points)
    out = []
    for t, e in pts:
        if e > 0 and (not out or e < out[-1][1]):
            out.append((t, e))
    return out


def time_at_error(points, err, extrapolate_slope=None):
    """Time to reach `err`, interpolating log error against log time; (time, how) with how in
    {'interpolated', 'extrapolated', None}."""
    pts = envelope(points)
    if not pts:
        return None, None
    for (t0, e0), (t1, e1) in zip(pts, pts[1:]):
        if e1 <= err <= e0:
            f = (math.log(err) - math.log(e0)) / (math.log(e1) - math.log(e0))
            return math.exp(math.log(t0) + f * (math.log(t1) - math.log(t0))), "interpolated"
    if err >= pts[0][1]:
        return pts[0][0], "at or below the fastest point"
    if extrapolate_slope is None:
        return None, None
    t_last, e_last = pts[-1]
    # Monte Carlo error falls as time^-1/2: extrapolate with the slope fitted to the measured points.
    return t_last * (err / e_last) ** (1.0 / extrapolate_slope), "extrapolated"


def cycles_slope(points):
    if len(points) < 2:
        return -0.5
    x = np.log([p[0] for p in points])
    y = np.log([p[1] for p in points])
    return float(np.polyfit(x, y, 1)[0])


def tables(results):
    lines = []
    for r in results:
        name = r["scene"]
        lines.append(f"### {name}\n")
        lines.append(f"{len(r['receivers'])} receivers, {r['faces']} faces, {r['texels']} texels at "
                     f"{r['resolution']}²; reference: Cycles DIFFUSE bake, {r['reference_samples']} samples "
                     f"({r['reference_seconds']:.0f} s), own noise {100 * r['noise_face']:.2f} % per face and "
                     f"{100 * r['noise_texel']:.2f} % per texel (removed in quadrature in the *corrected* columns).\n")
        clock = "CPU s" if r.get("clock") == "cpu" else "s"
        lines.append(f"| method | setting | time ({clock}) | per-face RMS | corrected | per-texel RMS | corrected | bias |")
        lines.append("|---|---|---|---|---|---|---|---|")
        for p in r["penumbra"]:
            if "stopped" in p:
                lines.append(f"| Penumbra {p.get('method', 'standard')} | ε {p['epsilon']:g}, min_size "
                             f"{p['min_size']:g} | stopped | | | | | |")
                continue
            conv = f", {p['convolution_links']} conv. links" if p.get("convolution_links") else ""
            lines.append(f"| Penumbra {p.get('method', 'standard')} | ε {p['epsilon']:g}, min_size {p['min_size']:g}{conv} | "
                         f"{p['seconds']:.2f} | "
                         f"{100 * p['face']:.2f} % | {100 * p['face_corrected']:.2f} % | {100 * p['texel']:.2f} % | "
                         f"{100 * p['texel_corrected']:.2f} % | {100 * p['bias']:+.2f} % |")
        for c in r["cycles"]:
            lines.append(f"| Cycles | {c['samples']} spp | {c['seconds']:.2f} | {100 * c['face']:.2f} % | "
                         f"{100 * c['face_corrected']:.2f} % | {100 * c['texel']:.2f} % | "
                         f"{100 * c['texel_corrected']:.2f} % | {100 * c['bias']:+.2f} % |")
        lines.append("")
        lines.append("Speed-up at equal error (corrected errors; times interpolated in log-log, Cycles beyond its "
                     "measured range extrapolated along its fitted slope):\n")
        lines.append("| metric | Penumbra setting | error | Penumbra time (s) | Cycles time at that error (s) | speed-up |")
        lines.append("|---|---|---|---|---|---|")
        for metric in ("face", "texel"):
            key = metric + "_corrected"
            cyc = [(c["seconds"], c[key]) for c in r["cycles"] if c[key] > 0]
            slope = cycles_slope(cyc)
            for p in r["penumbra"]:
                if "stopped" in p or p[key] <= 0:
                    continue
                tc, how = time_at_error(cyc, p[key], extrapolate_slope=slope)
                if tc is None:
                    continue
                mark = "*" if how == "extrapolated" else ""
                lines.append(f"| {metric} | {p.get('method', 'standard')} ε {p['epsilon']:g}, min_size {p['min_size']:g} | "
                             f"{100 * p[key]:.2f} % | "
                             f"{p['seconds']:.2f} | {tc:.1f}{mark} | {tc / p['seconds']:.2g}×{mark} |")
            c256 = next((c for c in r["cycles"] if c["samples"] == 256), None)
            if c256 is not None:
                pen = [(p["seconds"], p[key]) for p in r["penumbra"] if "stopped" not in p and p[key] > 0]
                tp, how = time_at_error(pen, c256[key])
                if tp is None:
                    best = min(pen, key=lambda x: x[1]) if pen else None
                    lines.append(f"| {metric} | Cycles 256 spp error {100 * c256[key]:.2f} % | not reached by "
                                 f"Penumbra (best {100 * best[1]:.2f} % in {best[0]:.2f} s) | | "
                                 f"{c256['seconds']:.1f} | – |")
                else:
                    lines.append(f"| {metric} | **at Cycles 256 spp's error** | {100 * c256[key]:.2f} % | {tp:.2f} | "
                                 f"{c256['seconds']:.1f} | **{c256['seconds'] / tp:.2g}×** |")
        lines.append("")
    return "\n".join(lines)


def plot(r, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, 2, figsize=(10, 4.2))
    for ax, metric, title in ((axes[0], "face_corrected", "per-face averages"),
                              (axes[1], "texel_corrected", "per texel")):
        cyc = [c for c in r["cycles"] if c[metric] > 0]
        for method, style, colour in (("standard", "o--", "tab:gray"), ("hybrid", "o-", "tab:blue"),
                                      ("contact", "o-", "tab:green"), ("flat", "o:", "tab:purple")):
            pen = [p for p in r["penumbra"] if "stopped" not in p and p[metric] > 0
                   and p.get("method", "standard") == method]
            if not pen:
                continue
            ax.loglog([p["seconds"] for p in pen], [100 * p[metric] for p in pen], style, color=colour,
                      label=f"Penumbra {method}" + {"hybrid": " (convolution links)",
                                                    "contact": " (+ contact sub-blockers)",
                                                    "flat": " (flat receivers only)"}.get(method, ""))
            for p in pen:
                ax.annotate(f"ε {p['epsilon']:g}", (p["seconds"], 100 * p[metric]), fontsize=7, color=colour,
                            textcoords="offset points", xytext=(4, 4))
        ax.loglog([c["seconds"] for c in cyc], [100 * c[metric] for c in cyc], "s-", color="tab:red",
                  label="Cycles DIFFUSE bake")
        for c in cyc:
            ax.annotate(f"{c['samples']} spp", (c["seconds"], 100 * c[metric]), fontsize=7,
                        textcoords="offset points", xytext=(4, 4))
        ax.set_xlabel("CPU s (2 shared cores)" if r.get("clock") == "cpu" else "time (s, 2 cores)")
        ax.set_ylabel("relative RMS error (%), reference noise removed")
        ax.set_title(f"{r['scene']}: {title}")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main():
    args = parse_args()
    penumbra = enable_addon("bench")
    os.makedirs(args.out, exist_ok=True)
    names = args.scenes.split(",")
    results = []
    saved = os.path.join(args.out, args.json)
    if args.keep and os.path.exists(saved):
        with open(saved) as f:
            results = [r for r in json.load(f)["results"] if r["scene"] not in names]
    t0 = time.perf_counter()
    for name in names:
        r = run_scene(penumbra, name, args)
        results.append(r)
        plot(r, os.path.join(args.out, f"bench_{name}.png"))
        with open(saved, "w") as f:
            json.dump({"blender": bpy.app.version_string, "results": results,
                       "seconds": time.perf_counter() - t0}, f, indent=1)
    print(tables(results))
    log(f"benchmark took {time.perf_counter() - t0:.0f} s")


# Under `blender --python` this file is __main__; bench/lights_vs_cycles.py imports it for its functions.
if __name__ == "__main__":
    main()

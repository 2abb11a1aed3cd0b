"""Validation of Penumbra against converged Cycles DIFFUSE bakes on the validation corpus
(examples/validation_scenes.py), per object and per scene.

    PENUMBRA_ADDON_DIR=$PWD/build/addon blender -b --factory-startup --python-exit-code 1 \
        --python bench/validate.py -- [--scenes lamp_gap_5mm,stacked_rooms] [--resolution 64] [--samples 2048] \
        [--block 4] [--cache /tmp/penumbra_refs] [--json out.json] [--markdown table.md] [--images DIR] \
        [--epsilon E] [--min-size S] [--settings '{"convolution": false}']

For each scene:
1. build it, give every mesh a smart-project UV map "Lightmap" (the same for the reference and the bake);
2. the reference is Cycles' DIFFUSE bake (Direct + Indirect + Color, 32 bounces, clamping and denoising off) into
   those UV maps (penumbra.compare.cycles_lightmaps), made of two seeded halves of --samples/2 each. Their half
   difference has the variance of the noise of their mean, so it measures the reference's own noise. References
   are cached in --cache as <scene>_<resolution>_<samples>.npz and rebuilt when the UV maps differ;
3. Penumbra bakes with its default settings at the same resolution and UV map (plus --epsilon, --min-size and
   --settings), timed by the report's total;
4. scored over the texels whose centres lie in a face of the receiver (emitters are not receivers):
   relative RMS per texel, and per b x b block of texels (--block, default 4) wholly inside the islands, where
   the reference noise is b times lower; mean bias; the reference's noise at both scales; the block RMS with the
   noise removed in quadrature. An object the reference leaves dark (mean under 1e-4 of the scene's mean, e.g.
   the sealed upper room) gets no relative figures; its Penumbra mean as a fraction of the scene's reference
   mean is reported instead ("leak"). If the bake's report has an `error_estimate` (a number, or a dict per
   object), it is reported beside the measured error.
Prints a markdown table (also to --markdown PATH); --json writes every figure, including each object's reflected
power (pi * sum over faces of area x mean texel) for the reference, its noise and Penumbra; --images DIR writes
<DIR>/<scene>.png: the scene camera rendered from the lightmaps (Penumbra's preview, then the same preview with the
Cycles reference lightmaps put in the images) -- Cycles reference | Penumbra | relative difference (blue: Penumbra
darker, red: brighter, full colour at +-50 %). The reference image is rendered from the reference lightmaps at the
bake's resolution, so it shows the reference's per-texel noise too.
"""
import argparse
import json
import math
import os
import sys
import tempfile
import time

import bpy
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from lightmap_uv import UV, unwrap, uv_array  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(HERE)
sys.path.insert(0, os.path.join(REPO, "examples"))
import validation_scenes  # noqa: E402
from addon_env import enable_addon  # noqa: E402

BOUNCES = 32
DARK = 1e-4


def parse_args():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    ap = argparse.ArgumentParser(prog="validate.py")
    ap.add_argument("--scenes", default=",".join(validation_scenes.SCENES))
    ap.add_argument("--resolution", type=int, default=64)
    ap.add_argument("--samples", type=int, default=2048, help="reference samples per texel (two seeded halves)")
    ap.add_argument("--block", type=int, default=4, help="block size b for the b x b block-averaged RMS")
    ap.add_argument("--cache", default="/tmp/penumbra_refs")
    ap.add_argument("--json", default=None, help="write every figure to this JSON file")
    ap.add_argument("--markdown", default=None, help="write the table to this file too (Cycles prints to stdout)")
    ap.add_argument("--images", default=None)
    ap.add_argument("--epsilon", type=float, default=None)
    ap.add_argument("--min-size", type=float, default=None)
    ap.add_argument("--settings", default="{}", help="JSON of extra penumbra.bake settings")
    return ap.parse_args(argv)


def log(*a):
    print(*a, file=sys.stderr, flush=True)


def prepare(name):
    """Build the scene and unwrap every mesh; returns the receivers (meshes that do not emit)."""
    from penumbra.compare import _material_emits
    bpy.ops.wm.read_homefile(use_empty=True)
    obs = validation_scenes.build(name)
    for o in obs.values():
        if o.type == "MESH":
            unwrap(o)
    return [n for n, o in obs.items() if o.type == "MESH" and not _material_emits(o)]


def reference(name, receivers, res, samples, cache_dir):
    """({name: half A}, {name: half B}, seconds), from the cache when its UV maps match."""
    from penumbra.compare import cycles_lightmaps
    os.makedirs(cache_dir, exist_ok=True)
    path = os.path.join(cache_dir, f"{name}_{res}_{samples}.npz")
    uvs = {n: uv_array(bpy.data.objects[n]) for n in receivers}
    if os.path.exists(path):
        z = np.load(path, allow_pickle=False)
        if all(f"uv_{n}" in z and np.array_equal(z[f"uv_{n}"], uvs[n]) for n in receivers):
            log(f"{name}: cached reference {path}")
            return ({n: z[f"a_{n}"] for n in receivers}, {n: z[f"b_{n}"] for n in receivers},
                    float(z["seconds"]), True)
        log(f"{name}: cached reference does not match the UV maps; rebuilding")
    jobs = {n: (UV, res, res) for n in receivers}
    log(f"{name}: Cycles reference, {samples} samples as two seeded halves ...")
    a, ta = cycles_lightmaps(bpy.context.scene, jobs, samples // 2, seed=101, bounces=BOUNCES)
    b, tb = cycles_lightmaps(bpy.context.scene, jobs, samples // 2, seed=202, bounces=BOUNCES)
    arrays = {"seconds": np.float64(ta + tb)}
    for n in receivers:
        arrays[f"a_{n}"], arrays[f"b_{n}"], arrays[f"uv_{n}"] = a[n], b[n], uvs[n]
    np.savez_compressed(path, **arrays)
    log(f"{name}: reference took {ta + tb:.1f} s, cached in {path}")
    return a, b, ta + tb, False


def image_array(img):
    w, h = img.size
    px = np.empty(w * h * 4, np.float32)
    img.pixels.foreach_get(px)
    return px.reshape(h, w, 4)


def blocks(x, owner, b):
    """b x b block means of x (H, W, C) over blocks whose texels all lie in the islands; (N, C)."""
    h, w = owner.shape
    hb, wb = h // b, w // b
    inside = (owner[:hb * b, :wb * b] >= 0).reshape(hb, b, wb, b).all(axis=(1, 3))
    xb = x[:hb * b, :wb * b, :3].astype(np.float64).reshape(hb, b, wb, b, 3).mean(axis=(1, 3))
    return xb[inside]


def figures(pen, ref, noise):
    """error_figures over (N, 3) arrays, or None when there is nothing lit to compare."""
    from penumbra.compare import error_figures
    if len(ref) == 0 or (ref ** 2).sum() <= 0:
        return None
    return error_figures(pen, ref, np.ones(len(ref), bool), noise)


def estimate_for(report, name):
    est = report.get("error_estimate")
    if est is None:
        est = report.get("solver", {}).get("error_estimate")
    if isinstance(est, dict):
        v = est.get(name, est.get("objects", {}).get(name) if isinstance(est.get("objects"), dict) else None)
        return v
    return None


def overall_estimate(report):
    est = report.get("error_estimate")
    if est is None:
        est = report.get("solver", {}).get("error_estimate")
    if isinstance(est, (int, float)):
        return float(est)
    if isinstance(est, dict):
        for k in ("overall", "total", "relative_rms", "scene"):
            if isinstance(est.get(k), (int, float)):
                return float(est[k])
    return None


def reflected_power(ob, owner, pixels):
    """pi * sum over faces of (face area x mean texel radiance): the power (W per colour unit) the object
    reflects, from the faces that own texels (RGB)."""
    from penumbra.compare import face_means
    me = ob.data
    area = np.empty(len(me.polygons), np.float64)
    me.polygons.foreach_get("area", area)
    means, count = face_means(pixels, owner, len(area))
    keep = count > 0
    return math.pi * (means[keep] * area[keep, None]).sum(axis=0), float(area[keep].sum() / area.sum())


def score(receivers, pen_maps, a, b, res, block, report):
    from penumbra.compare import LUMA, uv_owner
    parts, powers = {}, {}
    for n in receivers:
        ob = bpy.data.objects[n]
        owner = uv_owner(ob.data, UV, res, res)
        ref = 0.5 * (a[n][..., :3].astype(np.float64) + b[n][..., :3])
        noise = 0.5 * (a[n][..., :3].astype(np.float64) - b[n][..., :3])
        pen = pen_maps[n][..., :3].astype(np.float64)
        m = owner >= 0
        parts[n] = {"texel": (pen[m], ref[m], noise[m]),
                    "block": (blocks(pen, owner, block), blocks(ref, owner, block), blocks(noise, owner, block))}
        pr, covered = reflected_power(ob, owner, ref)
        pp, _ = reflected_power(ob, owner, pen)
        pn, _ = reflected_power(ob, owner, noise)
        powers[n] = {"reference": pr.tolist(), "penumbra": pp.tolist(), "reference_noise": pn.tolist(),
                     "area_covered": covered,
                     "ratio": float(pp @ LUMA / (pr @ LUMA)) if pr @ LUMA > 0 else None}
    scene_mean = float(np.concatenate([p["texel"][1] for p in parts.values()]).mean())
    objects = {}
    for n, p in parts.items():
        pen, ref, noise = p["texel"]
        o = {"texels": int(len(ref)), "blocks": int(len(p["block"][1])),
             "reference_mean": float(ref.mean()), "penumbra_mean": float(pen.mean()),
             "relative_level": float(ref.mean() / scene_mean), "error_estimate": estimate_for(report, n),
             "power": powers[n]}
        if ref.mean() <= DARK * scene_mean:
            o["dark"] = True
            o["leak"] = float(pen.mean() / scene_mean)
            o["leak_max"] = float(pen.max() / scene_mean)
        else:
            o["dark"] = False
            o["texel"] = figures(pen, ref, noise)
            o["block"] = figures(*p["block"])
        objects[n] = o

    def pooled(key):
        return figures(*(np.concatenate([parts[n][key][i] for n in parts]) for i in range(3)))
    return {"scene_reference_mean": scene_mean, "texel": pooled("texel"), "block": pooled("block"),
            "objects": objects, "error_estimate": overall_estimate(report)}


def camera_images(penumbra, scene, receivers, report, a, b, path):
    """Cycles reference | Penumbra | relative difference, rendered from the lightmaps through the preview."""
    from penumbra import compare
    tmp = tempfile.mkdtemp(prefix="penumbra_validate_")
    r = scene.render
    r.resolution_x, r.resolution_y, r.resolution_percentage = 320, 240, 100
    compare._path_tracing(scene, 16, 4, 0)
    imgs = {n: bpy.data.images[report["outputs"][n]["image"]] for n in receivers}
    saved = {n: image_array(img).copy() for n, img in imgs.items()}
    penumbra.preview(scene, True)
    try:
        pen, _, _ = compare._render(scene, os.path.join(tmp, "p.exr"))
        for n, img in imgs.items():
            ref = 0.5 * (a[n] + b[n])
            ref[..., 3] = 1.0
            img.pixels.foreach_set(np.ascontiguousarray(ref, np.float32).ravel())
            img.update()
        ref, _, _ = compare._render(scene, os.path.join(tmp, "r.exr"))
    finally:
        for n, img in imgs.items():
            img.pixels.foreach_set(saved[n].ravel())
            img.update()
        penumbra.preview(scene, False)
    ref, pen = ref[..., :3].astype(np.float64), pen[..., :3].astype(np.float64)
    lum_r, lum_p = ref @ compare.LUMA, pen @ compare.LUMA
    white = float(np.percentile(lum_r, 97))
    if white <= 1e-6 * max(float(lum_p.max()), 1e-30):
        # A room the reference leaves black (the sealed upper room): scale by the bake, so a leak shows.
        white = max(float(np.percentile(lum_p, 99.9)), 1e-30)
    floor = 0.01 * max(float(lum_r.mean()), 1e-30)
    heat = compare.false_colour((lum_p - lum_r) / np.maximum(lum_r, floor), 0.5)
    gap = np.ones((ref.shape[0], 4, 3))
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    compare._write_png(path, np.concatenate([compare._tonemap(ref, white), gap, compare._tonemap(pen, white),
                                             gap, heat], axis=1))


def run_scene(penumbra, name, args):
    res = args.resolution
    receivers = prepare(name)
    polygons = sum(len(o.data.polygons) for o in bpy.context.scene.objects if o.type == "MESH")
    a, b, ref_seconds, cached = reference(name, receivers, res, args.samples, args.cache)
    scene = bpy.context.scene
    extra = dict(json.loads(args.settings))
    if args.epsilon is not None:
        extra["epsilon"] = args.epsilon
    if args.min_size is not None:
        extra["min_size"] = args.min_size
    rep = penumbra.bake(scene, resolution=res, uv_map=UV, targets={"LIGHTMAP"}, **extra)
    maps = {n: image_array(bpy.data.images[rep["outputs"][n]["image"]]) for n in receivers}
    s = score(receivers, maps, a, b, res, args.block, rep)
    result = {"scene": name, "polygons": polygons, "resolution": res, "reference_samples": args.samples,
              "reference_seconds": ref_seconds, "reference_cached": cached, "block_size": args.block,
              "penumbra_seconds": rep["times"]["total"], "solve_seconds": rep["times"].get("solve"),
              "elements": rep.get("elements"), "links": rep.get("links"),
              "convolution_links": rep.get("convolution_links"), "settings": extra,
              "warnings": rep.get("warnings", []), **s}
    t, bl = s["texel"], s["block"]
    log(f"{name}: {polygons} polygons; Penumbra {result['penumbra_seconds']:.2f} s; texel RMS "
        f"{100 * t['relative_rms']:.2f} % (noise {100 * t['noise_relative_rms']:.2f} %), {args.block}x{args.block} "
        f"RMS {100 * bl['relative_rms']:.2f} % (noise {100 * bl['noise_relative_rms']:.2f} %), bias "
        f"{100 * t['mean_bias']:+.2f} %")
    if args.images:
        t0 = time.perf_counter()
        camera_images(penumbra, scene, receivers, rep, a, b, os.path.join(args.images, f"{name}.png"))
        log(f"{name}: images in {time.perf_counter() - t0:.1f} s")
    penumbra.clear(scene)
    return result


def pct(x, signed=False):
    if x is None:
        return "–"
    return f"{100 * x:+.1f} %" if signed else f"{100 * x:.1f} %"


def table(results):
    b = results[0]["block_size"] if results else 2
    lines = [f"| scene | object | texels | Penumbra (s) | RMS per texel | RMS {b}x{b} | noise texel / {b}x{b} | "
             f"RMS {b}x{b} − noise | bias | estimate |",
             "|---|---|---|---|---|---|---|---|---|---|"]

    def est(v):
        return "–" if v is None else (pct(v) if isinstance(v, (int, float)) else str(v))
    for r in results:
        t, bl = r["texel"], r["block"]
        lines.append(f"| **{r['scene']}** | all | {t['samples']} | {r['penumbra_seconds']:.2f} | "
                     f"**{pct(t['relative_rms'])}** | **{pct(bl['relative_rms'])}** | "
                     f"{pct(t['noise_relative_rms'])} / {pct(bl['noise_relative_rms'])} | "
                     f"{pct(bl['relative_rms_corrected'])} | **{pct(t['mean_bias'], True)}** | "
                     f"{est(r['error_estimate'])} |")
        for n, o in r["objects"].items():
            if o["dark"]:
                lines.append(f"| | {n} | {o['texels']} | | dark in Cycles: Penumbra mean {pct(o['leak'])}, max "
                             f"{pct(o['leak_max'])} of the scene's mean | | | | | {est(o['error_estimate'])} |")
                continue
            ot, ob = o["texel"], o["block"]
            lines.append(f"| | {n} | {o['texels']} | | {pct(ot['relative_rms'])} | "
                         f"{pct(ob['relative_rms']) if ob else '–'} | {pct(ot['noise_relative_rms'])} / "
                         f"{pct(ob['noise_relative_rms']) if ob else '–'} | "
                         f"{pct(ob['relative_rms_corrected']) if ob else '–'} | {pct(ot['mean_bias'], True)} | "
                         f"{est(o['error_estimate'])} |")
    return "\n".join(lines)


def build_info():
    path = os.path.join(os.path.dirname(__import__("penumbra").__file__), "_build_info.json")
    try:
        with open(path) as f:
            return json.load(f)
    except (OSError, ValueError):
        return None


def main():
    args = parse_args()
    penumbra = enable_addon("validate")
    info = build_info()
    try:
        import subprocess
        commit = subprocess.run(["git", "-C", REPO, "rev-parse", "HEAD"], capture_output=True, text=True,
                                timeout=10).stdout.strip() or None
    except (OSError, subprocess.SubprocessError):
        commit = None
    names = [n for n in args.scenes.split(",") if n]
    t0 = time.perf_counter()
    results = []
    for name in names:
        results.append(run_scene(penumbra, name, args))
        if args.json:
            os.makedirs(os.path.dirname(os.path.abspath(args.json)), exist_ok=True)
            with open(args.json, "w") as f:
                json.dump({"blender": bpy.app.version_string, "samples": args.samples,
                           "resolution": args.resolution, "block_size": args.block, "build": info, "commit": commit,
                           "results": results, "seconds": time.perf_counter() - t0}, f, indent=1)
    md = table(results)
    print(md)
    if args.markdown:
        with open(args.markdown, "w") as f:
            f.write(md + "\n")
    log(f"validate: {len(names)} scene(s) in {time.perf_counter() - t0:.0f} s")


main()

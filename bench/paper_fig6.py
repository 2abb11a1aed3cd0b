"""The paper's Fig. 6 (Soler & Sillion 1998): convolution links against standard hierarchical radiosity with
clustering at equal run time, from the lightmaps bench/run_time_vs_error.py saved (--save-maps) and its JSON.

    PENUMBRA_ADDON_DIR=$PWD/build/addon blender -b --factory-startup --python-exit-code 1 \\
        --python bench/run_time_vs_error.py -- --scenes scalable --methods standard,contact \\
        --settings 0.002:0.01,0.001:0.01 --hybrid '{"t_max": 1.0}' --clock cpu --json paper_fig6.json \\
        --ref-samples 512 --cycles-samples 4,16 --save-maps /tmp/maps
    (and --methods standard --settings 0.0005:0.01,0.0002:0.01 --json paper_fig6_standard.json, same maps folder)
    /usr/bin/python3 bench/paper_fig6.py --json docs/paper_fig6.json,docs/paper_fig6_standard.json \\
        --maps /tmp/maps --scene scalable [--object Floor] [--png docs/paper_fig6.png] [--epsilon 0.001]

Prints, per bake, the CPU seconds and the relative RMS error per texel against the converged Cycles reference
over all receivers (run_time_vs_error's scoring, reference noise removed) and over one object's lightmap
(`--object`: its UV islands less their outer edge; the reference's noise, from the two halves cached by
run_time_vs_error in --cache, removed in quadrature), then the standard series interpolated in log-log at the
convolution bake's CPU time (equal run time) and at its error (equal error). The PNG puts that object's lightmaps
side by side: the Cycles reference, the convolution bake of --epsilon, the standard bake closest in CPU time, and
both bakes' differences.
"""
import argparse
import json
import math
import os

import numpy as np


def load(maps, scene, tag):
    z = np.load(os.path.join(maps, f"{scene}_{tag}.npz"))
    return {k: z[k] for k in z.files}


def inside(ref, border=2):
    """The islands' texels: those the reference lights, with the holes filled (the floor under a drawer unit is
    black in the reference, and its edge is where contact shadows are judged), less `border` texels along the
    islands' outer edges, where the bakes' margins (dilation) differ, which is not the light's error."""
    from scipy.ndimage import binary_erosion, binary_fill_holes
    m = binary_fill_holes(ref[..., :3].sum(axis=-1) > 0)
    return binary_erosion(m, iterations=border)


def rms(got, ref, noise=None):
    """Relative RMS over inside(ref); with the reference's half difference `noise`, its own noise removed in
    quadrature, as run_time_vs_error's Scorer does."""
    m = inside(ref)
    d = got[m][:, :3].astype(np.float64) - ref[m][:, :3]
    r2 = float((ref[m][:, :3].astype(np.float64) ** 2).sum())
    e2 = float((d ** 2).sum()) / r2
    if noise is not None:
        e2 -= float((noise[m][:, :3].astype(np.float64) ** 2).sum()) / r2
    return math.sqrt(max(e2, 0.0))


def interpolate(points, t):
    """Error at time t on the log-log polyline through (time, error), or None outside the measured times:
    two settings of nearly equal time (a coarser epsilon is not always faster) make any extrapolation wild."""
    pts = sorted(points)
    for (t0, e0), (t1, e1) in zip(pts, pts[1:]):
        if t0 <= t <= t1 and t1 > t0:
            f = (math.log(t) - math.log(t0)) / (math.log(t1) - math.log(t0))
            return math.exp(math.log(e0) + f * (math.log(e1) - math.log(e0)))
    return None


def main():
    ap = argparse.ArgumentParser(prog="paper_fig6.py")
    ap.add_argument("--json", required=True, help="results files, comma-separated: the Penumbra runs of all "
                                                  "are merged, and the Cycles runs of sample counts the first lacks")
    ap.add_argument("--maps", required=True)
    ap.add_argument("--scene", default="scalable")
    ap.add_argument("--object", default="Floor")
    ap.add_argument("--method", default="contact", help="the convolution series to compare with standard")
    ap.add_argument("--png", default=None)
    ap.add_argument("--epsilon", type=float, default=None, help="the convolution bake the PNG shows (default: "
                                                                 "the first)")
    ap.add_argument("--cache", default=os.path.join(os.path.dirname(os.path.abspath(__file__)), "cache"),
                    help="run_time_vs_error's reference cache, whose two halves give the reference's noise")
    a = ap.parse_args()
    r = None
    for path in a.json.split(","):
        with open(path) as f:
            x = next(x for x in json.load(f)["results"] if x["scene"] == a.scene)
        if r is None:
            r = x
        else:
            r["penumbra"] += x["penumbra"]
            r["cycles"] = sorted(r["cycles"] + [c for c in x["cycles"] if c["samples"] not in
                                                {d["samples"] for d in r["cycles"]}], key=lambda c: c["samples"])
    ref = load(a.maps, a.scene, "reference")
    halves = os.path.join(a.cache, f"{a.scene}_{r['resolution']}_{r['reference_samples']}.npz")
    noise = None
    if os.path.exists(halves):
        z = np.load(halves)
        noise = 0.5 * (z[f"a_{a.object}"].astype(np.float64) - z[f"b_{a.object}"])
        print(f"{a.object}: reference noise {100 * rms(ref[a.object] + noise, ref[a.object]):.2f} % per texel, "
              "removed in quadrature")
    rows = []
    for p in r["penumbra"]:
        if "stopped" in p:
            continue
        maps = load(a.maps, a.scene, f"{p['method']}_{p['epsilon']:g}")
        rows.append({**p, "label": f"{p['method']} ε {p['epsilon']:g}", "object": rms(maps[a.object], ref[a.object], noise),
                     "maps": maps})
    for c in r["cycles"]:
        maps = load(a.maps, a.scene, f"cycles_{c['samples']}")
        rows.append({**c, "method": "cycles", "label": f"Cycles {c['samples']} spp",
                     "object": rms(maps[a.object], ref[a.object], noise), "maps": maps})
    print(f"{a.scene}: per texel against Cycles {r['reference_samples']} spp; CPU s of the bake call")
    print(f"| bake | conv. links | CPU s | all receivers, per texel (noise removed) | per face | bias | "
          f"{a.object}, per texel (noise removed) |")
    print("|---|---|---|---|---|---|---|")
    for x in rows:
        print(f"| {x['label']} | {x.get('convolution_links', '')} | {x['cpu_seconds']:.1f} | "
              f"{100 * x['texel_corrected']:.2f} % | {100 * x['face_corrected']:.2f} % | {100 * x['bias']:+.2f} % | "
              f"{100 * x['object']:.2f} % |")
    std = [x for x in rows if x["method"] == "standard"]
    print("\nAt equal CPU time (standard's error interpolated in log-log at the convolution bake's time):\n")
    print(f"| convolution bake | CPU s | error (all, per texel) | standard at that time | standard's CPU s at that "
          f"error | {a.object}: convolution | {a.object}: standard at that time |")
    print("|---|---|---|---|---|---|---|")
    for x in (x for x in rows if x["method"] == a.method):
        e_all = interpolate([(s["cpu_seconds"], s["texel_corrected"]) for s in std], x["cpu_seconds"])
        e_obj = interpolate([(s["cpu_seconds"], s["object"]) for s in std], x["cpu_seconds"])
        # The same polyline read the other way: standard's time to reach this bake's error (equal error).
        t_eq = interpolate([(s["texel_corrected"], s["cpu_seconds"]) for s in std], x["texel_corrected"])
        out = "outside the standard runs"
        pct = (lambda v: out if v is None else "%.2f %%" % (100 * v))  # noqa: E731
        eq = out if t_eq is None else "%.1f (%.2g×)" % (t_eq, t_eq / x["cpu_seconds"])
        print(f"| {x['label']} | {x['cpu_seconds']:.1f} | {100 * x['texel_corrected']:.2f} % | {pct(e_all)} | "
              f"{eq} | {100 * x['object']:.2f} % | {pct(e_obj)} |")
    if a.png:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        conv = [x for x in rows if x["method"] == a.method]
        if not conv or not std:
            return
        c = next((x for x in conv if a.epsilon is not None and math.isclose(x["epsilon"], a.epsilon)), conv[0])
        s = min(std, key=lambda x: abs(math.log(x["cpu_seconds"] / c["cpu_seconds"])))
        R = ref[a.object][..., :3]
        scale = np.percentile(R[R.sum(-1) > 0], 99)

        def show(img):
            return np.clip(img[..., :3] / scale, 0, 1) ** (1 / 2.2)
        fig, axes = plt.subplots(1, 5, figsize=(19, 4.4))
        panels = [(show(R), f"Cycles reference, {r['reference_samples']} spp"),
                  (show(c["maps"][a.object]), f"{c['label']}, {c.get('convolution_links', 0)} conv. links\n"
                                              f"{c['cpu_seconds']:.0f} CPU s, {100 * c['object']:.1f} % RMS"),
                  (show(s["maps"][a.object]), f"{s['label']}\n{s['cpu_seconds']:.0f} CPU s, "
                                              f"{100 * s['object']:.1f} % RMS")]
        for ax, (img, title) in zip(axes, panels):
            ax.imshow(img, origin="lower")
            ax.set_title(title, fontsize=9)
        for ax, x in zip(axes[3:], (c, s)):
            d = np.where(inside(ref[a.object]), (x["maps"][a.object][..., :3].mean(-1) - R.mean(-1)) / scale,
                         np.nan)
            im = ax.imshow(d, origin="lower", cmap="RdBu_r", vmin=-0.15, vmax=0.15)
            ax.set_title(f"{x['label']} − reference\n(fraction of the 99th percentile)", fontsize=9)
        fig.colorbar(im, ax=axes[4], fraction=0.046)
        for ax in axes:
            ax.set_xticks([])
            ax.set_yticks([])
        fig.suptitle(f"{a.scene}: the {a.object}'s lightmap (same UV map for every bake)", fontsize=10)
        fig.tight_layout()
        fig.savefig(a.png, dpi=90)
        plt.close(fig)


if __name__ == "__main__":
    main()

"""The paper's Fig. 5 (Soler & Sillion 1998) on the ~5k-polygon office with four area lights: how much of the
direct light convolution links carry, and what the solve costs, as E_max and a_min vary (t_max = 1 s, as in
the paper).

    /usr/bin/python3 bench/paper_fig5.py [--polygons 5000] [--layout office] [--e-max 4.04,2.02,1,0.18]
        [--a-min 0.802,0.108,0.04] [--settings '{"epsilon": 0.002}'] [--json docs/paper_fig5.json]
        [--plot docs/paper_fig5.png]

Scene: examples/scalable_scene.py (desks, chairs and monitors standing on the floor, four rectangular area
lights under the ceiling). Every run has `contact_slabs` on (without it nothing in this room is a valid
convolution site: every blocker stands on its receiver) and `t_max` = 1 s; one more run has convolution off.

The share of direct light carried by textures: for every (receiving polygon, lamp) pair, the lamp's unoccluded
irradiance at the polygon's centroid (Lambert's exact form factor of the lamp clipped to the polygon's front
half-space) times the polygon's area is the direct flux the pair stands for; a pair is "by texture" when a
convolution link from that lamp covers that polygon. The share is the flux of those pairs over all pairs', per
object. Unoccluded, because it weighs how much of the direct-light transfer the refiner handed to textures,
not how much light got through. "textures, wall s" is the solver's own clock for the textures (report times),
wall time on a shared machine: read it as a share of the run, not as CPU time.

Time: CPU seconds of the solve call (time.process_time, one solver thread), so other jobs on the machine do
not count; the solver's own stage times are kept in the JSON.
"""
import argparse
import json
import math
import os
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(HERE)
sys.path.insert(0, os.path.join(os.environ.get("PENUMBRA_ADDON_DIR", os.path.join(REPO, "build", "addon")),
                                "penumbra"))
sys.path.insert(0, os.path.join(REPO, "examples"))
sys.path.insert(0, os.path.join(REPO, "native", "python"))
import _native  # noqa: E402
import scalable_scene  # noqa: E402
from test_solver import lambert_irradiance_factor  # noqa: E402

RECEIVERS = ("Floor", "Walls", "Desks", "Chairs", "Monitors")


def clip_to_front(poly, p, n):
    """The part of `poly` strictly in front of the plane through p with normal n (Sutherland-Hodgman)."""
    d = (poly - p) @ n
    out = []
    for i in range(len(poly)):
        a, b, da, db = poly[i], poly[(i + 1) % len(poly)], d[i], d[(i + 1) % len(poly)]
        if da > 0:
            out.append(a)
        if (da > 0) != (db > 0) and da != db:
            out.append(a + (b - a) * (da / (da - db)))
    return np.array(out) if len(out) >= 3 else None


def direct_flux(scene):
    """(polygons, lamps) array of unoccluded direct flux per unit exitance, and the lamp polygon indices."""
    v = scene["vertices"].astype(np.float64)
    polys, flags = scene["polygons"], scene["flags"]
    lamps = np.flatnonzero(flags & _native.LIGHT_ONLY)
    flux = np.zeros((len(polys), len(lamps)))
    for i, q in enumerate(polys):
        if flags[i] & _native.LIGHT_ONLY:
            continue
        pv = v[q[q >= 0]]
        c = pv.mean(axis=0)
        nrm = np.cross(pv[1] - pv[0], pv[2] - pv[0])
        area = 0.5 * np.linalg.norm(sum(np.cross(pv[k], pv[(k + 1) % len(pv)]) for k in range(len(pv))))
        nrm /= np.linalg.norm(nrm)
        for j, L in enumerate(lamps):
            lv = v[polys[L][polys[L] >= 0]]
            ln = np.cross(lv[1] - lv[0], lv[2] - lv[0])
            if (c - lv.mean(axis=0)) @ ln <= 0:
                continue          # behind the lamp, which emits from its front only
            part = clip_to_front(lv, c, nrm)
            if part is not None:
                flux[i, j] = lambert_irradiance_factor(c, nrm, part) * area
    return flux, lamps


def texture_share(scene, flux, lamps, links):
    covered = np.zeros_like(flux, bool)
    col = {int(L): j for j, L in enumerate(lamps)}
    for link in links:
        for s in link["source_polygons"]:
            if int(s) in col:
                covered[link["receiver_polygons"], col[int(s)]] = True
    obj = scene["object_index"]
    out = {}
    floor_walls = np.isin(obj, [scene["object_names"].index(n) for n in ("Floor", "Walls")])
    for name in RECEIVERS + ("Floor+Walls", "all"):
        rows = (obj >= 0 if name == "all" else floor_walls if name == "Floor+Walls"
                else obj == scene["object_names"].index(name))
        total = flux[rows].sum()
        if total > 0:
            out[name] = float(flux[rows][covered[rows]].sum() / total)
    return out, covered


def run(scene, settings):
    t = time.process_time()
    sol = _native.solve(**scene, settings=dict(settings, threads=1))
    cpu = time.process_time() - t
    rep = sol.report
    links = sol.convolution_links
    return sol, cpu, rep, links


def coverage(scene, row, lamps):
    """(polygons, lamps) bool: which lamp reaches which polygon through a texture, from a row's link list."""
    cov = np.zeros((len(scene["polygons"]), len(lamps)), bool)
    col = {int(L): j for j, L in enumerate(lamps)}
    for link in row["link_list"]:
        for src in link["sources"]:
            if src in col:
                cov[link["receivers"], col[src]] = True
    return cov


def plot(rows, scene, lamps, path, views, view_rows=None):
    """Top: the share of direct flux by texture (floor, desks, all) and the solve's CPU time against E_max, one
    colour per a_min. Bottom: plan views of the upward-facing receivers (floor, desk and chair tops) for the
    (E_max, a_min) pairs in `views`, shaded by how many lamps reach each polygon through a texture, taken from
    `view_rows` (default `rows`): runs whose link lists name their receivers."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import PolyCollection
    conv = [r for r in rows if r["convolution"]]
    a_mins = sorted({r["a_min"] for r in conv}, reverse=True)
    fig = plt.figure(figsize=(14, 8))
    grid = fig.add_gridspec(2, len(views) or 1, height_ratios=[1, 1.1])
    ax1 = fig.add_subplot(grid[0, :len(views) // 2 or 1])
    ax2 = fig.add_subplot(grid[0, len(views) // 2 or 1:])
    for k, a in enumerate(a_mins):
        rs = sorted((r for r in conv if r["a_min"] == a), key=lambda r: r["e_max"])
        e = [r["e_max"] for r in rs]
        for key, style in (("Floor", "o-"), ("Desks", "s--"), ("all", "^:")):
            ax1.semilogx(e, [100 * r["share"].get(key, 0) for r in rs], style, color=f"C{k}",
                         label=f"{key.lower()}, a_min {a:g}")
        ax2.semilogx(e, [r["cpu_seconds"] for r in rs], "o-", color=f"C{k}", label=f"a_min {a:g}")
    off = next((r for r in rows if not r["convolution"]), None)
    if off:
        ax2.axhline(off["cpu_seconds"], color="gray", ls=":", label="convolution off")
    ax1.set(xlabel="E_max", ylabel="direct flux by texture (%)",
            title="share of the direct flux carried by convolution links (walls: 0 in every run)")
    ax2.set(xlabel="E_max", ylabel="solve CPU s (1 thread)", title="run time (t_max = 1 s)")
    for ax in (ax1, ax2):
        ax.legend(fontsize=7, ncol=2 if ax is ax1 else 1)
        ax.grid(True, which="both", alpha=0.3)
    v, polys, obj = scene["vertices"], scene["polygons"], scene["object_index"]
    corners = v[polys].astype(np.float64)
    up = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])[:, 2] > 0
    floor = obj == scene["object_names"].index("Floor")
    shown = np.flatnonzero(up & ~(scene["flags"] & _native.LIGHT_ONLY).astype(bool))
    shown = shown[np.argsort(~floor[shown], kind="stable")]      # the floor first, the tops drawn over it
    pc = None
    for k, (e_max, a_min) in enumerate(views):
        row = next((r for r in (view_rows or rows) if r["convolution"] and math.isclose(r["e_max"], e_max)
                    and math.isclose(r["a_min"], a_min)
                    and all("receivers" in link for link in r["link_list"])), None)
        if row is None:
            continue
        ax = fig.add_subplot(grid[1, k])
        cov = coverage(scene, row, lamps)
        # Furniture outlined: a desk top lit through textures by all four lamps is the floor's colour.
        pc = PolyCollection([corners[i][:, :2] for i in shown], array=cov[shown].sum(axis=1), cmap="viridis",
                            clim=(0, len(lamps)), edgecolors=[(0, 0, 0, 0) if floor[i] else (1, 1, 1, 1) for i in shown],
                            linewidths=0.4)
        ax.add_collection(pc)
        ax.autoscale()
        ax.set_aspect("equal")
        ax.set_xticks([])
        ax.set_yticks([])
        ax.set_title(f"E_max {e_max:g}, a_min {a_min:g}: {row['convolution_links']} links, "
                     f"{row['cpu_seconds']:.0f} CPU s", fontsize=8)
    if pc is not None:
        fig.colorbar(pc, ax=fig.axes[2:], fraction=0.02, label="lamps reaching it by texture")
    fig.suptitle("Fig. 5 on the 5k office: floor and upward-facing furniture seen from above", fontsize=10)
    fig.savefig(path, dpi=90)
    plt.close(fig)


def main():
    ap = argparse.ArgumentParser(prog="paper_fig5.py")
    ap.add_argument("--polygons", type=int, default=5000)
    ap.add_argument("--layout", default="office")
    ap.add_argument("--e-max", default="4.04,2.02,1,0.18")
    ap.add_argument("--a-min", default="0.802,0.108,0.04")
    ap.add_argument("--settings", default='{"epsilon": 0.002}', help="JSON, the same for every run")
    ap.add_argument("--json", default=os.path.join(REPO, "docs", "paper_fig5.json"))
    ap.add_argument("--plot", default=os.path.join(REPO, "docs", "paper_fig5.png"))
    ap.add_argument("--views", default="4.04:0.802,4.04:0.04,1:0.04,0.18:0.802",
                    help="E_max:a_min pairs whose plan views the plot shows (runs whose links list receivers)")
    ap.add_argument("--replot", default=None, help="only plot: the curves from --json's rows, the plan views "
                                                   "from this JSON's (a run with receiver lists)")
    a = ap.parse_args()
    scene = scalable_scene.make_scene(a.polygons, layout=a.layout)
    views = [tuple(float(x) for x in v.split(":")) for v in a.views.split(",") if v]
    if a.replot:
        with open(a.json) as f:
            rows = json.load(f)["rows"]
        with open(a.replot) as f:
            view_rows = json.load(f)["rows"]
        lamps = np.flatnonzero(scene["flags"] & _native.LIGHT_ONLY)
        plot(rows, scene, lamps, a.plot, views, view_rows)
        return
    flux, lamps = direct_flux(scene)
    base = json.loads(a.settings)
    runs = [dict(convolution=False)]
    runs += [dict(convolution=True, contact_slabs=True, t_max=1.0, e_max=float(e), a_min=float(m))
             for m in a.a_min.split(",") for e in a.e_max.split(",")]
    print(f"{a.layout}, {len(scene['polygons'])} polygons, settings {base}; CPU s of the solve, one thread")
    print("| E_max | a_min | conv. links (tried) | refused | floor direct by texture | walls | desks | all "
          "| links | rays | solve CPU s | textures, wall s |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    rows = []
    for extra in runs:
        sol, cpu, rep, links = run(scene, dict(base, **extra))
        share, _ = texture_share(scene, flux, lamps, links)
        refused = {k: v for k, v in rep["convolution_refused"].items() if v}
        row = {**extra, "e_max": extra.get("e_max"), "a_min": extra.get("a_min"), "cpu_seconds": cpu,
               "share": share, "convolution_links": rep["convolution_links"],
               "convolution_tried": rep["convolution_tried"], "refused": refused, "links": rep["links"],
               "elements": rep["elements"], "rays": rep["rays"], "times": rep["times"],
               "texels": rep["convolution_texels"],
               "link_list": [{"receiver_polygons": len(l["receiver_polygons"]),
                              "receivers": [int(p) for p in l["receiver_polygons"]],
                              "receiver_objects": sorted({scene["object_names"][o] for o in
                                                          np.unique(scene["object_index"][l["receiver_polygons"]])}),
                              "sources": [int(s) for s in l["source_polygons"]], "resolution": l["resolution"],
                              "sub_blockers": l["sub_blockers"], "error": l["error"]} for l in links]}
        rows.append(row)
        del sol
        pct = lambda k: f"{100 * share.get(k, 0):.0f} %"  # noqa: E731
        em = "off" if not extra["convolution"] else f"{extra['e_max']:g}"
        am = "" if not extra["convolution"] else f"{extra['a_min']:g}"
        print(f"| {em} | {am} | {rep['convolution_links']} ({rep['convolution_tried']}) | "
              f"{', '.join(f'{k} {v}' for k, v in refused.items()) or '–'} | {pct('Floor')} | {pct('Walls')} | "
              f"{pct('Desks')} | {pct('all')} | {rep['links'] / 1e6:.2f}M | {rep['rays'] / 1e6:.1f}M | {cpu:.1f} | "
              f"{rep['times'].get('convolution_textures', 0):.1f} |", flush=True)
        if a.json:
            with open(a.json, "w") as f:
                json.dump({"scene": {"layout": a.layout, "polygons": int(len(scene["polygons"]))},
                           "settings": base, "clock": "process_time of the solve, threads=1",
                           "rows": rows}, f, indent=1)
    if a.plot:
        plot(rows, scene, lamps, a.plot, views)


if __name__ == "__main__":
    main()

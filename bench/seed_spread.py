"""Penumbra's own sampling noise: the same scene and settings solved with several `seed`s.

    /usr/bin/python3 bench/seed_spread.py [--sizes 5000,20000] [--seeds 4] [--settings '{"epsilon": 0.005}']
        [--build build/addon] [--json FILE] [--plot FILE]

Every ray estimate of a solve (a link's visibility, a face's share of a cluster link, the lamps' points) is seeded
by the identities of its elements, so a bake is deterministic; the `seed` setting draws them all anew. Two seeds'
answers differ by the sampling noise alone, which no comparison against a reference separates from the method's
own error. This measures it on the scalable office (examples/scalable_scene.py, no Blender): the radiance at
every face's centre for each seed, and per object the noise of one bake, the relative RMS of the seeds' answers
about their mean (sample standard deviation, summed over faces, over the RMS of the mean), with its run time.

A benchmark, not a test. Outputs: a markdown table on stdout, --json, and --plot (noise per object, one group of
bars per size). The comparison against Cycles takes the seed the same way:
`bench/run_time_vs_error.py --hybrid '{"seed": 1}'` (docs/scaling.md, stop 46).
"""
import argparse
import datetime
import json
import os
import subprocess
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(HERE)
sys.path.insert(0, os.path.join(REPO, "examples"))
sys.path.insert(0, HERE)
from scaling import import_native, parse_sizes  # noqa: E402  (the module from --build, as bench/scaling.py finds it)


def parse_args(argv=None):
    ap = argparse.ArgumentParser(prog="seed_spread.py", description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", default="5000,20000", help="target polygon counts, comma-separated (k suffix allowed)")
    ap.add_argument("--seeds", type=int, default=4, help="seeds 0 .. N-1 per size (at least 2)")
    ap.add_argument("--settings", default='{"epsilon": 0.005}', help="JSON dict of solver settings")
    ap.add_argument("--build", default=os.path.join(REPO, "build", "addon"),
                    help="folder holding penumbra/_native*.so (or the .so itself's folder)")
    ap.add_argument("--json", default="", help="write the results here")
    ap.add_argument("--plot", default="", help="write the figure here (PNG)")
    args = ap.parse_args(argv)
    args.sizes = parse_sizes(args.sizes)
    args.settings = json.loads(args.settings)
    if args.seeds < 2:
        ap.error("--seeds: at least 2 (the spread of one bake is not measurable)")
    if "seed" in args.settings:
        ap.error("--settings: leave out 'seed'; --seeds chooses them")
    return args


def face_points(scene):
    """Each face's centre, lifted off it by 0.1 mm, and its normal."""
    v = np.asarray(scene["vertices"], np.float64)
    corners = v[np.asarray(scene["polygons"])]
    centre = corners.mean(axis=1)
    normal = np.cross(corners[:, 2] - corners[:, 0], corners[:, 3] - corners[:, 1])
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    return np.ascontiguousarray(centre + 1e-4 * normal, np.float32), np.ascontiguousarray(normal, np.float32)


def spread(radiance, objects, names):
    """Per receiving object and over all: the relative RMS noise of one bake (sample standard deviation over the
    seeds at each face, root mean square over the faces, over the root mean square of the seeds' mean)."""
    r = np.asarray(radiance, np.float64)            # seeds x faces x 3
    mean = r.mean(axis=0)
    var = r.var(axis=0, ddof=1)
    out = {}
    for name, mask in [(n, objects == i) for i, n in enumerate(names)] + [("all", np.ones_like(objects, bool))]:
        ref2 = float((mean[mask] ** 2).sum())
        if ref2 <= 0:
            continue
        out[name] = float(np.sqrt(var[mask].sum() / ref2))
    return out


def run(args):
    import scalable_scene
    _native = import_native(args.build)
    rows = []
    for n in args.sizes:
        scene = scalable_scene.make_scene(n)
        emits = np.asarray(scene["emission"]).max(axis=1) > 0
        names = list(scene["object_names"])
        objects = np.asarray(scene["object_index"])
        keep = ~emits
        pts, nrm = face_points(scene)
        answers, walls = [], []
        for seed in range(args.seeds):
            t = time.perf_counter()
            sol = _native.solve(**scene, settings={**args.settings, "seed": seed})
            walls.append(time.perf_counter() - t)
            answers.append(np.asarray(sol.radiance(pts[keep], nrm[keep]))[:, :3])
            print(f"seed_spread: {n} polygons, seed {seed}: {walls[-1]:.1f} s, {sol.report['links']} links",
                  file=sys.stderr, flush=True)
        noise = spread(answers, objects[keep], names)
        rows.append({"polygons": len(scene["polygons"]), "seeds": args.seeds, "wall_s": walls, "noise": noise})
    return rows


def table(rows):
    names = [k for k in rows[0]["noise"] if k != "all"] + ["all"]
    lines = ["| polygons | wall s (mean) | " + " | ".join(names) + " |", "|---|---|" + "---|" * len(names)]
    for r in rows:
        cells = [f"{100 * r['noise'][k]:.2f} %" if k in r["noise"] else "" for k in names]
        lines.append(f"| {r['polygons']} | {np.mean(r['wall_s']):.1f} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def plot(rows, path, settings):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    names = [k for k in rows[0]["noise"] if k != "all"] + ["all"]
    fig, ax = plt.subplots(figsize=(8, 4))
    width = 0.8 / len(rows)
    for i, r in enumerate(rows):
        x = np.arange(len(names)) + (i - (len(rows) - 1) / 2) * width
        ax.bar(x, [100 * r["noise"].get(k, 0) for k in names], width, label=f"{r['polygons']} polygons")
    ax.set_xticks(np.arange(len(names)), names)
    ax.set_ylabel("noise of one bake, % (RMS over faces)")
    ax.set_title(f"Penumbra's sampling noise over {rows[0]['seeds']} seeds, {json.dumps(settings)}")
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main(argv=None):
    args = parse_args(argv)
    rows = run(args)
    print(table(rows))
    if args.json:
        commit = subprocess.run(["git", "-C", REPO, "rev-parse", "--short", "HEAD"], capture_output=True,
                                text=True).stdout.strip()
        with open(args.json, "w") as f:
            json.dump({"settings": args.settings, "commit": commit, "date": datetime.date.today().isoformat(),
                       "rows": rows}, f, indent=1)
    if args.plot:
        plot(rows, args.plot, args.settings)


if __name__ == "__main__":
    main()

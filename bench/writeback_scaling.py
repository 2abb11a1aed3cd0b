"""Write-back time against object count: N small cubes, each its own mesh, under one area light.

    blender -b --factory-startup --python bench/writeback_scaling.py -- \
        [--sizes 100,200,500,1000] [--resolution 32] [--build build/addon] [--label TEXT]
        [--json docs/writeback_results.json] [--plot docs/bench_writeback.png] [--profile N]

Every size is baked in a fresh empty file (begin, solve, finish, targets LIGHTMAP and COLOR_ATTRIBUTE) and the
report's times['write_back'] is the figure: everything after the solve that puts the bake into the .blend
(UV unwrap, rasterising, images, colour attributes) up to the commit. `finish_s` is the wall time of the whole
finish() with the commit, `finish_cpu_s` the CPU time of all the process's threads meanwhile (a steadier figure
than wall time on a shared machine), `finish_main_cpu_s` that of the main thread alone (Blender's side of the
write-back, which the lightmaps' worker thread runs beside), `other_load` the 1-minute load average less this
process. `first_read_s` is the CPU time of reading every lightmap's pixels once after the bake: Blender decodes
a packed lightmap when something first needs its pixels (a material drawn, Image.pixels), as after opening
the .blend. The solver is
set coarse (epsilon 0.01) so that the solve does not dominate the run; it has no effect on the write-back's
work, which depends on the objects and texels only.

--profile N bakes N objects under cProfile once more and prints the most expensive calls, by cumulative and
by own time. --rebake bakes every size a second time over the first (every image and attribute replaced at
the commit) and reports that write-back too. Sizes already in --json under the same --label are replaced;
other labels are kept, so a "before" and an "after" run end up side by side in one plot.
"""
import argparse
import json
import os
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(HERE)
sys.path.insert(0, os.path.join(REPO, "examples"))
from addon_env import enable_addon  # noqa: E402
TARGET_OBJECTS, TARGET_SECONDS = 1000, 1.0
RESOLUTION = [32]


def parse_args():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    ap = argparse.ArgumentParser(prog="writeback_scaling.py", description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", default="100,200,500,1000")
    ap.add_argument("--resolution", type=int, default=32)
    ap.add_argument("--build", default=os.path.join(REPO, "build", "addon"))
    ap.add_argument("--label", default="")
    ap.add_argument("--json", default=os.path.join(REPO, "docs", "writeback_results.json"))
    ap.add_argument("--plot", default=os.path.join(REPO, "docs", "bench_writeback.png"))
    ap.add_argument("--profile", type=int, default=0)
    ap.add_argument("--rebake", action="store_true", help="bake each size twice; the second replaces the first")
    args = ap.parse_args(argv)
    args.sizes = sorted({int(s) for s in args.sizes.split(",") if s.strip()})
    return args


def build_scene(n):
    """n cubes of 0.5 m on a square grid 1 m apart, on no floor, and one area light above the middle. Built
    through bpy.data (no operators), so that building costs little beside the bake."""
    import bpy
    bpy.ops.wm.read_homefile(use_empty=True)   # read_factory_settings would unregister the add-on
    scene = bpy.context.scene
    h = 0.25
    verts = [(x, y, z) for x in (-h, h) for y in (-h, h) for z in (-h, h)]
    faces = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    side = int(n ** 0.5 + 0.999)
    for i in range(n):
        me = bpy.data.meshes.new(f"Cube{i:04d}")
        me.from_pydata(verts, [], faces)
        ob = bpy.data.objects.new(f"Cube{i:04d}", me)
        ob.location = (i % side - side / 2, i // side - side / 2, 0.0)
        scene.collection.objects.link(ob)
    light = bpy.data.lights.new("Light", "AREA")
    light.size = side
    light.energy = 100.0 * n
    lob = bpy.data.objects.new("Light", light)
    lob.location = (0, 0, 3)
    scene.collection.objects.link(lob)
    return scene


def bake(penumbra, scene):
    """The report, and the wall, CPU (all threads of the process) and main-thread CPU seconds of the whole
    finish(): the write-back with its commit, which report['times']['write_back'] stops short of."""
    job = penumbra.begin(scene, resolution=RESOLUTION[0], margin=2, epsilon=0.01,
                         targets={"LIGHTMAP", "COLOR_ATTRIBUTE"})
    job.solve()
    t, c, m = time.perf_counter(), time.process_time(), time.thread_time()
    rep = job.finish()
    return rep, time.perf_counter() - t, time.process_time() - c, time.thread_time() - m


def first_read(rep):
    """CPU seconds of reading every lightmap's pixels once."""
    import bpy
    import numpy as np
    c = time.process_time()
    for out in rep["outputs"].values():
        img = bpy.data.images[out["image"]]
        px = np.empty(len(img.pixels), np.float32)
        img.pixels.foreach_get(px)
    return time.process_time() - c


def other_load():
    """The 1-minute load average less this process (about 1 while it runs alone): other work on the machine."""
    try:
        return max(0.0, os.getloadavg()[0] - 1.0)
    except OSError:
        return None


def run(penumbra, n, resolution, rebake):
    RESOLUTION[0] = resolution
    scene = build_scene(n)
    rep, wall, cpu, main_cpu = bake(penumbra, scene)
    baked = len(rep["objects_baked"])
    if baked != n:
        raise SystemExit(f"writeback_scaling: {baked} of {n} objects baked ({rep['skipped'][:3]})")
    t = rep["times"]
    row = {"objects": n, "write_back_s": t["write_back"], "solve_s": t["solve"], "export_s": t["export"],
           "per_object_ms": 1000.0 * t["write_back"] / n, "resolution": resolution, "finish_s": wall,
           "finish_cpu_s": cpu, "finish_main_cpu_s": main_cpu, "other_load": other_load(),
           "first_read_s": first_read(rep)}
    if rebake:
        # A second bake replaces every image and attribute the first made: the commit's swap path.
        rep, wall, cpu, main_cpu = bake(penumbra, scene)
        row["rebake_write_back_s"] = rep["times"]["write_back"]
        row["rebake_finish_s"] = wall
    return row


def plot(rows_by_label, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    for label, rows in rows_by_label.items():
        rows = sorted(rows, key=lambda r: r["objects"])
        ax.plot([r["objects"] for r in rows], [r["write_back_s"] for r in rows], "o-", label=label or "run")
    ax.plot([TARGET_OBJECTS], [TARGET_SECONDS], "r*", markersize=12, label="target: 1000 objects in 1 s")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("objects (cubes, one mesh each)")
    ax.set_ylabel("write-back seconds")
    ax.set_title("Penumbra write-back against object count")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main():
    args = parse_args()
    penumbra = enable_addon("writeback_scaling", args.build)
    rows = []
    for n in args.sizes:
        r = run(penumbra, n, args.resolution, args.rebake)
        rows.append(r)
        print(f"{n:6d} objects: write-back {r['write_back_s']:8.3f} s  ({r['per_object_ms']:6.2f} ms/object)  "
              f"finish {r['finish_s']:.3f} s ({r['finish_cpu_s']:.3f} CPU s, "
              f"main thread {r['finish_main_cpu_s']:.3f})  "
              f"first read {r['first_read_s']:.3f} CPU s  solve {r['solve_s']:.2f} s  "
              f"other load {r['other_load']:.1f}"
              + (f"  re-bake write-back {r['rebake_write_back_s']:.3f} s" if "rebake_write_back_s" in r else ""),
              flush=True)
    print("\n| objects | write-back s | ms per object | finish s (with the commit) | finish CPU s | "
          "main thread CPU s | re-bake write-back s | other load |\n|---:|---:|---:|---:|---:|---:|---:|---:|")
    for r in rows:
        again = f"{r['rebake_write_back_s']:.3f}" if "rebake_write_back_s" in r else "-"
        print(f"| {r['objects']} | {r['write_back_s']:.3f} | {r['per_object_ms']:.2f} | {r['finish_s']:.3f} | "
              f"{r['finish_cpu_s']:.3f} | {r['finish_main_cpu_s']:.3f} | {again} | {r['other_load']:.1f} |")
    if args.profile:
        import cProfile
        import pstats
        prof = cProfile.Profile()
        scene = build_scene(args.profile)
        prof.enable()
        penumbra.bake(scene, resolution=args.resolution, margin=2, epsilon=0.01,
                      targets={"LIGHTMAP", "COLOR_ATTRIBUTE"})
        prof.disable()
        pstats.Stats(prof).sort_stats("cumulative").print_stats(30)
        pstats.Stats(prof).sort_stats("tottime").print_stats(40)
    if args.json and rows:
        data = {}
        if os.path.exists(args.json):
            with open(args.json) as f:
                data = json.load(f)
        old = {r["objects"]: r for r in data.get(args.label, [])}
        old.update({r["objects"]: r for r in rows})
        data[args.label] = [old[k] for k in sorted(old)]
        with open(args.json, "w") as f:
            json.dump(data, f, indent=1)
        if args.plot:
            plot(data, args.plot)


if __name__ == "__main__":
    try:
        main()
    except SystemExit as e:
        if e.code not in (None, 0):
            print(e.code, file=sys.stderr)
            sys.exit(1)

"""Run time against error of several runs of bench/run_time_vs_error.py drawn over each other, one panel per scene
and metric, so that two builds or two settings can be compared at equal error rather than at equal epsilon.

    /usr/bin/python3 bench/frontiers.py --run "far_field 0.2=docs/far_field_02_bench.json" \
        --run "far_field 0.3=docs/far_field_03_bench.json" [--scenes office5k,office] [--out docs/plot.png]

Each --run is LABEL=PATH of a bench_results.json. Only the Penumbra series are drawn (Cycles' are the same in
every run of one machine); each point is annotated with its epsilon. The time axis is the run's own clock
(`clock` in the JSON: CPU or wall seconds). A markdown table of the points is printed.
"""
import argparse
import json
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.ticker import FuncFormatter  # noqa: E402

METRICS = (("face", "per face"), ("texel", "per texel"))


def load(spec):
    label, sep, path = spec.partition("=")
    if not sep or not label or not path:
        raise SystemExit(f"frontiers: --run wants LABEL=PATH, got {spec!r}")
    try:
        with open(path) as f:
            data = json.load(f)
        return label, {r["scene"]: r for r in data["results"]}
    except (OSError, ValueError, KeyError, TypeError) as e:
        raise SystemExit(f"frontiers: {path} is not a bench/run_time_vs_error.py result: {e}")


def seconds(point, clock):
    return point["cpu_seconds"] if clock == "cpu" else point.get("wall_seconds", point["seconds"])


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--run", action="append", required=True, help="LABEL=bench_results.json (repeat)")
    ap.add_argument("--scenes", default=None, help="comma-separated; default: the scenes every run has")
    ap.add_argument("--out", default="frontiers.png")
    args = ap.parse_args(argv)
    runs = [load(r) for r in args.run]
    scenes = args.scenes.split(",") if args.scenes else sorted(set.intersection(*(set(r) for _, r in runs)))
    missing = [(label, s) for label, r in runs for s in scenes if s not in r]
    if missing:
        raise SystemExit(f"frontiers: no results for {missing}")
    fig, axes = plt.subplots(len(scenes), len(METRICS), figsize=(5.5 * len(METRICS), 4 * len(scenes)), squeeze=False)
    plain = FuncFormatter(lambda v, _: f"{v:g}")
    print("| scene | run | epsilon | seconds | per face | per texel | bias |")
    print("|---|---|---|---|---|---|---|")
    for row, scene in enumerate(scenes):
        clock = "wall"
        for label, results in runs:
            r = results[scene]
            clock = r.get("clock", "wall")
            pts = sorted(r["penumbra"], key=lambda p: seconds(p, clock))
            xs = [seconds(p, clock) for p in pts]
            for p, x in zip(pts, xs):
                print(f"| {scene} | {label} | {p['epsilon']:g} | {x:.2f} | {100 * p['face']:.2f} % | "
                      f"{100 * p['texel']:.2f} % | {100 * p['bias']:+.2f} % |")
            for col, (key, _) in enumerate(METRICS):
                ys = [100 * p[key] for p in pts]
                line, = axes[row][col].plot(xs, ys, "o-", label=label)
                for p, x, y in zip(pts, xs, ys):
                    axes[row][col].annotate(f"{p['epsilon']:g}", (x, y), fontsize=7, color=line.get_color(),
                                            textcoords="offset points", xytext=(4, 4))
        for col, (_, name) in enumerate(METRICS):
            ax = axes[row][col]
            ax.set_xscale("log")
            ax.set_yscale("log")
            for axis in (ax.xaxis, ax.yaxis):
                axis.set_major_formatter(plain)
                axis.set_minor_formatter(plain)
            ax.set_title(f"{scene}: error {name} against Cycles")
            ax.set_xlabel(f"Penumbra bake, {'CPU' if clock == 'cpu' else 'wall'} seconds")
            ax.set_ylabel("relative RMS error, %")
            ax.grid(True, which="both", alpha=0.3)
            ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(args.out, dpi=110)
    print(f"frontiers: wrote {args.out}", file=sys.stderr)


if __name__ == "__main__":
    main()

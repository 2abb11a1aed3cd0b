"""Convolution links on objects standing on their receiver (issue 12): box on a floor, table on a floor, bookcase
against a wall (native/python/contact_scenes.py), against their exact direct light.

    /usr/bin/python3 bench/contact_links.py [--grid 48] [--repeats 3]

Per scene and mode (standard refinement, convolution links): relative RMS and worst error of the receiver's
radiance over a grid (points covered by an object left out), the largest radiance on the covered points (light
under the object, as a fraction of the peak), convolution links, elements, rays, and the solve's CPU time (one
thread, best of --repeats; CPU time because the machine is shared).
"""
import argparse
import os
import resource
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(os.environ.get("PENUMBRA_ADDON_DIR", os.path.join(HERE, "..", "build", "addon")),
                                "penumbra"))
sys.path.insert(0, os.path.join(HERE, "..", "native", "python"))
import _native  # noqa: E402
import contact_scenes  # noqa: E402

MODES = {"standard": {"convolution": False}, "convolution": {"contact_slabs": True}}


def cpu():
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def radiance(sol, scene, pts):
    n = np.tile(scene.normal.astype(np.float32), (len(pts), 1))
    return sol.radiance(pts.astype(np.float32), n)[:, 0].astype(np.float64)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--grid", type=int, default=48)
    ap.add_argument("--repeats", type=int, default=3)
    a = ap.parse_args()
    print("| scene | mode | RMS | worst | light under the object | convolution links (tried) | elements | rays | "
          "solve CPU s |")
    print("|---|---|---|---|---|---|---|---|---|")
    for name in ("box_on_floor", "table_on_floor", "bookcase_against_wall"):
        scene = getattr(contact_scenes, name)()
        pts = scene.sample_points(a.grid)
        exact = scene.exact_radiance(pts)
        under = scene.under_points()
        for mode, settings in MODES.items():
            best = np.inf
            for _ in range(a.repeats):
                t = cpu()
                sol = _native.solve(*scene.args, dict(settings, threads=1))
                best = min(best, cpu() - t)
            got = radiance(sol, scene, pts)
            rms = np.sqrt(((got - exact) ** 2).sum() / (exact ** 2).sum())
            worst = np.abs(got - exact).max() / exact.max()
            dark = radiance(sol, scene, under).max() / exact.max() if len(under) else 0.0
            rep = sol.report
            print(f"| {name} | {mode} | {rms * 100:.2f} % | {worst * 100:.1f} % | {dark * 100:.2f} % | "
                  f"{rep['convolution_links']} ({rep['convolution_tried']}) | {rep['elements']} | {rep['rays']} | "
                  f"{best:.2f} |", flush=True)


if __name__ == "__main__":
    main()

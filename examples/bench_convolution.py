#!/usr/bin/python3
"""Benchmark of the convolution soft-shadow stage through the Python module (not a test).

    PENUMBRA_ADDON_DIR=$PWD/build/addon /usr/bin/python3 examples/bench_convolution.py [--quick]

Prints markdown tables: time per link for n = 64..1024 and N = 1, 2, 4, 8 split into raster / FFT /
rest beside the FFTW floor (three transforms of the padded size per sub-blocker, timed in the same
run with the same plans), and the blocker-mask rasterizers (CPU span vs OSMesa). Saves a plot to
docs/bench_convolution.png. Times are the best of a few runs; the machine is shared, read them
as +-20 %.
"""
import argparse
import os
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
_stage = os.environ.get("PENUMBRA_ADDON_DIR", os.path.join(HERE, "..", "build", "addon"))
sys.path.insert(0, os.path.join(os.path.abspath(_stage), "penumbra"))
import _native  # noqa: E402


def blocker_mesh(cells, z0=1.0, z1=1.5, half=0.8):
    """A warped, tessellated patch (2 * cells^2 triangles) whose depth runs from z0 to z1, so that
    N depth slabs all receive triangles."""
    g = np.linspace(-half, half, cells + 1)
    X, Y = np.meshgrid(g, g, indexing="ij")
    Z = z0 + (z1 - z0) * (X - X.min()) / (X.max() - X.min())
    X = X + 0.05 * np.sin(7 * Y)
    P = np.stack([X, Y, Z], -1)
    a, b, c, d = P[:-1, :-1], P[1:, :-1], P[1:, 1:], P[:-1, 1:]
    t1 = np.stack([a, b, c], -2).reshape(-1, 3, 3)
    t2 = np.stack([a, c, d], -2).reshape(-1, 3, 3)
    # Holes so the mask is not one convex blob: drop every third quad.
    keep = (np.arange(len(t1)) % 3) != 0
    return np.concatenate([t1[keep], t2[keep]])


def best_of(fn, repeats):
    best = None
    for _ in range(repeats):
        t0 = time.perf_counter()
        r = fn()
        dt = (time.perf_counter() - t0) * 1e3
        if best is None or dt < best[0]:
            best = (dt, r)
    return best


def link_table(ns, Ns, quick):
    source = np.array([[-0.25, -0.25, 0], [0.25, -0.25, 0], [0.25, 0.25, 0], [-0.25, 0.25, 0]], float)
    receiver = np.array([[-3, -3, 3], [3, -3, 3], [3, 3, 3], [-3, 3, 3]], float)
    tris = blocker_mesh(70)
    rows = []
    for n in ns:
        for N in Ns:
            call = lambda: _native.soft_shadow_texture(source, receiver, tris, resolution=n, e_max=1e-9,
                                                       n_max=N, direction="source_normal")
            call()  # plans and wisdom for this size
            reps = 2 if quick else (5 if n <= 256 else 3)
            wall, r = best_of(call, reps)
            t = r["times"]
            floor = _native.bench_fft_floor_ms(r["fft_size"], 3 if quick else 5) * r["sub_blockers"]
            rows.append(dict(n=n, N=r["sub_blockers"], F=r["fft_size"], wall=wall, raster=t["raster_ms"],
                             fft=t["fft_ms"], rest=t["rest_ms"], floor=floor,
                             ratio=wall / (floor + t["raster_ms"]),
                             pred=_native.predicted_seconds(r["fft_size"], r["sub_blockers"]) * 1e3))
    print(f"\nBlocker: {len(tris)} triangles spread in depth 1.0..1.5; source 0.5 x 0.5; receiver 6 x 6 at depth 3.")
    print("| n | N | FFT size | link ms (wall) | raster ms | FFT ms | rest ms | FFTW floor ms (3N transforms) "
          "| link / (floor + raster) | model (2+2N)·C·n²·log₂n ms |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['n']} | {r['N']} | {r['F']} | {r['wall']:.2f} | {r['raster']:.2f} | {r['fft']:.2f} | "
              f"{r['rest']:.2f} | {r['floor']:.2f} | {r['ratio']:.2f} | {r['pred']:.2f} |")
    return rows


def mask_table(sizes, counts, quick):
    rows = []
    try:
        _native.bench_rasterize(np.zeros((1, 3, 2)), 0, 1, 8, "osmesa", 4, 1)
        have_osmesa = True
    except RuntimeError as e:
        print("OSMesa unavailable:", e)
        have_osmesa = False
    for cells in counts:
        tris3 = blocker_mesh(cells)
        tris = tris3[:, :, :2] * (3.0 / tris3[:, :, 2:3])  # central projection onto depth 3
        for size in sizes:
            reps = 3 if quick else 10
            span, img_s = _native.bench_rasterize(tris, -3.2, 3.2, size, "span", 4, reps)
            row = dict(tris=len(tris), size=size, span=span, cov=img_s.mean())
            if have_osmesa:
                o16, img_o = _native.bench_rasterize(tris, -3.2, 3.2, size, "osmesa", 4, reps)
                o4, _ = _native.bench_rasterize(tris, -3.2, 3.2, size, "osmesa", 2, reps)
                row.update(osm16=o16, osm4=o4, cov_o=img_o.mean(), diff=np.abs(img_o - img_s).mean())
            rows.append(row)
    print("\n| triangles | mask size | span, 4 sub-rows (ms) | OSMesa 16 samples (4x MSAA, 2x2 upscale) (ms) "
          "| OSMesa 4x MSAA (ms) | OSMesa16 / span | coverage span / OSMesa | mean abs diff |")
    print("|---|---|---|---|---|---|---|---|")
    for r in rows:
        if "osm16" in r:
            print(f"| {r['tris']} | {r['size']}² | {r['span']:.2f} | {r['osm16']:.2f} | {r['osm4']:.2f} | "
                  f"{r['osm16'] / r['span']:.1f}× | {r['cov']:.4f} / {r['cov_o']:.4f} | {r['diff']:.4f} |")
        else:
            print(f"| {r['tris']} | {r['size']}² | {r['span']:.2f} | – | – | – | {r['cov']:.4f} | – |")
    return rows


def plot(rows, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(1, 2, figsize=(11, 4.2))
    for N in sorted({r["N"] for r in rows}):
        sel = [r for r in rows if r["N"] == N]
        ns = [r["n"] for r in sel]
        line, = ax[0].loglog(ns, [r["wall"] for r in sel], "o-", label=f"link, N={N}")
        ax[0].loglog(ns, [r["floor"] + r["raster"] for r in sel], "--", color=line.get_color(), alpha=0.6)
        ax[1].semilogx(ns, [r["ratio"] for r in sel], "o-", label=f"N={N}")
    ax[0].set_xlabel("texture resolution n")
    ax[0].set_ylabel("ms per link (dashed: FFTW floor + raster)")
    ax[0].legend(fontsize=8)
    ax[0].grid(True, which="both", alpha=0.3)
    ax[1].axhline(2.0, color="k", lw=0.8, ls=":")
    ax[1].set_xlabel("texture resolution n")
    ax[1].set_ylabel("link / (FFTW floor + raster)")
    ax[1].set_ylim(0, 2.5)
    ax[1].legend(fontsize=8)
    ax[1].grid(True, alpha=0.3)
    for a in ax:
        a.set_xticks([64, 128, 256, 512, 1024])
        a.set_xticklabels(["64", "128", "256", "512", "1024"])
    fig.suptitle("Convolution soft-shadow link cost (fftw3f, span rasterizer, 1 thread)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    print(f"\nplot saved to {path}")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true", help="fewer sizes and repeats")
    ap.add_argument("--plot", default=os.path.join(HERE, "..", "docs", "bench_convolution.png"))
    args = ap.parse_args()
    print(f"load average at start: {os.getloadavg()[0]:.2f}; FFT cost constant C = {_native.fft_cost_constant():.3e} s")
    ns = [64, 128, 256] if args.quick else [64, 128, 256, 512, 1024]
    rows = link_table(ns, [1, 2, 4, 8], args.quick)
    mask_table([256, 512, 1024], [22, 70, 224], args.quick)
    print(f"load average at end: {os.getloadavg()[0]:.2f}")
    plot(rows, os.path.abspath(args.plot))


if __name__ == "__main__":
    main()

"""Solve time and memory against polygon count on the scalable office (examples/scalable_scene.py).

    /usr/bin/python3 bench/scaling.py [--sizes 1000,5000,20000,50000,100000] [--timeout 300]
        [--settings '{"clustering": true}'] [--min-size-m 0.15] [--build build/addon] [--label TEXT]
        [--json docs/scaling_results.json] [--plot docs/bench_scaling.png] [--no-skip]

Each size runs in a fresh subprocess of this script (`--worker N`), so the peak memory is that size's own: the
kernel's high-water mark of the child (ru_maxrss from wait4), which also covers a child killed at the
timeout; the child's own VmHWM before and after the solve is kept in the JSON as well. The clock is the
solver's own: report['times'], per stage and their total (the solve call's wall time is kept beside it).

A size the solver refuses (BudgetExceeded, e.g. max_face_pairs without clustering), one past --timeout, one
that fails and one whose process dies are rows in the table, not a crash; after a timeout the larger sizes are
skipped (they would only time out later) unless --no-skip. Settings that the module does not know are caught
once, up front, with a message naming the key, before any size runs (exit status 2).

The scene keeps one workstation per 4 m^2 and lights of fixed exitance, so its bounding box grows like
sqrt(polygons); the solver's default min_size is relative to that box, so by default the smallest element
grows with the scene (0.13 m at 1k polygons, 0.96 m at 100k). --min-size-m holds it fixed in metres instead
(converted to the relative setting per size); the table shows which one was used.

Outputs: a markdown table on stdout, --json (the runs, settings, machine, commit) and --plot: log-log solve
time against polygons with the least-squares exponent over the solved sizes from --fit-from (5k) up, the
target (100k polygons in 20 s) and an exponent-1.1 reference line (issue 14) through it; and peak memory beside it, with
its target (4 GB at 200k polygons). --replot JSON redraws a saved run's figure.
"""
import argparse
import datetime
import json
import math
import os
import platform
import signal
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(HERE)
sys.path.insert(0, os.path.join(REPO, "examples"))

TARGET_POLYGONS, TARGET_SECONDS, TARGET_EXPONENT = 100_000, 20.0, 1.1  # issue 14: exponent <= 1.1 from 5k
TARGET_MEMORY_POLYGONS, TARGET_MEMORY_MIB = 200_000, 4096.0  # issue 14: peak memory <= 4 GB at 200k polygons
DEFAULT_MIN_SIZE = 0.01               # the solver's default relative min_size (native/python/API.md)
RESULT_MARK = "SCALING-RESULT "        # the worker's last stdout line; anything the module prints is ignored


def parse_args(argv=None):
    ap = argparse.ArgumentParser(prog="scaling.py", description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", default="1000,5000,20000,50000,100000",
                    help="target polygon counts, comma-separated (k suffix allowed: 1k,5k)")
    ap.add_argument("--timeout", type=float, default=300.0, help="seconds per size, scene build included")
    ap.add_argument("--settings", default="{}", help="JSON dict of extra solver settings, e.g. "
                                                     "'{\"clustering\": true}'")
    ap.add_argument("--min-size-m", type=float, default=None,
                    help="smallest element edge in metres, held fixed across sizes (default: the solver's "
                         "relative min_size)")
    ap.add_argument("--build", default=os.path.join(REPO, "build", "addon"),
                    help="folder holding penumbra/_native*.so (or the .so itself's folder)")
    ap.add_argument("--seed", type=int, default=0, help="scene seed")
    ap.add_argument("--fit-from", type=int, default=5000, help="fit the exponent over solved sizes >= this")
    ap.add_argument("--label", default="", help="a note kept in the JSON and the plot title")
    ap.add_argument("--json", default=os.path.join(REPO, "docs", "scaling_results.json"))
    ap.add_argument("--plot", default=os.path.join(REPO, "docs", "bench_scaling.png"))
    ap.add_argument("--no-skip", action="store_true", help="run the larger sizes after a timeout too")
    ap.add_argument("--clock", choices=("wall", "cpu"), default="wall",
                    help="what the fit and the plot use: the solver's own wall clock, or the CPU seconds of the "
                         "solve call (all threads; steadier on a machine other jobs load)")
    ap.add_argument("--replot", default=None,
                    help="redraw --plot from a JSON this script wrote (no solving)")
    ap.add_argument("--include", default=None,
                    help="a JSON file of an earlier run whose solved sizes (not run again here) join the table, fit "
                         "and plot, marked as included (e.g. docs/scaling_results_200k.json)")
    ap.add_argument("--worker", type=int, default=None, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    try:
        args.settings = json.loads(args.settings)
    except json.JSONDecodeError as e:
        ap.error(f"--settings is not JSON: {e}")
    if not isinstance(args.settings, dict):
        ap.error("--settings must be a JSON object, e.g. '{\"clustering\": true}'")
    args.sizes = sorted(set(parse_sizes(args.sizes)))
    return args


def parse_sizes(text):
    """Polygon counts from a comma-separated list, a k suffix meaning thousands (1k, 5k, 20000)."""
    sizes = []
    for s in text.split(","):
        s = s.strip().lower()
        if s:
            sizes.append(int(float(s[:-1]) * 1000) if s.endswith("k") else int(s))
    return sizes


def import_native(build):
    for d in (os.path.join(build, "penumbra"), build):
        if os.path.isdir(d) and any(f.startswith("_native") and f.endswith(".so") for f in os.listdir(d)):
            sys.path.insert(0, d)
            import _native
            return _native
    raise SystemExit(f"scaling: no _native*.so in {build}/penumbra or {build}; run bash scripts/build.sh "
                     f"or pass --build")


def vm_hwm_mib():
    """This process's resident high-water mark so far (VmHWM), in MiB."""
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 1024.0
    return float("nan")


def busy_cpu_seconds():
    """CPU time all processes have used since boot (/proc/stat, every core, idle and iowait excluded)."""
    with open("/proc/stat") as f:
        fields = [int(x) for x in f.readline().split()[1:]]
    user, nice, system, idle, iowait, irq, softirq, steal = (fields + [0] * 8)[:8]
    return (user + nice + system + irq + softirq + steal) / os.sysconf("SC_CLK_TCK")


def effective_settings(args, scene):
    import scalable_scene
    settings = dict(args.settings)
    diagonal = scalable_scene.scene_diagonal(scene)
    if args.min_size_m is not None and "min_size" not in settings:
        settings["min_size"] = args.min_size_m / diagonal
    return settings, diagonal


# ---------------------------------------------------------------------------------------------- worker side

def worker(args):
    """Build one size, solve it, print one result line. Progress goes to stderr so that a run killed at the
    timeout still says where it was."""
    import scalable_scene
    _native = import_native(args.build)
    hwm_import = vm_hwm_mib()
    t0 = time.perf_counter()
    scene = scalable_scene.make_scene(args.worker, seed=args.seed)
    build_s = time.perf_counter() - t0
    settings, diagonal = effective_settings(args, scene)
    result = {"target": args.worker, "polygons": int(len(scene["polygons"])), "build_seconds": build_s,
              "diagonal_m": diagonal, "settings": settings,
              "min_size_m": settings.get("min_size", DEFAULT_MIN_SIZE) * diagonal,
              "hwm_after_import_mib": hwm_import, "hwm_before_solve_mib": vm_hwm_mib()}
    # Said early, so that the parent can tell the solve's own memory even if this process is killed.
    print(f"baseline {result['hwm_before_solve_mib']:.1f} MiB", file=sys.stderr, flush=True)
    last = [None, -1.0]

    def progress(stage, fraction):
        if stage != last[0] or fraction >= last[1] + 0.05:
            last[0], last[1] = stage, fraction
            print(f"progress {time.perf_counter() - t0:.1f} s {stage} {fraction:.2f}", file=sys.stderr,
                  flush=True)
        return True

    t1 = time.perf_counter()
    c1 = time.process_time()     # every thread of this process: the solver's CPU whatever else loads the machine
    try:
        sol = _native.solve(**scene, settings=settings, progress=progress)
    except _native.BudgetExceeded as e:
        result.update(status="refused", message=str(e))
    except ValueError as e:
        result.update(status="error", message=f"ValueError: {e}")
    except Exception as e:                              # reported in the table, not raised: the run goes on
        result.update(status="error", message=f"{type(e).__name__}: {e}")
    else:
        rep = sol.report
        times = {k: float(v) for k, v in rep["times"].items()}
        result.update(status="solved", wall_seconds=time.perf_counter() - t1, times=times,
                      solve_cpu_seconds=time.process_time() - c1,
                      total_seconds=times.get("total", sum(times.values())),
                      **{k: rep[k] for k in ("elements", "leaves", "links", "rays", "shafts_clear", "iterations",
                                             "residual", "converged", "refine_passes", "warnings")
                         if k in rep})
        if "min_edge" in rep:  # the solver's own floor (min_size of the smaller of the diagonal and 35 pieces)
            result["min_size_m"] = float(rep["min_edge"])
        # The answer must be usable, not just fast: sample the radiance at every face centre.
        import numpy as np
        v, p = scene["vertices"], scene["polygons"]
        corners = v[p]
        centre = corners.mean(axis=1)
        normal = np.cross(corners[:, 1] - corners[:, 0], corners[:, 3] - corners[:, 0])
        normal /= np.linalg.norm(normal, axis=1, keepdims=True)
        rad = sol.radiance(np.ascontiguousarray(centre + 1e-4 * normal, np.float32),
                           np.ascontiguousarray(normal, np.float32))
        result["radiance_finite_nonnegative"] = bool(np.isfinite(rad).all() and (rad >= 0).all())
        result["radiance_mean"] = float(rad.mean())
    result["hwm_after_solve_mib"] = vm_hwm_mib()
    print(RESULT_MARK + json.dumps(result), flush=True)
    return 0


# ---------------------------------------------------------------------------------------------- parent side

def check_settings(args):
    """One tiny solve in this process with the settings, so an unknown or bad key stops the run at once
    instead of filling every row with the same error."""
    import numpy as np
    _native = import_native(args.build)
    verts = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0],
                      [-.2, -.2, 1], [-.2, .2, 1], [.2, .2, 1], [.2, -.2, 1]], np.float32)
    settings = dict(args.settings)
    if args.min_size_m is not None and "min_size" not in settings:
        settings["min_size"] = 0.01
    try:
        _native.solve(verts, np.array([[0, 1, 2, 3], [4, 5, 6, 7]], np.int32),
                      np.array([[.5] * 3, [0] * 3], np.float32), np.array([[0] * 3, [1] * 3], np.float32),
                      np.array([0, _native.LIGHT_ONLY], np.uint8), np.array([0, 1], np.int32),
                      ["Plane", "Lamp"], settings=settings)
    except ValueError as e:
        msg = str(e)
        if "unknown setting" in msg:
            key = msg.split("'")[1] if msg.count("'") >= 2 else "?"
            print(f"scaling: the module in {args.build} does not know the setting '{key}' ({msg}); it was "
                  f"built before that setting existed -- rebuild it, or drop the key from --settings",
                  file=sys.stderr)
        else:
            print(f"scaling: the module refuses --settings {json.dumps(args.settings)}: {msg}", file=sys.stderr)
        sys.exit(2)
    return _native


def run_size(args, n, skip_reason=None):
    import scalable_scene
    row = {"target": n}
    if skip_reason:
        row.update(status="skipped", message=skip_reason, polygons=scalable_scene.plan(n)["polygons"])
        return row
    cmd = [sys.executable, os.path.abspath(__file__), "--worker", str(n), "--build", args.build,
           "--settings", json.dumps(args.settings), "--seed", str(args.seed)]
    if args.min_size_m is not None:
        cmd += ["--min-size-m", repr(args.min_size_m)]
    busy0 = busy_cpu_seconds()
    with tempfile.TemporaryFile("w+") as out, tempfile.TemporaryFile("w+") as err:
        t0 = time.perf_counter()
        proc = subprocess.Popen(cmd, stdout=out, stderr=err, text=True)
        timed_out = False
        # wait4 rather than Popen.wait: its rusage gives the child's own peak RSS, even once killed.
        while True:
            pid, status, usage = os.wait4(proc.pid, os.WNOHANG)
            if pid:
                break
            if time.perf_counter() - t0 > args.timeout:
                timed_out = True
                proc.kill()
                pid, status, usage = os.wait4(proc.pid, 0)
                break
            time.sleep(0.05)
        proc.returncode = os.waitstatus_to_exitcode(status)       # already reaped; keep Popen from waiting
        elapsed = time.perf_counter() - t0
        out.seek(0)
        err.seek(0)
        stdout, stderr = out.read(), err.read()
    row["peak_mib"] = usage.ru_maxrss / 1024.0
    row["cpu_seconds"] = usage.ru_utime + usage.ru_stime
    # Other work on the machine slows the solver down: the cores it kept busy on average during this run,
    # so that a noisy row can be recognised (the load average would count this run too, and lags).
    row["other_cores"] = max(0.0, (busy_cpu_seconds() - busy0 - row["cpu_seconds"]) / elapsed)
    row["process_seconds"] = elapsed
    results = [line[len(RESULT_MARK):] for line in stdout.splitlines() if line.startswith(RESULT_MARK)]
    progress = [line for line in stderr.splitlines() if line.startswith("progress ")]
    baseline = [line for line in stderr.splitlines() if line.startswith("baseline ")]
    if baseline:
        row["baseline_mib"] = float(baseline[0].split()[1])
        row["solve_mib"] = row["peak_mib"] - row["baseline_mib"]
    if timed_out:
        row.update(status="timeout", message=f"killed after {args.timeout:g} s" +
                   (f"; last {progress[-1]}" if progress else ""))
    elif results:
        row.update(json.loads(results[-1]))
    else:
        code = proc.returncode
        why = f"signal {signal.Signals(-code).name}" if code < 0 else f"exit status {code}"
        tail = " | ".join(stderr.strip().splitlines()[-3:])
        row.update(status="crashed", message=f"{why}" + (f": {tail}" if tail else ""))
    if "polygons" not in row:
        row["polygons"] = scalable_scene.plan(n)["polygons"]
    if "min_size_m" not in row:
        # The room encloses everything, so its diagonal is the scene's; no need to build the scene here.
        diagonal = math.hypot(*scalable_scene.plan(n)["room"])
        row["min_size_m"] = args.settings["min_size"] * diagonal if "min_size" in args.settings else \
            args.min_size_m if args.min_size_m is not None else DEFAULT_MIN_SIZE * diagonal
    return row


def seconds(row, clock):
    """The row's solve time on the chosen clock. Rows from runs before solve_cpu_seconds was kept fall back on
    the whole worker's CPU (scene build and import included: small beside a large solve)."""
    if clock == "cpu":
        return row.get("solve_cpu_seconds", row.get("cpu_seconds", 0.0))
    return row["total_seconds"]


def fit_exponent(rows, fit_from, clock="wall"):
    pts = [(r["polygons"], seconds(r, clock)) for r in rows
           if r["status"] == "solved" and r["polygons"] >= fit_from and seconds(r, clock) > 0]
    if len(pts) < 2:
        return None
    xs = [math.log(p) for p, _ in pts]
    ys = [math.log(t) for _, t in pts]
    mx, my = sum(xs) / len(xs), sum(ys) / len(ys)
    sxx = sum((x - mx) ** 2 for x in xs)
    slope = sum((x - mx) * (y - my) for x, y in zip(xs, ys)) / sxx
    return {"exponent": slope, "log_intercept": my - slope * mx, "from": min(p for p, _ in pts),
            "to": max(p for p, _ in pts), "points": len(pts)}


def stage_names(rows):
    names = []
    for r in rows:
        for k in r.get("times", {}):
            if k not in names and k != "total":
                names.append(k)
    order = ["scene", "visibility_setup", "refine", "solve", "reconstruct"]
    return sorted(names, key=lambda k: (order.index(k) if k in order else len(order), k))


def _si(x):
    for unit, scale in (("G", 1e9), ("M", 1e6), ("k", 1e3)):
        if x >= scale:
            return f"{x / scale:.3g}{unit}"
    return f"{x:g}"


def markdown_table(rows, fit, fit_from):
    stages = stage_names(rows)
    head = ["target", "polygons", "status", "total s", "solve CPU s"] + [f"{s} s" for s in stages] + \
           ["elements", "links", "rays", "peak MiB", "solve MiB", "min elem m", "other cores"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in rows:
        if r["status"] == "solved":
            cpu = r.get("solve_cpu_seconds", r.get("cpu_seconds"))
            cells = [f"{r['total_seconds']:.2f}", f"{cpu:.1f}" if cpu is not None else "—"] + \
                    [f"{r['times'].get(s, 0.0):.2f}" for s in stages] + \
                    [_si(r["elements"]), _si(r["links"]), _si(r["rays"])]
        else:
            cells = ["—"] * (2 + len(stages) + 3)
        peak = f"{r['peak_mib']:.0f}" if "peak_mib" in r else "—"
        grown = f"{r['solve_mib']:.0f}" if "solve_mib" in r else "—"
        mins = f"{r['min_size_m']:.3f}" if "min_size_m" in r else "—"
        load = f"{r['other_cores']:.2f}" if "other_cores" in r else "—"
        status = r["status"] + (" (included)" if r.get("included") else "")
        lines.append("| " + " | ".join([_si(r["target"]), str(r.get("polygons", "—")), status] + cells +
                                       [peak, grown, mins, load]) + " |")
    notes = [f"- {_si(r['target'])}: {r['status']}: {r['message']}" for r in rows if r.get("message")]
    if fit:
        notes.append(f"- fitted exponent (time ~ polygons^k, {fit['points']} solved sizes from "
                     f"{fit['from']} to {fit['to']} polygons): k = {fit['exponent']:.2f}")
    else:
        notes.append(f"- no exponent fitted: fewer than two sizes of {fit_from} polygons or more were solved")
    return "\n".join(lines + ([""] + notes if notes else []))


def plot(rows, fit, path, title, clock="wall"):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax, axm) = plt.subplots(1, 2, figsize=(12, 5))
    solved = [r for r in rows if r["status"] == "solved"]
    xs_all = [r["polygons"] for r in rows] + [TARGET_POLYGONS]
    x_lo, x_hi = min(xs_all) / 1.5, max(xs_all) * 1.5
    if solved:
        ax.loglog([r["polygons"] for r in solved], [seconds(r, clock) for r in solved], "o-", color="C0",
                  label="solve time (report['times'] total)" if clock == "wall" else "solve CPU seconds (all threads)")
        inc = [r for r in solved if r.get("included")]
        if inc:
            ax.loglog([r["polygons"] for r in inc], [seconds(r, clock) for r in inc], "s", color="C0",
                      markerfacecolor="none", markersize=12, label="from an earlier run (--include)")
    timeouts = [r for r in rows if r["status"] == "timeout"]
    if timeouts:
        ax.loglog([r["polygons"] for r in timeouts], [r["process_seconds"] for r in timeouts], "^", color="C3",
                  markersize=10, label="timed out (time is a lower bound)")
    xr = [x_lo, x_hi]
    ax.loglog(xr, [TARGET_SECONDS * (x / TARGET_POLYGONS) ** TARGET_EXPONENT for x in xr], "--", color="0.5",
              label=f"exponent {TARGET_EXPONENT} through the target")
    ax.loglog([TARGET_POLYGONS], [TARGET_SECONDS], "*", color="C2", markersize=16,
              label=f"target: {TARGET_POLYGONS // 1000}k polygons in {TARGET_SECONDS:g} s")
    if fit:
        xf = [fit["from"], fit["to"]]
        ax.loglog(xf, [math.exp(fit["log_intercept"]) * x ** fit["exponent"] for x in xf], "-", color="C1",
                  linewidth=3, alpha=0.6, label=f"fit {fit['from']}–{fit['to']}: exponent {fit['exponent']:.2f}")
    ymin, ymax = ax.get_ylim()
    for r in rows:
        if r["status"] in ("refused", "error", "crashed", "skipped"):
            ax.axvline(r["polygons"], color="C3" if r["status"] != "skipped" else "0.7", linestyle=":")
            ax.text(r["polygons"], ymax / 1.3, f"{r['status']} ", rotation=90, va="top", ha="right",
                    color="C3" if r["status"] != "skipped" else "0.5")
    ax.set_xlim(x_lo, x_hi)
    ax.set_xlabel("polygons")
    ax.set_ylabel("seconds" if clock == "wall" else "CPU seconds (all threads)")
    ax.set_title("solve time")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8, loc="lower right")

    mem = [r for r in rows if "peak_mib" in r]
    if mem:
        for status, style in (("solved", "o-"), ("timeout", "^"), ("refused", "x"), ("error", "x"),
                              ("crashed", "x")):
            pts = [r for r in mem if r["status"] == status]
            if pts:
                axm.loglog([r["polygons"] for r in pts], [r["peak_mib"] for r in pts], style, markersize=8,
                           label=status)
    axm.loglog([TARGET_MEMORY_POLYGONS], [TARGET_MEMORY_MIB], "*", color="C2", markersize=16,
               label=f"target: at most {TARGET_MEMORY_MIB / 1024:g} GB at {TARGET_MEMORY_POLYGONS // 1000}k polygons")
    axm.set_xlim(x_lo, x_hi)
    axm.set_xlabel("polygons")
    axm.set_ylabel("MiB")
    axm.set_title("peak resident memory of the solving process")
    axm.grid(True, which="both", alpha=0.3)
    axm.legend(fontsize=8)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def git_describe():
    try:
        commit = subprocess.run(["git", "-C", REPO, "rev-parse", "HEAD"], capture_output=True, text=True,
                                check=True).stdout.strip()
        dirty = bool(subprocess.run(["git", "-C", REPO, "status", "--porcelain", "--untracked-files=no"],
                                    capture_output=True, text=True).stdout.strip())
        return commit, dirty
    except (OSError, subprocess.CalledProcessError):
        return None, None


def main():
    args = parse_args()
    args.build = os.path.abspath(args.build)
    if args.worker is not None:
        return worker(args)
    if args.replot:
        with open(args.replot) as f:
            saved = json.load(f)
        meta = saved["meta"]
        commit = meta.get("commit") or "?"
        title = "Penumbra scaling, scalable office scene" + (f" — {meta['label']}" if meta.get("label") else "") + \
                f"\nsettings {json.dumps(meta.get('settings'))}" + \
                (f", min size {meta['min_size_m']} m" if meta.get("min_size_m") is not None else ", default min_size") + \
                f", {meta.get('cpus', '?')} cores, commit {commit[:8]}{' (dirty)' if meta.get('dirty') else ''}"
        plot(saved["runs"], saved["fit"], args.plot, title, meta.get("clock", "wall"))
        return 0
    _native = check_settings(args)
    rows, skip = [], None
    for n in args.sizes:
        print(f"scaling: {n} polygons ...", file=sys.stderr, flush=True)
        row = run_size(args, n, skip)
        rows.append(row)
        done = f"{row['total_seconds']:.2f} s" if row["status"] == "solved" else row.get("message", "")
        print(f"scaling: {n}: {row['status']} {done} (peak {row.get('peak_mib', float('nan')):.0f} MiB)",
              file=sys.stderr, flush=True)
        if row["status"] == "timeout" and not args.no_skip:
            skip = f"not run: {n} polygons timed out (--no-skip runs it anyway)"
    if args.include:
        with open(args.include) as f:
            earlier = json.load(f)
        have = {r["target"] for r in rows}
        for r in earlier.get("runs", []):
            if r.get("status") == "solved" and r["target"] not in have:
                rows.append(dict(r, included=os.path.basename(args.include)))
        rows.sort(key=lambda r: r["target"])
    fit = fit_exponent(rows, args.fit_from, args.clock)
    commit, dirty = git_describe()
    meta = {"date": datetime.datetime.now().isoformat(timespec="seconds"), "label": args.label,
            "commit": commit, "dirty": dirty, "module": _native.__file__, "build": args.build,
            "settings": args.settings, "min_size_m": args.min_size_m, "timeout": args.timeout,
            "clock": args.clock, "include": args.include,
            "seed": args.seed, "cpus": os.cpu_count(), "machine": platform.platform(),
            "python": platform.python_version(),
            "target": {"polygons": TARGET_POLYGONS, "seconds": TARGET_SECONDS, "exponent": TARGET_EXPONENT}}
    table = markdown_table(rows, fit, args.fit_from)
    print(table)
    if args.json:
        os.makedirs(os.path.dirname(os.path.abspath(args.json)), exist_ok=True)
        with open(args.json, "w") as f:
            json.dump({"meta": meta, "fit": fit, "runs": rows, "table": table}, f, indent=1)
    if args.plot:
        title = "Penumbra scaling, scalable office scene" + (f" — {args.label}" if args.label else "") + \
                f"\nsettings {json.dumps(args.settings)}" + \
                (f", min size {args.min_size_m} m" if args.min_size_m is not None else ", default min_size") + \
                f", {os.cpu_count()} cores, commit {commit[:8] if commit else '?'}{' (dirty)' if dirty else ''}"
        plot(rows, fit, args.plot, title, args.clock)
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""Checks the portable add-on zip (scripts/portable_zip.py) where it is unpacked, with the Python it was built
for (the one the embedding Blender has; numpy needed):

    python3.x scripts/portable_check.py build/penumbra-addon-portable.zip

1. Every ELF object in it (_native and penumbra/lib/*) carries its relative run path, and the loader, with an
   empty environment, resolves each of their dependencies inside penumbra/lib or to glibc / the GCC runtime.
   A system copy of the same library (this machine has them all: it built the module) must not be chosen.
2. In a fresh interpreter with an empty environment, importing _native and running it (a solve checked against
   the exact form factor, a lightmap written as EXR through OpenImageIO, a convolution shadow texture through
   FFTW, the OSMesa rasterizer when vendored) maps no shared object that was not already mapped before the
   import, except from penumbra/lib and the C/C++ runtimes.
Exits non-zero, naming the object, on any failure. scripts/test.sh runs it on the host leg; in a root without
the libraries (docs/blender-versions.md) the same script shows that nothing else is needed."""
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import zipfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from portable_zip import SYSTEM  # noqa: E402

RUNTIME_PROBE = r"""
import json, math, os, sys
pkg = sys.argv[1]
def mapped():
    return {l.split()[-1] for l in open("/proc/self/maps") if ".so" in l.split()[-1]}
before = mapped()
import numpy as np
before |= mapped()   # numpy's own libraries (libopenblas, ...) are the interpreter's, not the module's
sys.path.insert(0, pkg)
import _native
# A 0.5 m square lamp 1 m above a plane of albedo 0.5: the radiance under its centre is
# rho * E * F / pi with F the exact point-to-square form factor (Lambert's formula, here in closed form).
verts = np.array([[-2, -2, 0], [2, -2, 0], [2, 2, 0], [-2, 2, 0],
                  [-.25, -.25, 1], [-.25, .25, 1], [.25, .25, 1], [.25, -.25, 1]], np.float32)
sol = _native.solve(verts, np.array([[0, 1, 2, 3], [4, 5, 6, 7]], np.int32),
                    np.array([[.5] * 3, [0] * 3], np.float32), np.array([[0] * 3, [10] * 3], np.float32),
                    np.array([0, _native.LIGHT_ONLY], np.uint8), np.array([0, 1], np.int32), ["Plane", "Lamp"])
got = float(sol.radiance(np.array([[0, 0, 0]], np.float32), np.array([[0, 0, 1]], np.float32))[0, 0])
a = 0.25
# Form factor from a point to a coaxial square of half-side a at height h = 1: 4 * (corner rectangle a x a).
def rect_ff(x, y, h=1.0):
    X, Y = x / h, y / h
    return (X / math.sqrt(1 + X * X) * math.atan(Y / math.sqrt(1 + X * X)) +
            Y / math.sqrt(1 + Y * Y) * math.atan(X / math.sqrt(1 + Y * Y))) / (2 * math.pi)
expect = 0.5 * 10.0 * 4 * rect_ff(a, a) / math.pi
img = sol.bake_lightmap(verts[[0, 1, 2, 0, 2, 3]].reshape(2, 3, 3),
                        np.array([[[0, 0], [1, 0], [1, 1]], [[0, 0], [1, 1], [0, 1]]], np.float32), 16, 16, 1)
exr = os.path.join(sys.argv[2], "lm.exr")
_native.write_exr(exr, img)
with open(exr, "rb") as f:
    magic = f.read(4)
sq = np.array([[-.5, -.5, 0], [.5, -.5, 0], [.5, .5, 0], [-.5, .5, 0]], float)
rec = np.array([[-3, -3, 3], [3, -3, 3], [3, 3, 3], [-3, 3, 3]], float)
blk = [[[-.35, -.6, 1], [.65, -.6, 1], [.65, .4, 1]], [[-.35, -.6, 1], [.65, .4, 1], [-.35, .4, 1]]]
span = _native.soft_shadow_texture(sq, rec, blk, resolution=64, rasterizer="span")["visibility"]
osmesa = None
if os.path.exists(os.path.join(pkg, "lib", "libOSMesa.so.8")):
    o = _native.soft_shadow_texture(sq, rec, blk, resolution=64, rasterizer="osmesa")
    osmesa = float(np.abs(o["visibility"] - span).max())
print("PROBE", json.dumps({"radiance": got, "expect": expect, "exr_magic": magic.hex(), "exr_bytes":
      os.path.getsize(exr), "visibility_min": float(span.min()), "visibility_max": float(span.max()),
      "osmesa_max_diff": osmesa, "new": sorted(mapped() - before)}))
"""


def fail(msg):
    sys.exit(f"portable_check: FAILED: {msg}")


def soname(path):
    return os.path.basename(path)


def main():
    if len(sys.argv) != 2:
        sys.exit("usage: python3.x portable_check.py PORTABLE.zip")
    tmp = tempfile.mkdtemp(prefix="penumbra-portable-")
    try:
        with zipfile.ZipFile(sys.argv[1]) as z:
            z.extractall(tmp)
        pkg = os.path.join(tmp, "penumbra")
        libdir = os.path.join(pkg, "lib")
        objects = [os.path.join(pkg, f) for f in os.listdir(pkg) if f.startswith("_native") and f.endswith(".so")]
        if len(objects) != 1:
            fail(f"expected one _native*.so in the zip, found {objects}")
        libs = sorted(os.listdir(libdir))
        objects += [os.path.join(libdir, f) for f in libs if ".so" in f]

        # 1. Static: the run paths, and what the loader resolves. ldd on _native lists its whole closure, each
        # library's dependencies looked up through that library's own run path; the libraries it does not reach
        # (those opened with dlopen, as libtbbmalloc) get their own ldd.
        have_readelf = shutil.which("readelf") is not None
        if have_readelf:
            for obj in objects:
                dyn = subprocess.run(["readelf", "-d", obj], capture_output=True, text=True, check=True).stdout
                want = "$ORIGIN/lib" if obj == objects[0] else "$ORIGIN"
                if f"Library runpath: [{want}]" not in dyn:
                    fail(f"{obj} has no DT_RUNPATH {want}:\n{dyn}")
        # The loader itself, as ldd runs it: ldd is a bash script, and bash needs libtinfo, which the zip
        # vendors (for LLVM) and scripts/portable_root_check.sh hides from the system.
        lister = ["/lib64/ld-linux-x86-64.so.2", "--list"]
        reached = set()
        resolved_inside = 0
        for obj in objects:
            if soname(obj) in reached:
                continue
            r = subprocess.run(lister + [obj], env={"PATH": "/usr/bin:/bin"}, capture_output=True, text=True)
            if r.returncode != 0:   # the loader could not load something it found (127)
                fail(f"{' '.join(lister)} {soname(obj)}: exit {r.returncode}\n{r.stdout[-2000:]}{r.stderr[-2000:]}")
            out = r.stdout
            for line in out.splitlines():
                m = re.match(r"\s*(\S+)\s+=>\s+(.+?)\s+\(", line) or re.match(r"\s*(\S+)\s+=>\s+(not found)", line)
                if not m:
                    continue
                name, where = m.groups()
                if where == "not found":
                    fail(f"{soname(obj)} needs {name}, which is neither in penumbra/lib nor on the system")
                if os.path.realpath(where).startswith(os.path.realpath(libdir) + os.sep):
                    resolved_inside += 1
                    reached.add(name)
                elif not SYSTEM.match(name):
                    fail(f"{soname(obj)} resolves {name} to the system's {where}, not penumbra/lib")

        # 2. Dynamic: what the import and a run actually map.
        out = subprocess.run([sys.executable, "-c", RUNTIME_PROBE, pkg, tmp],
                             env={"PATH": "/usr/bin:/bin", "HOME": tmp}, capture_output=True, text=True)
        line = [x for x in out.stdout.splitlines() if x.startswith("PROBE ")]
        if out.returncode != 0 or not line:
            fail(f"the probe failed (exit {out.returncode}):\n{out.stdout[-3000:]}\n{out.stderr[-3000:]}")
        probe = json.loads(line[0][6:])
        inside = [p for p in probe["new"] if os.path.realpath(p).startswith(os.path.realpath(pkg) + os.sep)]
        outside = [p for p in probe["new"] if p not in inside and not SYSTEM.match(soname(p))]
        if outside:
            fail(f"importing and running _native mapped system libraries: {outside}")
        if abs(probe["radiance"] - probe["expect"]) > 0.01 * probe["expect"]:
            fail(f"radiance {probe['radiance']} against the exact {probe['expect']}")
        if probe["exr_magic"] != "762f3101":   # OpenEXR's magic number, little-endian
            fail(f"write_exr wrote no EXR (magic {probe['exr_magic']})")
        if not (probe["visibility_min"] < 0.05 and probe["visibility_max"] > 0.95):
            fail(f"the shadow texture has no umbra or no lit part: {probe}")
        if probe["osmesa_max_diff"] is not None and probe["osmesa_max_diff"] > 0.05:
            fail(f"the OSMesa rasterizer differs from the span one by {probe['osmesa_max_diff']}")
        print(f"portable_check: ok: {len(libs)} files in penumbra/lib; {len(objects)} ELF objects, "
              f"{resolved_inside} of their dependencies resolved inside penumbra/lib, none to a system copy; the run "
              f"mapped {len(inside)} objects from the zip and no other library; radiance "
              f"{probe['radiance']:.6f} (exact {probe['expect']:.6f}), EXR {probe['exr_bytes']} bytes, "
              f"OSMesa {'checked' if probe['osmesa_max_diff'] is not None else 'not vendored'}"
              f"{'' if have_readelf else '; readelf missing: run paths not read'}")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()

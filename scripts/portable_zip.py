"""Writes the portable add-on zip: the staged add-on with every shared library that _native needs copied into
penumbra/lib/, except the C and C++ runtimes, and relative run paths, so that the zip does not need Debian's
runtime or -dev packages where it is installed (a blender.org build with its own Python; issue 16 item 4).

    portable_zip.py STAGED_PACKAGE_DIR WORK_DIR OUT.zip

WORK_DIR/penumbra is made anew from STAGED_PACKAGE_DIR. The libraries are the whole closure that the dynamic
loader resolves for _native on this machine (ldd, with an empty environment so that no LD_LIBRARY_PATH leaks
in), each copied under its soname. _native gets the run path $ORIGIN/lib and each copied library $ORIGIN: a
DT_RUNPATH applies only to the object that carries it, so every library must find its own dependencies
beside itself. Needs patchelf (scripts/deps.sh installs it).

Left out, the system's own on every Linux that Blender runs on: glibc (libc, libm, libmvec, libpthread, libdl,
librt, libresolv, libutil, the loader) and the GCC runtimes (libstdc++, libgcc_s). The versions of those that
the zip needs (the highest GLIBC_ and GLIBCXX_ symbol versions) are written to penumbra/lib/NEEDS.txt and
printed; a system older than that cannot load it."""
import json
import os
import re
import shutil
import subprocess
import sys
import zipfile

# Sonames never vendored: glibc's libraries and the GCC runtime. Blender itself needs them, a copy of glibc
# cannot be mixed with the running one, and libstdc++ must be the process's single copy.
SYSTEM = re.compile(r"^(linux-vdso|ld-linux[-\w.]*|libc|libm|libmvec|libpthread|libdl|librt|libresolv|libutil|"
                    r"libanl|libBrokenLocale|libstdc\+\+|libgcc_s)\.so(\.\d+)*$")
# Loaded with dlopen by a vendored library, so ldd does not list them: oneTBB opens its scalable allocator
# from its own directory when it is there (and falls back to malloc when not).
DLOPENED = {"libtbb.so.12": ["libtbbmalloc.so.2"]}


def run(*cmd, **kw):
    return subprocess.run(cmd, check=True, capture_output=True, text=True, **kw).stdout


def resolved(path):
    """{soname: resolved path} for the loader's closure of `path`, or SystemExit naming a missing one."""
    out = run("ldd", path, env={"PATH": "/usr/bin:/bin"})
    libs = {}
    for line in out.splitlines():
        m = re.match(r"\s*(\S+)\s+=>\s+(\S+)", line)
        if not m:
            continue
        if m.group(2) == "not":
            sys.exit(f"portable_zip.py: {path} needs {m.group(1)}, which the loader cannot find")
        libs[m.group(1)] = m.group(2)
    return libs


def symbol_versions(path, prefix):
    """The highest `prefix`N.N.N symbol version that `path` requires (objdump -T), as a tuple."""
    best = ()
    for v in re.findall(re.escape(prefix) + r"([\d.]+)", run("objdump", "-T", path)):
        best = max(best, tuple(int(x) for x in v.strip(".").split(".")))
    return best


def main():
    if len(sys.argv) != 4:
        sys.exit("usage: portable_zip.py STAGED_PACKAGE_DIR WORK_DIR OUT.zip")
    src, work, dst = sys.argv[1:]
    if shutil.which("patchelf") is None:
        sys.exit("portable_zip.py: patchelf is missing (bash scripts/deps.sh installs it)")
    pkg = os.path.join(work, "penumbra")
    shutil.rmtree(pkg, ignore_errors=True)
    shutil.copytree(src, pkg, ignore=shutil.ignore_patterns("__pycache__", "lib"))
    modules = [f for f in os.listdir(pkg) if f.startswith("_native") and f.endswith(".so")]
    if len(modules) != 1:
        sys.exit(f"portable_zip.py: expected one _native*.so in {src}, found {modules}")
    module = os.path.join(pkg, modules[0])
    libdir = os.path.join(pkg, "lib")
    os.makedirs(libdir)

    closure = resolved(module)
    for soname, extra in DLOPENED.items():
        if soname in closure:
            for name in extra:
                path = os.path.join(os.path.dirname(closure[soname]), name)
                if os.path.exists(path):
                    closure[name] = path
                    for k, v in resolved(path).items():
                        closure.setdefault(k, v)
    vendored = sorted(s for s in closure if not SYSTEM.match(s))
    for soname in vendored:
        target = os.path.join(libdir, soname)
        shutil.copyfile(os.path.realpath(closure[soname]), target)
        os.chmod(target, 0o644)
        run("patchelf", "--set-rpath", "$ORIGIN", target)
    run("patchelf", "--set-rpath", "$ORIGIN/lib", module)

    objects = [module] + [os.path.join(libdir, s) for s in vendored]
    glibc = max(symbol_versions(o, "GLIBC_") for o in objects)
    glibcxx = max(symbol_versions(o, "GLIBCXX_") for o in objects)
    size = sum(os.path.getsize(os.path.join(libdir, s)) for s in vendored)
    needs = {"glibc": ".".join(map(str, glibc)), "glibcxx": ".".join(map(str, glibcxx)),
             "vendored": vendored, "vendored_bytes": size,
             "left_to_the_system": sorted(s for s in closure if SYSTEM.match(s))}
    with open(os.path.join(pkg, "_build_info.json")) as f:
        info = json.load(f)
    info["portable"] = needs
    with open(os.path.join(pkg, "_build_info.json"), "w") as f:
        json.dump(info, f, indent=1)
        f.write("\n")
    with open(os.path.join(libdir, "NEEDS.txt"), "w") as f:
        f.write(f"Python {info.get('python')} (the embedding Blender's), glibc >= {needs['glibc']}, "
                f"libstdc++ with GLIBCXX_{needs['glibcxx']}\n")

    with zipfile.ZipFile(dst, "w", zipfile.ZIP_DEFLATED) as zf:
        for root, dirs, files in os.walk(pkg):
            dirs[:] = sorted(dirs)
            for name in sorted(files):
                if name == "blender_manifest.toml":
                    continue   # the legacy form (top folder penumbra/), as penumbra-addon.zip
                full = os.path.join(root, name)
                zf.write(full, os.path.relpath(full, work))
    print(f"wrote {dst}: {len(vendored)} libraries vendored ({size / 1e6:.1f} MB unpacked, zip "
          f"{os.path.getsize(dst) / 1e6:.1f} MB); Python {info.get('python')}, needs glibc >= {needs['glibc']}, "
          f"GLIBCXX_{needs['glibcxx']}")


if __name__ == "__main__":
    main()

"""Zips the staged add-on folder in the two forms Blender installs:
    make_zip.py SRC legacy OUT     top folder = package, no manifest: Preferences > Add-ons > Install... (3.4-4.1,
                                   and the legacy path that 4.2+ still has)
    make_zip.py SRC extension OUT  package files at the top with blender_manifest.toml: Get Extensions >
                                   Install from Disk (4.2+)"""
import os
import sys
import zipfile

MANIFEST = "blender_manifest.toml"
if len(sys.argv) != 4 or sys.argv[2] not in ("legacy", "extension"):
    sys.exit("usage: make_zip.py STAGED_PACKAGE_DIR legacy|extension OUT.zip")
src, kind, dst = sys.argv[1], sys.argv[2], sys.argv[3]
if not os.path.isfile(os.path.join(src, "__init__.py")):
    sys.exit(f"make_zip.py: {src} is not a staged add-on package (no __init__.py)")
if kind == "extension" and not os.path.isfile(os.path.join(src, MANIFEST)):
    sys.exit(f"make_zip.py: {src} has no {MANIFEST}")
top = "" if kind == "extension" else os.path.basename(os.path.normpath(src))
with zipfile.ZipFile(dst, "w", zipfile.ZIP_DEFLATED) as zf:
    for root, dirs, files in os.walk(src):
        dirs[:] = sorted(d for d in dirs if d != "__pycache__")
        for name in sorted(files):
            rel = os.path.relpath(os.path.join(root, name), src)
            if kind == "legacy" and rel == MANIFEST:
                continue   # 4.2+ would otherwise take the legacy zip for an extension with a top folder
            zf.write(os.path.join(root, name), os.path.join(top, rel))
print("wrote", dst)

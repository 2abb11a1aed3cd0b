"""Zip the staged add-on folder so that Blender's "Install..." accepts it (top folder = package)."""
import os
import sys
import zipfile

src, dst = sys.argv[1], sys.argv[2]
top = os.path.basename(os.path.normpath(src))
with zipfile.ZipFile(dst, "w", zipfile.ZIP_DEFLATED) as zf:
    for root, dirs, files in os.walk(src):
        dirs[:] = [d for d in dirs if d != "__pycache__"]
        for name in sorted(files):
            path = os.path.join(root, name)
            zf.write(path, os.path.join(top, os.path.relpath(path, src)))
print("wrote", dst)

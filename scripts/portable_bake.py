"""Installs the portable zip the way a user does and bakes the example Cornell box with it (scripts/portable_root_check.sh
runs it inside a root that has Blender and none of the build packages):

    BLENDER_USER_SCRIPTS=<empty dir> blender -b --factory-startup --python-exit-code 1 \
        --python scripts/portable_bake.py -- PORTABLE.zip EXAMPLES_DIR OUT_DIR

Prints one line `PORTABLE-BAKE {json}`: the solver's counts, the lightmaps written, and, for every library in
penumbra/lib, whether the process mapped the zip's copy or a system copy (a library that Blender had loaded
before the add-on, under the same soname, is shared with it: the loader never loads a soname twice)."""
import json
import os
import sys

import addon_utils
import bpy

zip_path, examples, out = sys.argv[sys.argv.index("--") + 1:][:3]
assert bpy.ops.preferences.addon_install(filepath=zip_path, overwrite=True) == {"FINISHED"}
assert bpy.ops.preferences.addon_enable(module="penumbra") == {"FINISHED"}
import penumbra  # noqa: E402
assert addon_utils.check("penumbra") == (True, True)
pkg = os.path.dirname(os.path.realpath(penumbra.__file__))
assert pkg.startswith(os.path.realpath(os.environ["BLENDER_USER_SCRIPTS"])), pkg

sys.path.insert(0, examples)
import cornell_box  # noqa: E402
cornell_box.clear_scene()
cornell_box.build()
report = penumbra.bake(bpy.context.scene, resolution=256, output_dir=out)

vendored = set(os.listdir(os.path.join(pkg, "lib")))
mapped = {line.split()[-1] for line in open("/proc/self/maps") if ".so" in line.split()[-1]}
from_zip, from_system = set(), set()
for path in mapped:
    name = os.path.basename(path)
    if path.startswith(pkg + os.sep):
        from_zip.add(name)
    else:
        # A system copy of a vendored library is mapped under its real file name (libfoo.so.1.2.3), the zip's
        # under its soname (libfoo.so.1).
        for v in vendored:
            if name == v or name.startswith(v + "."):
                from_system.add(v)
print("PORTABLE-BAKE " + json.dumps({
    "blender": bpy.app.version_string, "python": sys.version.split()[0], "installed_in": pkg,
    "polygons": report.get("polygons"), "elements": report.get("elements"), "links": report.get("links"),
    "objects_baked": len(report.get("objects_baked", [])),
    "exr": sorted(os.path.basename(o["exr"]) for o in report["outputs"].values() if "exr" in o),
    "vendored": len(vendored - {"NEEDS.txt"}), "mapped_from_zip": sorted(from_zip),
    "mapped_from_system": sorted(from_system)}), flush=True)
print(penumbra.summary(report), flush=True)

"""The add-on zip installs through Preferences > Add-ons > Install... and enables, in a clean user folder."""
import os
import subprocess
import sys

import pytest

from conftest import REPO

SCRIPT = r"""
import os, sys, bpy, addon_utils
zip_path = sys.argv[sys.argv.index("--") + 1]
assert bpy.ops.preferences.addon_install(filepath=zip_path, overwrite=True) == {"FINISHED"}
assert bpy.ops.preferences.addon_enable(module="penumbra") == {"FINISHED"}
import penumbra
loaded, enabled = addon_utils.check("penumbra")
assert loaded and enabled, (loaded, enabled)
user = os.environ["BLENDER_USER_SCRIPTS"]
assert os.path.realpath(penumbra.__file__).startswith(os.path.realpath(user)), penumbra.__file__
assert hasattr(penumbra._native, "solve")
assert "penumbra.bake" not in dir(bpy.ops) or hasattr(bpy.ops.penumbra, "bake")
print("ZIP-OK", penumbra.__file__)
"""


def _zip_path():
    staged = os.environ.get("PENUMBRA_ADDON_DIR", "")
    for p in (os.path.join(os.path.dirname(staged.rstrip("/")), "penumbra-addon.zip") if staged else "",
              os.path.join(REPO, "build", "penumbra-addon.zip")):
        if p and os.path.isfile(p):
            return p
    pytest.fail("build/penumbra-addon.zip is missing: run bash scripts/build.sh")


def test_zip_installs_and_enables(tmp_path):
    script = tmp_path / "install.py"
    script.write_text(SCRIPT)
    env = dict(os.environ)
    # Set before Blender starts: Preferences' install copies into the user scripts folder.
    env["BLENDER_USER_SCRIPTS"] = str(tmp_path / "scripts")
    env["BLENDER_USER_CONFIG"] = str(tmp_path / "config")
    env.pop("PYTHONPATH", None)
    r = subprocess.run(["blender", "-b", "--factory-startup", "--python-exit-code", "1", "--python", str(script),
                        "--", _zip_path()], env=env, capture_output=True, text=True, timeout=120)
    assert r.returncode == 0 and "ZIP-OK" in r.stdout, r.stdout[-3000:] + r.stderr[-3000:]
    assert (tmp_path / "scripts" / "addons" / "penumbra" / "__init__.py").is_file()

"""The add-on zips install and enable in a clean user folder: the legacy one through Preferences > Add-ons >
Install... (every version), the extension one through Install from Disk (4.2+)."""
import os
import subprocess
import sys
import zipfile

import bpy
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


EXTENSION_SCRIPT = r"""
import os, sys, bpy
zip_path = sys.argv[sys.argv.index("--") + 1]
r = bpy.ops.extensions.package_install_files(filepath=zip_path, repo="user_default", enable_on_install=True)
assert r == {"FINISHED"}, r
import penumbra   # the alias __init__.py sets for the bl_ext.* package
assert penumbra.__name__ == "bl_ext.user_default.penumbra", penumbra.__name__
assert os.path.realpath(penumbra.__file__).startswith(os.path.realpath(os.environ["BLENDER_USER_EXTENSIONS"]))
assert hasattr(penumbra._native, "solve")
assert hasattr(bpy.ops.penumbra, "bake")
print("EXTENSION-OK", penumbra.__file__)
"""


def _zip_path(name="penumbra-addon.zip"):
    staged = os.environ.get("PENUMBRA_ADDON_DIR", "")
    for p in (os.path.join(os.path.dirname(staged.rstrip("/")), name) if staged else "",
              os.path.join(REPO, "build", name)):
        if p and os.path.isfile(p):
            return p
    pytest.fail(f"build/{name} is missing: run bash scripts/build.sh")


def test_legacy_zip_has_no_manifest_and_extension_zip_has_one():
    with zipfile.ZipFile(_zip_path()) as z:
        names = z.namelist()
    assert "penumbra/__init__.py" in names and not any(n.endswith("blender_manifest.toml") for n in names)
    with zipfile.ZipFile(_zip_path("penumbra-extension.zip")) as z:
        names = z.namelist()
        manifest = z.read("blender_manifest.toml").decode()
    assert "__init__.py" in names and any(n.startswith("_native") and n.endswith(".so") for n in names)
    assert 'id = "penumbra"' in manifest and 'blender_version_min = "4.2.0"' in manifest


@pytest.mark.skipif(bpy.app.version < (4, 2, 0), reason="extensions (blender_manifest.toml) start at Blender 4.2")
def test_extension_zip_installs_and_enables(tmp_path):
    script = tmp_path / "install.py"
    script.write_text(EXTENSION_SCRIPT)
    env = dict(os.environ)
    env["BLENDER_USER_SCRIPTS"] = str(tmp_path / "scripts")
    env["BLENDER_USER_CONFIG"] = str(tmp_path / "config")
    env["BLENDER_USER_EXTENSIONS"] = str(tmp_path / "extensions")
    env.pop("PYTHONPATH", None)
    r = subprocess.run(["blender", "-b", "--factory-startup", "--python-exit-code", "1", "--python", str(script),
                        "--", _zip_path("penumbra-extension.zip")], env=env, capture_output=True, text=True,
                       timeout=120)
    assert r.returncode == 0 and "EXTENSION-OK" in r.stdout, r.stdout[-3000:] + r.stderr[-3000:]
    assert (tmp_path / "extensions" / "user_default" / "penumbra" / "__init__.py").is_file()


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

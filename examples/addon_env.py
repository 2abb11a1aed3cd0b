"""Enables the Penumbra add-on inside `blender -b` for the example and benchmark scripts.

The add-on comes from $PENUMBRA_ADDON_DIR (default <repo>/build/addon, made by scripts/build.sh), or from the
folder a script is given.
"""
import os
import sys

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def enable_addon(prog, addon_dir=None):
    """Imports and enables the add-on; returns the `penumbra` module. Exits naming `prog` when it cannot."""
    import addon_utils
    addon_dir = addon_dir or os.environ.get("PENUMBRA_ADDON_DIR", os.path.join(REPO, "build", "addon"))
    if not os.path.isdir(os.path.join(addon_dir, "penumbra")):
        raise SystemExit(f"{prog}: no penumbra/ in {addon_dir}; run bash scripts/build.sh first")
    sys.path.insert(0, addon_dir)
    if addon_utils.enable("penumbra", default_set=True) is None:
        raise SystemExit(f"{prog}: the penumbra add-on failed to enable (see the error above)")
    import penumbra
    return penumbra

"""Run the add-on tests inside Blender:

    PENUMBRA_ADDON_DIR=$PWD/build/addon blender -b --factory-startup --python-exit-code 1 \
        --python blender_tests/run.py -- -q -p no:cacheprovider blender_tests

Enables the staged add-on (the folder holding penumbra/ with the compiled module), then hands the arguments
after `--` to pytest and exits with its status.
"""
import os
import sys

import addon_utils
import pytest

here = os.path.dirname(os.path.abspath(__file__))
addon_dir = os.environ.get("PENUMBRA_ADDON_DIR", os.path.join(os.path.dirname(here), "build", "addon"))
if not os.path.isdir(os.path.join(addon_dir, "penumbra")):
    sys.exit(f"blender_tests: no penumbra/ in PENUMBRA_ADDON_DIR={addon_dir}; run bash scripts/build.sh first")
sys.path.insert(0, addon_dir)
if addon_utils.enable("penumbra", default_set=True) is None:
    sys.exit("blender_tests: the penumbra add-on failed to enable (see the error above)")
args = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else [here]
sys.exit(pytest.main(args))

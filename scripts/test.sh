#!/usr/bin/env bash
# Every test: C++ unit tests (ctest), the native module under Debian's Python, and the add-on inside Blender.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/build.sh
BUILD=${PENUMBRA_BUILD_DIR:-build}
export PENUMBRA_ADDON_DIR="$PWD/$BUILD/addon"
echo "== C++ unit tests (ctest)"
(cd "$BUILD" && ctest --output-on-failure -j"$(nproc)")
echo "== native module tests (/usr/bin/python3 -m pytest)"
/usr/bin/python3 -m pytest -q -p no:cacheprovider native/python
echo "== add-on tests inside blender -b"
blender -b --factory-startup --python-exit-code 1 --python blender_tests/run.py -- -q -p no:cacheprovider blender_tests
/usr/bin/python3 -m pytest -q -p no:cacheprovider --noconftest blender_tests/ui   # the Bake button under Xvfb (blender_tests/ui/drive.py)

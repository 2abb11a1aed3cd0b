#!/usr/bin/env bash
# Every test: C++ unit tests (ctest), the native module under Debian's Python, and the add-on inside Blender;
# then, as root and unless PENUMBRA_SKIP_SID=1, all of it again in a Debian sid root (scripts/test_sid.sh).
set -euo pipefail
cd "$(dirname "$0")/.."
export PENUMBRA_WERROR=${PENUMBRA_WERROR:-ON}   # a warning in the native code fails CI
bash scripts/build.sh
BUILD=${PENUMBRA_BUILD_DIR:-build}
export PENUMBRA_ADDON_DIR="$PWD/$BUILD/addon"
echo "== C++ unit tests (ctest)"
(cd "$BUILD" && ctest --output-on-failure -j"$(nproc)")
if [ "${PENUMBRA_SKIP_ASAN:-0}" = 1 ]; then
  echo "== C++ unit tests under ASan + UBSan: skipped (PENUMBRA_SKIP_ASAN=1; the sid leg sets it, the host leg runs them)"
else
echo "== C++ unit tests under AddressSanitizer + UndefinedBehaviorSanitizer (build-asan)"
# Only penumbra_tests: the Python module under ASan would need the runtime preloaded into python.
# native/lsan.supp: FFTW's plan cache and Mesa's internals live until exit by design.
ASAN_BUILD=${PENUMBRA_ASAN_BUILD_DIR:-build-asan}
ROOT=$PWD
if [ ! -f "$ASAN_BUILD/CMakeCache.txt" ]; then
  cmake -S . -B "$ASAN_BUILD" -DPENUMBRA_SANITIZE=ON -DCMAKE_BUILD_TYPE=RelWithDebInfo \
    -DPython_EXECUTABLE="$(cat "$BUILD/python_executable.txt")"
fi
cmake -S . -B "$ASAN_BUILD" -DPENUMBRA_WERROR="$PENUMBRA_WERROR" > /dev/null
cmake --build "$ASAN_BUILD" --target penumbra_tests -j"$(nproc)"
(cd "$ASAN_BUILD" &&
  ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 \
  LSAN_OPTIONS=suppressions="$ROOT/native/lsan.supp" \
  UBSAN_OPTIONS=halt_on_error=1:print_stacktrace=1 \
  ctest --output-on-failure -j"$(nproc)")
fi
# The interpreter the module was built for (the one Blender embeds), not the python3 first on PATH.
PY=$(cat "$BUILD/python_executable.txt")
echo "== native module tests ($PY -m pytest)"
"$PY" -m pytest -q -p no:cacheprovider native/python
echo "== add-on tests inside blender -b"
blender -b --factory-startup --python-exit-code 1 --python blender_tests/run.py -- -q -p no:cacheprovider blender_tests
"$PY" -m pytest -q -p no:cacheprovider --noconftest blender_tests/ui   # the Bake button under Xvfb (blender_tests/ui/drive.py)
if [ "${PENUMBRA_SKIP_SID:-0}" != 1 ]; then
  echo "== the same tests in a Debian sid root, Blender 5.x (scripts/test_sid.sh; PENUMBRA_SKIP_SID=1 skips)"
  bash scripts/test_sid.sh
fi

#!/usr/bin/env bash
# Every test: C++ unit tests (ctest), the native module under Debian's Python, and the add-on inside Blender;
# then, as root and unless PENUMBRA_SKIP_SID=1, all of it again in a Debian sid root (scripts/test_sid.sh).
set -euo pipefail
cd "$(dirname "$0")/.."
export PENUMBRA_WERROR=${PENUMBRA_WERROR:-ON}   # a warning in the native code fails CI
bash scripts/build.sh
BUILD=${PENUMBRA_BUILD_DIR:-build}
export PENUMBRA_ADDON_DIR="$PWD/$BUILD/addon"
ASAN_PID=""
if [ "${PENUMBRA_SKIP_ASAN:-0}" = 1 ]; then
  echo "== C++ unit tests under ASan + UBSan: skipped (PENUMBRA_SKIP_ASAN=1; the sid leg sets it, the host leg runs them)"
else
# Only penumbra_tests: the Python module under ASan would need the runtime preloaded into python.
# native/lsan.supp: FFTW's plan cache and Mesa's internals live until exit by design.
ASAN_BUILD=${PENUMBRA_ASAN_BUILD_DIR:-build-asan}
ROOT=$PWD
asan_tests() {
  if [ ! -f "$ASAN_BUILD/CMakeCache.txt" ]; then
    cmake -S . -B "$ASAN_BUILD" -DPENUMBRA_SANITIZE=ON -DCMAKE_BUILD_TYPE=RelWithDebInfo \
      -DPython_EXECUTABLE="$(cat "$BUILD/python_executable.txt")"
  fi
  cmake -S . -B "$ASAN_BUILD" -DPENUMBRA_WERROR="$PENUMBRA_WERROR" > /dev/null
  cmake --build "$ASAN_BUILD" --target penumbra_tests -j"$(nproc)"
  cd "$ASAN_BUILD" &&
    ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 \
    LSAN_OPTIONS=suppressions="$ROOT/native/lsan.supp" \
    UBSAN_OPTIONS=halt_on_error=1:print_stacktrace=1 \
    ctest --output-on-failure -j"$(nproc)"
}
# Built and run in the background, beside the release ctest and the native and Blender tests, which leave a
# core idle for much of their time (one Python thread between solves, Blender's start-up, export and
# write-back); its output goes to a log that is printed if it fails. PENUMBRA_SERIAL_ASAN=1 runs it here in the foreground as before.
if [ "${PENUMBRA_SERIAL_ASAN:-0}" = 1 ]; then
  echo "== C++ unit tests under AddressSanitizer + UndefinedBehaviorSanitizer ($ASAN_BUILD)"
  (asan_tests)
else
  mkdir -p "$ASAN_BUILD"
  ASAN_LOG="$ASAN_BUILD/background-run.log"
  echo "== C++ unit tests under AddressSanitizer + UndefinedBehaviorSanitizer ($ASAN_BUILD): started in the background, log $ASAN_LOG"
  # Its own process group (setsid), so that a failure below stops the whole build-and-ctest, not just its shell.
  setsid bash -c "$(declare -f asan_tests); set -euo pipefail; BUILD='$BUILD' ASAN_BUILD='$ASAN_BUILD' ROOT='$ROOT' \
    PENUMBRA_WERROR='$PENUMBRA_WERROR'; asan_tests" > "$ASAN_LOG" 2>&1 &
  ASAN_PID=$!
  trap 'kill -- -"$ASAN_PID" 2>/dev/null || true' EXIT
fi
fi
echo "== C++ unit tests (ctest)"
(cd "$BUILD" && ctest --output-on-failure -j"$(nproc)")
# The interpreter the module was built for (the one Blender embeds), not the python3 first on PATH.
PY=$(cat "$BUILD/python_executable.txt")
echo "== native module tests ($PY -m pytest)"
"$PY" -m pytest -q -p no:cacheprovider native/python
echo "== add-on tests inside blender -b"
blender -b --factory-startup --python-exit-code 1 --python blender_tests/run.py -- -q -p no:cacheprovider blender_tests
if [ -n "$ASAN_PID" ]; then
  # Before the Xvfb test, whose window latencies are measured and should not share the cores with it.
  echo "== C++ unit tests under ASan + UBSan: waiting for the background run (log $ASAN_LOG)"
  asan_status=0
  wait "$ASAN_PID" || asan_status=$?
  trap - EXIT
  if [ "$asan_status" != 0 ]; then
    cat "$ASAN_LOG"
    echo "== ASan + UBSan build or ctest failed (exit $asan_status)"
    exit "$asan_status"
  fi
  grep -E "tests passed|Total Test time" "$ASAN_LOG"
fi
"$PY" -m pytest -q -p no:cacheprovider --noconftest blender_tests/ui   # the Bake button under Xvfb (blender_tests/ui/drive.py)
if [ "${PENUMBRA_SKIP_SID:-0}" != 1 ]; then
  echo "== the same tests in a Debian sid root, Blender 5.x (scripts/test_sid.sh; PENUMBRA_SKIP_SID=1 skips)"
  bash scripts/test_sid.sh
fi

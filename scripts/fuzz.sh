#!/usr/bin/env bash
# Fuzzes penumbra::solve with libFuzzer (clang, ASan + UBSan) for a bounded time. Not part of CI: CI
# replays what this finds (native/fuzz/regressions/, via penumbra_tests).
#   bash scripts/fuzz.sh [seconds=90]
# The core library is built with clang in build-fuzz/ with coverage instrumentation; crashing inputs are
# copied to native/fuzz/regressions/ (commit them with the fix), the growing corpus stays in build-fuzz/.
set -euo pipefail
cd "$(dirname "$0")/.."
SECONDS_TO_RUN=${1:-90}
need=()
for p in clang-14 libclang-rt-14-dev; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || need+=("$p")
done
if [ ${#need[@]} -gt 0 ]; then
  SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  $SUDO apt-get update -q
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -q --no-install-recommends "${need[@]}"
fi
bash scripts/deps.sh
OUT=build-fuzz
SAN="-fsanitize=address,undefined -fno-sanitize-recover=undefined -fno-omit-frame-pointer -g"
if [ ! -f "$OUT/CMakeCache.txt" ]; then
  cmake -S . -B "$OUT" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_COMPILER=clang++-14 \
    -DPython_EXECUTABLE=/usr/bin/python3.11 -DPENUMBRA_TESTS=OFF \
    -DCMAKE_CXX_FLAGS="-fsanitize=fuzzer-no-link $SAN"
fi
cmake --build "$OUT" --target penumbra_core -j"$(nproc)"
# shellcheck disable=SC2046
clang++-14 -std=c++17 -O1 $SAN -fsanitize=fuzzer -Inative/src native/fuzz/fuzz_scene.cpp \
  "$OUT/libpenumbra_core.a" -lembree3 $(pkg-config --libs fftw3f osmesa OpenImageIO) -lpthread \
  -o "$OUT/fuzz_scene"
mkdir -p "$OUT/corpus" "$OUT/crashes"
# Seed with the saved inputs, so a session starts where the last one (and its regressions) left off.
cp -n native/fuzz/regressions/* "$OUT/corpus/" 2>/dev/null || true
export ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=halt_on_error=1:print_stacktrace=1
export LSAN_OPTIONS=suppressions=$PWD/native/lsan.supp
set +e
"$OUT/fuzz_scene" -max_total_time="$SECONDS_TO_RUN" -max_len=4096 -timeout=20 -rss_limit_mb=4096 \
  -artifact_prefix="$OUT/crashes/" -print_final_stats=1 "$OUT/corpus" 2>&1 | tee "$OUT/fuzz.log" | tail -40
status=${PIPESTATUS[0]}
set -e
found=0
for f in "$OUT"/crashes/*; do
  [ -e "$f" ] || continue
  cp "$f" native/fuzz/regressions/ && found=$((found + 1))
done
echo "fuzz: exit $status, $found crashing input(s) copied to native/fuzz/regressions/ (log: $OUT/fuzz.log)"
exit "$status"

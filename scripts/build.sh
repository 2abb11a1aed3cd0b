#!/usr/bin/env bash
# Configures (once) and builds the native library, the Python module, the staged add-on and the zip.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/deps.sh
BUILD=${PENUMBRA_BUILD_DIR:-build}
# CMakeLists.txt asks the installed Blender which Python it embeds and builds the module for that one.
if [ ! -f "$BUILD/CMakeCache.txt" ]; then
  cmake -S . -B "$BUILD" -DCMAKE_BUILD_TYPE=Release ${PENUMBRA_CMAKE_ARGS:-}
fi
# PENUMBRA_WERROR=ON|OFF (scripts/test.sh sets ON) is applied to an existing build directory too.
if [ -n "${PENUMBRA_WERROR:-}" ]; then
  cmake -S . -B "$BUILD" -DPENUMBRA_WERROR="$PENUMBRA_WERROR" > /dev/null
fi
cmake --build "$BUILD" -j"$(nproc)"
cmake --build "$BUILD" --target addon_zip

#!/usr/bin/env bash
# The main job: build, then bake the example Cornell box headless.
#   bash scripts/bake_example.sh [OUTPUT_DIR]      (default out/cornell)
# Writes the lightmaps (EXR), the baked .blend, a PNG rendered with the bake shown, report.json,
# and prints a one-line summary.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/build.sh
BUILD=${PENUMBRA_BUILD_DIR:-build}
OUT=${1:-out/cornell}
export PENUMBRA_ADDON_DIR="$PWD/$BUILD/addon"
blender -b --factory-startup --python-exit-code 1 --python examples/bake_cornell.py -- --out "$OUT" 2>&1 \
  | grep -v -e '^Fra:' -e 'EGL Error' || { echo "bake_example: the bake failed" >&2; exit 1; }

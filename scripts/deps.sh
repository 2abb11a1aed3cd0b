#!/usr/bin/env bash
# Installs the Debian packages Penumbra needs, only those that are missing (a second run is instant).
set -euo pipefail
PKGS=(cmake g++ make pkg-config blender
      libfftw3-dev libosmesa6-dev libopenimageio-dev libembree-dev libtbb-dev libgtest-dev
      pybind11-dev python3-dev python3-pybind11 python3-numpy python3-pytest python3-matplotlib
      python3-openimageio xvfb xauth)
missing=()
for p in "${PKGS[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "penumbra: installing ${missing[*]}" >&2
  SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  $SUDO apt-get update -q
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -q --no-install-recommends "${missing[@]}"
fi

#!/usr/bin/env bash
# Installs the Debian packages Penumbra needs, only those that are missing (a second run is instant).
# Debian 12 (bookworm), 13 (trixie) and sid: the names are the same except OSMesa, which Mesa dropped in 25.1
# (sid has no libosmesa6-dev). The build uses it only for the optional GL rasterizer, so outside bookworm it is
# installed when the archive still has it and skipped otherwise.
set -euo pipefail
PKGS=(cmake g++ make pkg-config blender
      libfftw3-dev libopenimageio-dev libembree-dev libtbb-dev libgtest-dev
      pybind11-dev python3-dev python3-pybind11 python3-numpy python3-pytest python3-matplotlib
      python3-openimageio xvfb xauth
      patchelf)   # scripts/portable_zip.py: the relative run path of the vendored libraries
OPTIONAL=()
SUITE=unknown
if [ -r /etc/os-release ]; then
  SUITE=$(. /etc/os-release; echo "${VERSION_CODENAME:-unknown}")
  # sid's os-release names trixie/forky or nothing; its apt lists say "sid" either way.
  if [ -z "$SUITE" ] || [ "$SUITE" = unknown ] || grep -qs '^PRETTY_NAME=.*sid' /etc/os-release; then
    SUITE=sid
  fi
fi
case "$SUITE" in
  bookworm) PKGS+=(libosmesa6-dev) ;;   # Debian 12 as it always was: OSMesa required
  *) OPTIONAL+=(libosmesa6-dev) ;;
esac

installed() { dpkg-query -W -f='${Status}' "$1" 2>/dev/null | grep -q "install ok installed"; }
available() { [ -n "$(apt-cache policy "$1" 2>/dev/null | awk '/Candidate:/ {print $2}' | grep -v '(none)')" ]; }

missing=()
for p in "${PKGS[@]}"; do installed "$p" || missing+=("$p"); done
SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo"
updated=0
if [ ${#missing[@]} -gt 0 ]; then
  $SUDO apt-get update -q
  updated=1
fi
for p in "${OPTIONAL[@]}"; do
  installed "$p" && continue
  if available "$p"; then
    missing+=("$p")
  elif [ "$updated" = 1 ]; then
    echo "penumbra: $p is not in Debian $SUITE; building without it (the span rasterizer is the default)" >&2
  fi
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "penumbra: installing on Debian $SUITE: ${missing[*]}" >&2
  [ "$updated" = 1 ] || $SUDO apt-get update -q
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -q --no-install-recommends "${missing[@]}"
fi

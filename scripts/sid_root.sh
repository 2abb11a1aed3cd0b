#!/usr/bin/env bash
# Makes sure a Debian root of suite $PENUMBRA_SUITE (default sid: Blender 5.x) with Blender and the build packages
# exists and prints its path: /var/cache/penumbra/<suite>-root unless PENUMBRA_ROOT (or, for sid,
# PENUMBRA_SID_ROOT) says otherwise. A root that is present and passes the health check is reused as it is (a CI
# machine keeps it between runs); one that is absent, half-made or broken is made anew.
# PENUMBRA_ROOT_PACKAGES="blender ..." installs only those packages instead of scripts/deps.sh's list: the
# portable-zip check (scripts/portable_check.sh) wants a root with Blender but none of the build packages.
# Needs root and debootstrap (installed here when missing).
set -euo pipefail
cd "$(dirname "$0")/.."
SUITE=${PENUMBRA_SUITE:-sid}
if [ "$SUITE" = sid ]; then
  ROOT=${PENUMBRA_ROOT:-${PENUMBRA_SID_ROOT:-/var/cache/penumbra/sid-root}}
else
  ROOT=${PENUMBRA_ROOT:-/var/cache/penumbra/$SUITE-root}
fi
PACKAGES=${PENUMBRA_ROOT_PACKAGES:-}
# Bumped when the set of packages the root must hold changes, so an old cached root is made anew. A root with
# its own package list records the list too, so it is never taken for a build root or the other way round.
STAMP_VERSION=1
STAMP=$STAMP_VERSION${PACKAGES:+ packages: $PACKAGES}

if [ "$(id -u)" -ne 0 ]; then
  echo "penumbra: the $SUITE root needs root (debootstrap, chroot, mount); run as root or set PENUMBRA_SKIP_SID=1" >&2
  exit 1
fi

# Same mirror as the host's own apt sources, so a machine behind a local mirror uses it for sid too.
mirror() {
  local m=""
  if [ -n "${PENUMBRA_SID_MIRROR:-}" ]; then echo "$PENUMBRA_SID_MIRROR"; return; fi
  m=$(cat /etc/apt/sources.list /etc/apt/sources.list.d/*.list /etc/apt/sources.list.d/*.sources 2>/dev/null |
      grep -oE '(https?)://[^ ]+/debian/?( |$)' | grep -v security | head -n1 | tr -d ' ' || true)
  echo "${m:-http://deb.debian.org/debian}"
}

healthy() {
  [ -f "$ROOT/.penumbra-ready" ] &&
  [ "$(cat "$ROOT/.penumbra-ready")" = "$STAMP" ] &&
  [ -x "$ROOT/usr/bin/blender" ] &&
  chroot "$ROOT" /usr/bin/env -i PATH=/usr/sbin:/usr/bin:/sbin:/bin \
    /usr/bin/dpkg-query -W ${PACKAGES:-blender cmake g++} >/dev/null 2>&1
}

# Anything still mounted inside (a run killed before its trap) would be deleted through the bind mount.
unmount_all() {
  local m
  for m in $(awk -v r="$1" 'index($2, r) == 1 {print $2}' /proc/mounts | sort -r); do
    umount -l "$m" 2>/dev/null || true
  done
}

if healthy; then
  echo "$ROOT"
  exit 0
fi

command -v debootstrap >/dev/null || {
  echo "penumbra: installing debootstrap" >&2
  apt-get update -q >&2 && DEBIAN_FRONTEND=noninteractive apt-get install -y -q debootstrap >&2
}

MIRROR=$(mirror)
start=$(date +%s)
echo "penumbra: making the Debian $SUITE root $ROOT from $MIRROR (absent or unhealthy)" >&2
TMP_ROOT="$ROOT.new"
for r in "$ROOT" "$TMP_ROOT"; do
  unmount_all "$r"
  rm -rf --one-file-system "$r"
done
mkdir -p "$(dirname "$ROOT")"
debootstrap --variant=minbase "$SUITE" "$TMP_ROOT" "$MIRROR" >&2
# sid's Release file can carry a Valid-Until earlier than a mirror snapshot's date; apt-get update then fails.
echo 'Acquire::Check-Valid-Until "false";' > "$TMP_ROOT/etc/apt/apt.conf.d/99penumbra-no-valid-until"
cp /etc/resolv.conf "$TMP_ROOT/etc/resolv.conf"
mkdir -p "$TMP_ROOT/penumbra"
cp scripts/deps.sh "$TMP_ROOT/penumbra/deps.sh"
mount -t proc proc "$TMP_ROOT/proc"
trap 'umount -l "$TMP_ROOT/proc" 2>/dev/null || true' EXIT
if [ -n "$PACKAGES" ]; then
  # --no-install-recommends: what a user's `apt-get install blender` needs at least, and nothing to build with.
  chroot "$TMP_ROOT" /usr/bin/env -i HOME=/root PATH=/usr/sbin:/usr/bin:/sbin:/bin LANG=C.UTF-8 \
    DEBIAN_FRONTEND=noninteractive bash -c "apt-get update -q && apt-get install -y -q --no-install-recommends $PACKAGES" >&2
else
  chroot "$TMP_ROOT" /usr/bin/env -i HOME=/root PATH=/usr/sbin:/usr/bin:/sbin:/bin LANG=C.UTF-8 \
    bash /penumbra/deps.sh >&2
fi
chroot "$TMP_ROOT" apt-get clean >&2
umount -l "$TMP_ROOT/proc"
trap - EXIT
echo "$STAMP" > "$TMP_ROOT/.penumbra-ready"
mv "$TMP_ROOT" "$ROOT"
echo "penumbra: $SUITE root ready in $(( $(date +%s) - start )) s" >&2
echo "$ROOT"

#!/usr/bin/env bash
# Makes sure a Debian sid root with Blender 5.x and the build packages exists at $PENUMBRA_SID_ROOT
# (default /var/cache/penumbra/sid-root) and prints its path. A root that is present and passes the health check
# is reused as it is (a CI machine keeps it between runs); one that is absent, half-made or broken is made anew.
# Needs root and debootstrap (installed here when missing).
set -euo pipefail
cd "$(dirname "$0")/.."
SID_ROOT=${PENUMBRA_SID_ROOT:-/var/cache/penumbra/sid-root}
# Bumped when the set of packages the root must hold changes, so an old cached root is made anew.
STAMP_VERSION=1

if [ "$(id -u)" -ne 0 ]; then
  echo "penumbra: the sid root needs root (debootstrap, chroot, mount); run as root or set PENUMBRA_SKIP_SID=1" >&2
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
  [ -f "$SID_ROOT/.penumbra-ready" ] &&
  [ "$(cat "$SID_ROOT/.penumbra-ready")" = "$STAMP_VERSION" ] &&
  [ -x "$SID_ROOT/usr/bin/blender" ] &&
  chroot "$SID_ROOT" /usr/bin/env -i PATH=/usr/sbin:/usr/bin:/sbin:/bin \
    /usr/bin/dpkg-query -W blender cmake g++ >/dev/null 2>&1
}

# Anything still mounted inside (a run killed before its trap) would be deleted through the bind mount.
unmount_all() {
  local m
  for m in $(awk -v r="$1" 'index($2, r) == 1 {print $2}' /proc/mounts | sort -r); do
    umount -l "$m" 2>/dev/null || true
  done
}

if healthy; then
  echo "$SID_ROOT"
  exit 0
fi

command -v debootstrap >/dev/null || {
  echo "penumbra: installing debootstrap" >&2
  apt-get update -q >&2 && DEBIAN_FRONTEND=noninteractive apt-get install -y -q debootstrap >&2
}

MIRROR=$(mirror)
start=$(date +%s)
echo "penumbra: making the Debian sid root $SID_ROOT from $MIRROR (absent or unhealthy)" >&2
TMP_ROOT="$SID_ROOT.new"
for r in "$SID_ROOT" "$TMP_ROOT"; do
  unmount_all "$r"
  rm -rf --one-file-system "$r"
done
mkdir -p "$(dirname "$SID_ROOT")"
debootstrap --variant=minbase sid "$TMP_ROOT" "$MIRROR" >&2
# sid's Release file can carry a Valid-Until earlier than a mirror snapshot's date; apt-get update then fails.
echo 'Acquire::Check-Valid-Until "false";' > "$TMP_ROOT/etc/apt/apt.conf.d/99penumbra-no-valid-until"
cp /etc/resolv.conf "$TMP_ROOT/etc/resolv.conf"
mkdir -p "$TMP_ROOT/penumbra"
cp scripts/deps.sh "$TMP_ROOT/penumbra/deps.sh"
mount -t proc proc "$TMP_ROOT/proc"
trap 'umount -l "$TMP_ROOT/proc" 2>/dev/null || true' EXIT
chroot "$TMP_ROOT" /usr/bin/env -i HOME=/root PATH=/usr/sbin:/usr/bin:/sbin:/bin LANG=C.UTF-8 \
  bash /penumbra/deps.sh >&2
chroot "$TMP_ROOT" apt-get clean >&2
umount -l "$TMP_ROOT/proc"
trap - EXIT
echo "$STAMP_VERSION" > "$TMP_ROOT/.penumbra-ready"
mv "$TMP_ROOT" "$SID_ROOT"
echo "penumbra: sid root ready in $(( $(date +%s) - start )) s" >&2
echo "$SID_ROOT"

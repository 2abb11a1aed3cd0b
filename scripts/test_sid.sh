#!/usr/bin/env bash
# The sid leg of scripts/test.sh: every test, then the main job, again inside a Debian sid root (Blender 5.x, Python 3.14, Embree 4,
# OpenImageIO 3, no OSMesa). The root is made or reused by scripts/sid_root.sh; this work tree is copied into
# it (its build directories there are kept, so a reused root builds incrementally) and scripts/test.sh runs
# inside it under chroot. Its exit code is this script's. The ASan + UBSan ctest pass is left to the host leg
# (same sources; under load it took over 10 minutes here, which would put .ci/run past 45 minutes on a fresh
# machine); PENUMBRA_SID_ASAN=1 runs it in sid too.
# PENUMBRA_SUITE=trixie runs the same leg in a Debian 13 root (Blender 4.3.2) instead; CI does not (its time
# budget), this is the one command for it.
set -euo pipefail
cd "$(dirname "$0")/.."
start=$(date +%s)
SUITE=${PENUMBRA_SUITE:-sid}
export PENUMBRA_SUITE=$SUITE
SID_ROOT=$(bash scripts/sid_root.sh)
echo "== $SUITE leg: root $SID_ROOT ready after $(( $(date +%s) - start )) s"
SRC=/penumbra/src
DEST="$SID_ROOT$SRC"
mkdir -p "$DEST"
# Stale sources must go (the build globs native/src), the root's own build directories stay.
find "$DEST" -mindepth 1 -maxdepth 1 ! -name build ! -name build-asan -exec rm -rf {} +
tar -C . --exclude=./.git --exclude=./build --exclude='./build-*' --exclude=./out --exclude=./bench/cache \
  -cf - . | tar -C "$DEST" -xf -
cp /etc/resolv.conf "$SID_ROOT/etc/resolv.conf"   # deps.sh inside may still install a package

mounted=()
cleanup() {
  local i
  for (( i=${#mounted[@]}-1; i>=0; i-- )); do
    umount -R "${mounted[$i]}" 2>/dev/null || umount -l "${mounted[$i]}" 2>/dev/null || true
  done
}
trap cleanup EXIT
trap 'exit 143' INT TERM   # so a killed run still unmounts (the EXIT trap runs)
bind() {   # bind SOURCE TARGET-IN-ROOT
  mkdir -p "$SID_ROOT$2"
  mount --rbind "$1" "$SID_ROOT$2"
  mount --make-rslave "$SID_ROOT$2"
  mounted+=("$SID_ROOT$2")
}
mount -t proc proc "$SID_ROOT/proc"; mounted+=("$SID_ROOT/proc")
bind /sys /sys
bind /dev /dev
mount -t tmpfs tmpfs "$SID_ROOT/tmp"; mounted+=("$SID_ROOT/tmp")

set +e
chroot "$SID_ROOT" /usr/bin/env -i HOME=/root LANG=C.UTF-8 TERM="${TERM:-dumb}" CI="${CI:-}" \
  PATH=/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin PENUMBRA_SKIP_SID=1 PENUMBRA_SKIP_PORTABLE=1 \
  PENUMBRA_SKIP_ASAN="$([ "${PENUMBRA_SID_ASAN:-0}" = 1 ] && echo 0 || echo 1)" \
  bash -c "cd $SRC && bash scripts/test.sh && echo '== $SUITE leg: the main job (scripts/bake_example.sh)' &&
           bash scripts/bake_example.sh /tmp/cornell"
status=$?
set -e
echo "== $SUITE leg: exit $status after $(( $(date +%s) - start )) s"
exit "$status"

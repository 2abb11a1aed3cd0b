#!/usr/bin/env bash
# Runs the portable zip (build/penumbra-addon-portable.zip, scripts/portable_zip.py) where no build package and
# none of its libraries' system copies exist: a Debian 12 root with only `apt-get install --no-install-recommends
# blender python3-numpy` (Debian's Blender does not depend on numpy, the add-on needs it; a blender.org build
# bundles it) (made once by scripts/sid_root.sh at /var/cache/penumbra/bookworm-blender-root, about 2 GB; reused).
# Not part of CI (making the root takes minutes); one command, as root:
#     bash scripts/portable_root_check.sh [PORTABLE.zip]
# Everything runs in a private mount namespace (unshare -m), so its mounts go when it ends, even if killed.
#  1. No -dev package in the root.
#  2. Every library of the zip that the root has at all is covered by an empty file (/dev/null bound over it),
#     so a load of a system copy fails; Debian's python3.11 (the one Blender links; the same minor version as
#     a blender.org 4.x build's) then runs scripts/portable_check.py on the zip: import, solve, EXR, FFT, OSMesa.
#  3. A real headless bake with Blender: the zip installed through Preferences > Install in an empty user
#     folder, the example Cornell box baked. Blender itself needs some of the same libraries (OpenImageIO,
#     Embree, TBB, ...); only those are left visible, and the script reports which copy the process mapped.
set -euo pipefail

# The checks themselves, in the private mount namespace (the script runs itself again under unshare; its stdin
# is /dev/null so that no command inside can read anything meant for the shell).
inner() {
ROOT=$1 CHECK=$2
mount -t proc proc "$ROOT/proc"
mount --rbind /dev "$ROOT/dev"
mount -t tmpfs tmpfs "$ROOT/tmp"
in_root() { chroot "$ROOT" /usr/bin/env -i PATH=/usr/bin:/bin HOME=/tmp LANG=C.UTF-8 "$@"; }

echo "== 1. build packages in the root"
dev=$(in_root dpkg-query -W -f '${Package}\n' | grep -E -- '-dev$|^(cmake|g\+\+|gcc|make|patchelf)$' || true)
[ -z "$dev" ] || { echo "the root has build packages: $dev"; exit 1; }
echo "none (dpkg: $(in_root dpkg-query -W -f '${Package}\n' | wc -l) packages, blender $(in_root dpkg-query -W -f '${Version}' blender))"

# The root's own copies of the zip's libraries: every file the loader would find under that soname.
system_copies() {   # system_copies SONAME...
  local s
  for s in "$@"; do
    in_root /sbin/ldconfig -p | awk -v s="$s" '$1 == s {print $NF}'
  done | while read -r f; do in_root readlink -f "$f"; done | sort -u
}
hide() {   # hide FILE...: bind an empty file over each (real files inside the root, no symlinks)
  local f
  for f in "$@"; do mount --bind /dev/null "$ROOT$f"; done
}
mapfile -t vendored < "$ROOT$CHECK/vendored.txt"
mapfile -t present < <(system_copies "${vendored[@]}")
echo "the zip vendors ${#vendored[@]} libraries; the root has system copies of ${#present[@]} of them (Blender's dependencies)"

echo "== 2. the module alone with every system copy hidden (python3.11, scripts/portable_check.py)"
# Except those that the interpreter and numpy map before the module is imported (libz, libexpat, BLAS, ...):
# they belong to the process that loads the add-on, as Blender's own libraries do in 3.
mapfile -t interp < <(in_root python3.11 -c "import numpy, numpy.linalg
print('\n'.join(sorted({l.split()[-1] for l in open('/proc/self/maps') if '.so' in l.split()[-1]})))" |
  while read -r f; do in_root readlink -f "$f"; done | sort -u)
# Membership through an associative array: `printf | grep -q` under pipefail fails at random (grep exits at
# the first match, printf gets SIGPIPE).
declare -A in_interp=() in_blender=()
for f in "${interp[@]}"; do in_interp[$f]=1; done
hidden=()
for f in "${present[@]}"; do
  [ -n "${in_interp[$f]:-}" ] || hidden+=("$f")
done
echo "of the system copies, $(( ${#present[@]} - ${#hidden[@]} )) stay visible because python3.11 and numpy map them before the import; ${#hidden[@]} are hidden"
if [ "${PENUMBRA_PORTABLE_BAKE_ONLY:-0}" != 1 ]; then   # 1 skips 2 (about 3 min here) when 3 is what is wanted
# In a nested mount namespace, so that the covers go when it ends and step 3 starts from the root as it is.
unshare -m --propagation private bash -c '
  set -euo pipefail
  ROOT=$1 CHECK=$2; shift 2
  for f; do mount --bind /dev/null "$ROOT$f"; done
  run() { chroot "$ROOT" /usr/bin/env -i PATH=/usr/bin:/bin HOME=/tmp LANG=C.UTF-8 "$@"; }
  run python3.11 "$CHECK/portable_check.py" "$CHECK/penumbra-addon-portable.zip"
  # Proof that the hiding bites: a system copy that is still wanted now fails to load.
  run python3.11 -c "import ctypes; ctypes.CDLL(\"$1\")" 2>/dev/null &&
    { echo "hiding did not work: $1 still loads"; exit 1; }
  echo "(control: loading the hidden $1 fails, as it should)"
' _ "$ROOT" "$CHECK" "${hidden[@]}" < /dev/null

fi
echo "== 3. a real headless bake: the zip installed in an empty user folder, the Cornell box baked"
# The real files Blender's own closure maps (a soname and its file's name can differ: libopenjp2.so.7 is
# libopenjp2.so.2.5.0).
mapfile -t blender_needs < <(in_root /lib64/ld-linux-x86-64.so.2 --list /usr/bin/blender |
  awk '$2 == "=>" {print $3}' | while read -r f; do in_root readlink -f "$f"; done | sort -u)
for f in "${blender_needs[@]}"; do in_blender[$f]=1; done
keep=() drop=()
for f in "${present[@]}"; do
  # numpy's libraries too: Blender's Python imports it before the add-on
  if [ -n "${in_blender[$f]:-}" ] || [ -n "${in_interp[$f]:-}" ]; then keep+=("$f"); else drop+=("$f"); fi
done
echo "Blender's own closure: ${#blender_needs[@]} files; of the system copies, ${#keep[@]} stay visible because Blender itself links them (or numpy maps them); ${#drop[@]} are hidden: ${drop[*]##*/}"
hide "${drop[@]}"
mkdir -p "$ROOT/tmp/user" "$ROOT/tmp/out"
status=0
in_root env BLENDER_USER_SCRIPTS=/tmp/user BLENDER_USER_CONFIG=/tmp/config \
  blender -b --factory-startup --python-exit-code 1 --python "$CHECK/portable_bake.py" -- \
  "$CHECK/penumbra-addon-portable.zip" "$CHECK/examples" /tmp/out > "$ROOT/tmp/bake.log" 2>&1 || status=$?
if [ "$status" != 0 ]; then tail -n 40 "$ROOT/tmp/bake.log"; echo "the bake failed (exit $status)"; exit 1; fi
grep -E '^(PORTABLE-BAKE|Penumbra:)' "$ROOT/tmp/bake.log"
compgen -G "$ROOT/tmp/out/*.exr" > /dev/null || { echo "the bake wrote no lightmap"; exit 1; }
echo "== portable root check: ok"
}
if [ "${1:-}" = --inner ]; then
  inner "$2" "$3"
  exit
fi
SELF=$(realpath "$0")
cd "$(dirname "$0")/.."
ZIP=$(realpath "${1:-build/penumbra-addon-portable.zip}")
[ -f "$ZIP" ] || { echo "no $ZIP: build it with cmake --build build --target portable_zip" >&2; exit 1; }
ROOT=$(PENUMBRA_SUITE=bookworm PENUMBRA_ROOT=${PENUMBRA_PORTABLE_ROOT:-/var/cache/penumbra/bookworm-blender-root} \
       PENUMBRA_ROOT_PACKAGES='blender python3-numpy' bash scripts/sid_root.sh)
CHECK=/penumbra-portable-check
rm -rf "$ROOT$CHECK"
mkdir -p "$ROOT$CHECK/examples"
cp "$ZIP" "$ROOT$CHECK/penumbra-addon-portable.zip"
cp scripts/portable_check.py scripts/portable_zip.py scripts/portable_bake.py "$ROOT$CHECK/"
cp examples/cornell_box.py "$ROOT$CHECK/examples/"
/usr/bin/python3 -c 'import sys, zipfile; print("\n".join(n[len("penumbra/lib/"):] for n in zipfile.ZipFile(sys.argv[1]).namelist()
                      if n.startswith("penumbra/lib/") and ".so" in n))' "$ZIP" > "$ROOT$CHECK/vendored.txt"

unshare -m --propagation private bash "$SELF" --inner "$ROOT" "$CHECK" < /dev/null

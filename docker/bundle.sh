#!/usr/bin/env bash
# bundle.sh BASE_PACKAGES OUT BINARY...: copies the binaries to OUT/bin (without their symbol
# tables) and every shared library they load (ldd) to OUT/lib, except those of packages in
# BASE_PACKAGES (one name per line: what the base image already has, which the slim runtime image
# has too). A library's package is looked up under its real path and, Debian being merged-/usr, under
# /lib as well as /usr/lib (libc6 and others list their files under /lib); one dpkg query for all.
set -euo pipefail
base=$1 out=$2
shift 2
mkdir -p "$out/bin" "$out/lib"
libs=$(mktemp)
trap 'rm -f "$libs"' EXIT
for binary in "$@"; do
  cp "$binary" "$out/bin/"
  strip --strip-unneeded "$out/bin/$(basename "$binary")"
  ldd "$binary" | awk '$2 == "=>" && $3 ~ /^\// {print $1, $3}'
done | sort -u > "$libs"

declare -A owner
candidates=()
while read -r _ path; do
  real=$(readlink -f "$path")
  candidates+=("$real")
  case "$real" in /usr/lib/*) candidates+=("/lib/${real#/usr/lib/}") ;; esac
done < "$libs"
while IFS= read -r line; do
  package=${line%%: *}
  owner[${line#*: }]=${package%%:*}
done < <(dpkg -S "${candidates[@]}" 2> /dev/null || true)

kept=0
while read -r soname path; do
  real=$(readlink -f "$path")
  package=${owner[$real]:-}
  case "$real" in /usr/lib/*) [ -n "$package" ] || package=${owner[/lib/${real#/usr/lib/}]:-} ;; esac
  if [ -n "$package" ] && grep -qx "$package" "$base"; then continue; fi
  cp -L "$path" "$out/lib/$soname"
  kept=$((kept + 1))
done < "$libs"
if ldd "$out"/bin/* | grep -q "not found"; then
  echo "bundle.sh: unresolved libraries" >&2
  exit 1
fi
echo "bundle.sh: $kept libraries, $(du -sh "$out/lib" | cut -f1)"

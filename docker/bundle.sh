#!/usr/bin/env bash
# bundle.sh BASE_PACKAGES OUT BINARY...: copies the binaries to OUT/bin (without their symbol
# tables) and every shared library they load (ldd) to OUT/lib, except those of packages in
# BASE_PACKAGES (one name per line: what the base image already has, which the slim runtime image
# has too).
set -euo pipefail
base=$1 out=$2
shift 2
mkdir -p "$out/bin" "$out/lib"
for binary in "$@"; do
  cp "$binary" "$out/bin/"
  strip --strip-unneeded "$out/bin/$(basename "$binary")"
  ldd "$binary" | awk '$2 == "=>" && $3 ~ /^\// {print $1, $3}' | while read -r soname path; do
    owner=$(dpkg -S "$(readlink -f "$path")" 2>/dev/null | head -n 1 | cut -d: -f1) || owner=""
    if [ -n "$owner" ] && grep -qx "$owner" "$base"; then continue; fi
    cp -L "$path" "$out/lib/$soname"
  done
done
if ldd "$out"/bin/* | grep -q "not found"; then
  echo "bundle.sh: unresolved libraries" >&2
  exit 1
fi
echo "bundle.sh: $(ls "$out/lib" | wc -l) libraries, $(du -sh "$out/lib" | cut -f1)"

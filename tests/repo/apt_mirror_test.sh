#!/usr/bin/env bash
# docker/apt-mirror.sh reads the mirror from a host's apt configuration (one-line and deb822
# sources, options in brackets, commented stanzas), and stops with a message when there is none.
# Also: no tracked file names an outside host in a URL (fogmap names no package registry).
set -euo pipefail
top=$(cd "$(dirname "$0")/../.." && pwd)
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
fail=0
expect() {  # expect NAME WANT ACTUAL
  if [ "$2" != "$3" ]; then echo "FAIL $1: want '$2', got '$3'"; fail=1; else echo "ok   $1"; fi
}

# deb822, with a commented line and a deb-src-only stanza first.
mkdir -p "$work/a/etc/apt/sources.list.d"
cat > "$work/a/etc/apt/sources.list.d/debian.sources" << 'X'
Types: deb-src
URIs: http://src.mirror.test/debian
Suites: bookworm
Components: main

Types: deb
# a comment
URIs: http://mirror.test/debian/
Suites: bookworm bookworm-updates
Components: main

Types: deb deb-src
URIs: http://security.mirror.test/debian-security
Suites: bookworm-security
Components: main
X
expect "deb822 main" "http://mirror.test/debian" "$("$top/docker/apt-mirror.sh" --root "$work/a")"
expect "deb822 security" "http://security.mirror.test/debian-security" \
  "$("$top/docker/apt-mirror.sh" --root "$work/a" --security)"

# One-line sources with options.
mkdir -p "$work/b/etc/apt"
cat > "$work/b/etc/apt/sources.list" << 'X'
# deb http://old.mirror.test/debian bookworm main
deb-src http://src.mirror.test/debian bookworm main
deb [arch=amd64 signed-by=/k.gpg] http://one.mirror.test/debian bookworm main contrib
deb http://one.mirror.test/debian-security bookworm-security main
X
expect "list main" "http://one.mirror.test/debian" "$("$top/docker/apt-mirror.sh" --root "$work/b")"
expect "list security" "http://one.mirror.test/debian-security" \
  "$("$top/docker/apt-mirror.sh" --root "$work/b" --security)"

# None: exit 1 with a message naming what to do.
mkdir -p "$work/c/etc/apt"
if out=$("$top/docker/apt-mirror.sh" --root "$work/c" 2>&1); then
  echo "FAIL none: exited 0 with '$out'"; fail=1
else
  case "$out" in *"--mirror URL"*) echo "ok   none" ;; *) echo "FAIL none: '$out'"; fail=1 ;; esac
fi

# No tracked file names an outside host in a URL: loopback and the test's own .test names only.
if [ -d "$top/.git" ]; then
  hosts=$(cd "$top" && git ls-files -z | xargs -0 grep -IhoE "https?://[A-Za-z0-9][A-Za-z0-9.-]*" 2> /dev/null |
    sed -E 's#https?://##' | grep -vE '^(localhost|host|127\.[0-9.]+|[a-z0-9.-]+\.test)$' | sort -u || true)
  if [ -n "$hosts" ]; then echo "FAIL tracked files name outside hosts: $hosts"; fail=1; else echo "ok   no outside hosts"; fi
fi
exit $fail

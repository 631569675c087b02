#!/usr/bin/env bash
# Prints the Debian mirror this host's apt uses, read from its own configuration: the first
# `deb` source of a bookworm suite in /etc/apt/sources.list, /etc/apt/sources.list.d/*.list or
# /etc/apt/sources.list.d/*.sources (deb822). With --security, the source of bookworm-security
# instead. fogmap names no package host of its own: a machine's mirror is the machine's choice.
#   docker/apt-mirror.sh [--security] [--root DIR]
# --root reads DIR/etc/apt instead of /etc/apt (tests). Exits 1, saying so, when none is found.
set -euo pipefail

root=
want=bookworm
while [ $# -gt 0 ]; do
  case "$1" in
    --security) want=bookworm-security; shift ;;
    --root) root=$2; shift 2 ;;
    -h | --help) sed -n '2,7p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) echo "apt-mirror.sh: unknown argument '$1'" >&2; exit 2 ;;
  esac
done
apt_dir=$root/etc/apt

# One-line sources: "deb [options] URI SUITE COMPONENT...".
from_list() {
  awk -v want="$want" '
    /^[[:space:]]*deb[[:space:]]/ {
      i = 2
      if ($i ~ /^\[/) { while (i <= NF && $i !~ /\]$/) i++; i++ }
      if ($(i + 1) == want) { print $i; exit }
    }' "$1"
}

# deb822 stanzas: Types, URIs and Suites fields, stanzas separated by blank lines.
from_sources() {
  awk -v want="$want" '
    function flush() {
      if (types ~ /(^| )deb( |$)/ && uri != "") {
        n = split(suites, s, " ")
        for (k = 1; k <= n; k++) if (s[k] == want) { split(uri, u, " "); print u[1]; found = 1; exit }
      }
      types = ""; uri = ""; suites = ""
    }
    /^[[:space:]]*$/ { flush(); next }
    /^#/ { next }
    tolower($1) == "types:" { $1 = ""; types = $0 " " }
    tolower($1) == "uris:" { $1 = ""; uri = $0; sub(/^ +/, "", uri) }
    tolower($1) == "suites:" { $1 = ""; suites = $0 }
    END { if (!found) flush() }' "$1"
}

files=()
[ -f "$apt_dir/sources.list" ] && files+=("$apt_dir/sources.list")
for f in "$apt_dir"/sources.list.d/*.list "$apt_dir"/sources.list.d/*.sources; do
  [ -f "$f" ] && files+=("$f")
done
for f in "${files[@]+"${files[@]}"}"; do
  case "$f" in
    *.sources) found=$(from_sources "$f") ;;
    *) found=$(from_list "$f") ;;
  esac
  if [ -n "$found" ]; then
    echo "${found%/}"
    exit 0
  fi
done
echo "apt-mirror.sh: no apt source for $want in $apt_dir (sources.list, sources.list.d/*.list, *.sources);" \
  "give the mirror with --mirror URL or FOGMAP_DEBIAN_MIRROR" >&2
exit 1

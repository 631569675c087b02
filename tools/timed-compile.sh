#!/usr/bin/env bash
# A compiler launcher that records each translation unit's compile time:
#   tools/timed-compile.sh LOG COMPILER ARGS...
# appends "SECONDS OBJECT" to LOG. tools/compile-times.sh configures a build with it and ranks the
# units; the ranking is where the build's time goes.
log=$1
shift
start=$(date +%s%N)
"$@"
status=$?
end=$(date +%s%N)
out=
prev=
for arg in "$@"; do
  [ "$prev" = "-o" ] && out=$arg
  prev=$arg
done
printf '%d.%03d %s\n' $(((end - start) / 1000000000)) $((((end - start) / 1000000) % 1000)) "${out:-?}" >> "$log"
exit $status

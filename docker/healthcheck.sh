#!/bin/bash
# The fogmap image's HEALTHCHECK: healthy when the service answers GET /metrics with 200 at
# $FOGMAP_METRICS (HOST:PORT, set per service by the compose file). bash's /dev/tcp: no curl needed.
set -u
addr=${FOGMAP_METRICS:-}
if [[ $addr != *:* ]]; then
  echo "fogmap-healthcheck: FOGMAP_METRICS is not HOST:PORT: '$addr'"
  exit 1
fi
exec 3<>"/dev/tcp/${addr%:*}/${addr##*:}" || exit 1
printf 'GET /metrics HTTP/1.0\r\nHost: %s\r\n\r\n' "$addr" >&3
IFS= read -r -t 5 status <&3 || exit 1
[[ $status == *" 200 "* ]]

#!/usr/bin/env bash
# Builds the fogmap image (default tag fogmap:latest). As root, with the Docker daemon running and
# the base images present (docker/offline-base.sh without a registry).
#   docker/image.sh [--from-host BUILD_DIR] [--tag NAME]
# Default: compiled inside the image (docker/Dockerfile: Debian's -dev packages, OpenCV built static
# from Debian's source package; the release image, 244 MB; 25 minutes on 2 cores uncached).
# --from-host BUILD_DIR: the services already built on this host in BUILD_DIR/bin (a Release build
# of this tree, e.g. build/ from tools/build.sh) with the shared libraries they load (ldd), except
# those of packages the base image has (docker/bundle.sh), on debian:bookworm-slim
# (docker/Dockerfile.host): under a minute, and the same runtime stage. It is larger (494 MB),
# because Debian's shared OpenCV brings its codec and GIS libraries. The host must be Debian
# bookworm, as the image is.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
from_host=""
tag=fogmap:latest
while [ $# -gt 0 ]; do
  case "$1" in
    --from-host) [ $# -ge 2 ] || { echo "image.sh: --from-host needs a build directory" >&2; exit 2; }
                 from_host=$2; shift 2 ;;
    --tag) [ $# -ge 2 ] || { echo "image.sh: --tag needs a name" >&2; exit 2; }
           tag=$2; shift 2 ;;
    -h | --help) sed -n '2,13p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) echo "image.sh: unknown argument '$1'" >&2; exit 2 ;;
  esac
done

if [ -z "$from_host" ]; then
  exec docker build --network host -q -f "$here/Dockerfile" -t "$tag" "$here/.."
fi

# The four services, and fogctl for the live view (fogctl view, the compose file's `view` service).
services=(edge-cluster merge-aggregator detection tracker fogctl)
for s in "${services[@]}"; do
  [ -x "$from_host/bin/$s" ] || { echo "image.sh: $from_host/bin/$s is missing: build it first (tools/build.sh)" >&2; exit 1; }
done
if ! grep -q '^VERSION_CODENAME=bookworm' /etc/os-release; then
  echo "image.sh: --from-host needs a Debian bookworm host (the image is bookworm): build from source instead" >&2
  exit 1
fi
stage=$(mktemp -d)
trap 'rm -rf "$stage"' EXIT
# The packages the base image holds: their libraries are in the image already.
docker run --rm --network none debian:bookworm-slim dpkg-query -W -f '${Package}\n' | sort > "$stage/base-packages.txt"
"$here/bundle.sh" "$stage/base-packages.txt" "$stage" "${services[@]/#/$from_host/bin/}" > /dev/null
cp "$here/healthcheck.sh" "$here/runtime-setup.sh" "$stage/"
docker build --network none -q -f "$here/Dockerfile.host" -t "$tag" "$stage"

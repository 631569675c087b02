#!/usr/bin/env bash
# Makes the base images docker/Dockerfile builds on, debian:bookworm and debian:bookworm-slim,
# from a Debian mirror with debootstrap: no container registry needed (fog sites often have
# none). Run as root, with the Docker daemon running.
#   docker/offline-base.sh [--mirror URL] [--security-mirror URL] [--force]
# The mirror is --mirror, else $FOGMAP_DEBIAN_MIRROR, else the one this host's apt uses
# (docker/apt-mirror.sh); the security mirror likewise (--security-mirror,
# $FOGMAP_DEBIAN_SECURITY_MIRROR, the host's bookworm-security source). None found: it stops.
# debian:bookworm is a minbase system; debian:bookworm-slim is the same packages without
# documentation, manual pages and translations, as Debian's own slim images. Grafana's image cannot
# be made this way (it is not a Debian package): the compose files keep it in the grafana profile.
set -euo pipefail

mirror=${FOGMAP_DEBIAN_MIRROR:-}
security=${FOGMAP_DEBIAN_SECURITY_MIRROR:-}
force=0
while [ $# -gt 0 ]; do
  case "$1" in
    --mirror) mirror=$2; shift 2 ;;
    --security-mirror) security=$2; shift 2 ;;
    --force) force=1; shift ;;
    -h | --help) sed -n '2,11p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) echo "offline-base.sh: unknown argument '$1'" >&2; exit 2 ;;
  esac
done

here=$(dirname "$0")
[ -n "$mirror" ] || mirror=$("$here/apt-mirror.sh") || { echo "offline-base.sh: no Debian mirror: give --mirror URL" >&2; exit 1; }
[ -n "$security" ] || security=$("$here/apt-mirror.sh" --security) ||
  { echo "offline-base.sh: no Debian security mirror: give --security-mirror URL" >&2; exit 1; }

command -v debootstrap > /dev/null || { echo "offline-base.sh: debootstrap is missing (tools/install-deps.sh --deploy)" >&2; exit 1; }
docker info > /dev/null 2>&1 || { echo "offline-base.sh: the Docker daemon does not answer" >&2; exit 1; }
if [ $force -eq 0 ] && docker image inspect debian:bookworm > /dev/null 2>&1 &&
  docker image inspect debian:bookworm-slim > /dev/null 2>&1; then
  echo "offline-base.sh: debian:bookworm and debian:bookworm-slim exist (--force makes them again)"
  exit 0
fi

work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
root=$work/rootfs
start=$(date +%s)
debootstrap --variant=minbase bookworm "$root" "$mirror"
# apt as in Debian's images: the mirror and security updates, no caches.
rm -f "$root/etc/apt/sources.list"
cat > "$root/etc/apt/sources.list.d/debian.sources" << SOURCES
Types: deb
URIs: $mirror
Suites: bookworm bookworm-updates
Components: main
Signed-By: /usr/share/keyrings/debian-archive-keyring.gpg

Types: deb
URIs: $security
Suites: bookworm-security
Components: main
Signed-By: /usr/share/keyrings/debian-archive-keyring.gpg
SOURCES
chroot "$root" apt-get clean
rm -rf "$root"/var/lib/apt/lists/* "$root"/var/cache/apt/*.bin "$root"/var/log/*.log "$root"/var/log/apt/*
tar -C "$root" --numeric-owner -c . | docker import --change 'CMD ["bash"]' - debian:bookworm > /dev/null

# Slim: dpkg leaves documentation out from now on, and what is there goes (copyright notices stay).
cat > "$root/etc/dpkg/dpkg.cfg.d/docker-slim" << 'SLIM'
path-exclude /usr/share/doc/*
path-include /usr/share/doc/*/copyright
path-exclude /usr/share/man/*
path-exclude /usr/share/info/*
path-exclude /usr/share/locale/*
path-exclude /usr/share/groff/*
path-exclude /usr/share/lintian/*
SLIM
find "$root/usr/share/doc" -mindepth 1 -not -name copyright -not -type d -delete
find "$root/usr/share/doc" -mindepth 1 -type d -empty -delete
rm -rf "$root"/usr/share/man/* "$root"/usr/share/info/* "$root"/usr/share/locale/* "$root"/usr/share/groff/* \
  "$root"/usr/share/lintian/*
tar -C "$root" --numeric-owner -c . | docker import --change 'CMD ["bash"]' - debian:bookworm-slim > /dev/null

docker image ls --format '{{.Repository}}:{{.Tag}} {{.Size}}' | grep '^debian:bookworm'
echo "offline-base.sh: made in $(($(date +%s) - start)) s from $mirror"

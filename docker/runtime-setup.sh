#!/bin/sh
# Run once in the runtime stage of both fogmap images (docker/Dockerfile, docker/Dockerfile.host),
# after the binaries are in /usr/local/bin and their libraries in /usr/local/lib/fogmap: makes the
# libraries loadable, adds the service user (uid 10001, no home, no shell) and checks that every
# service starts far enough to answer --help.
set -eu
echo /usr/local/lib/fogmap > /etc/ld.so.conf.d/fogmap.conf
ldconfig
useradd --system --uid 10001 --user-group --no-create-home --home-dir /nonexistent --shell /usr/sbin/nologin fogmap
edge-cluster --help > /dev/null
merge-aggregator --help > /dev/null
detection --help 2> /dev/null
tracker --help > /dev/null

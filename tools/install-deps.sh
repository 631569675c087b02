#!/usr/bin/env bash
# Installs what fogmap needs from Debian bookworm, only if something is missing.
# Runs apt-get as root directly, or through sudo. The one list of fogmap's packages:
#   tools/install-deps.sh            building and testing (the README's commands)
#   tools/install-deps.sh --build    building the services only (docker/Dockerfile's build stage)
#   tools/install-deps.sh --deploy   the container deployment on this host (Docker, docker-compose,
#                                    debootstrap for base images without a registry)
set -euo pipefail

build=(
  build-essential cmake pkg-config
  libeigen3-dev libpcl-dev libopencv-dev
  libgrpc++-dev protobuf-compiler-grpc libprotobuf-dev protobuf-compiler
  prometheus-cpp-dev libyaml-cpp-dev libssl-dev
  nlohmann-json3-dev  # harness/ and fogctl: JSON reports
  libcivetweb-dev civetweb  # view/: the live view's web server (civetweb's CMake package names its binary)
  libembree-dev  # common/sim: ray casting
  lld  # the linker (CMakeLists.txt): links in a fraction of GNU ld's time
)
test=(
  libgtest-dev libgmock-dev libbenchmark-dev
  prometheus  # a real Prometheus server and promtool for the monitoring tests
  iproute2 iptables
  clang libclang-rt-14-dev  # tools/fuzz.sh: libFuzzer, AddressSanitizer and UBSan runtimes
  opencv-data python3-onnx  # the detector tests: OpenCV's cascades, and building a tiny ONNX network
  chromium  # the live view's browser tests (headless)
)
host=(
  ninja-build  # tools/build.sh's generator: compiles across targets, so every core stays busy
)
deploy=(docker.io docker-compose debootstrap curl jq)

case "${1:-}" in
  "") packages=("${build[@]}" "${host[@]}" "${test[@]}") ;;
  --build) packages=("${build[@]}") ;;
  --deploy) packages=("${deploy[@]}") ;;
  -h | --help)
    sed -n '2,7p' "$0" | sed 's/^# \{0,1\}//'
    exit 0
    ;;
  *)
    echo "install-deps: unknown option '$1' (--build, --deploy, or none)" >&2
    exit 2
    ;;
esac

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: every package is present"
  exit 0
fi

as_root=()
if [ "$(id -u)" -ne 0 ]; then
  command -v sudo >/dev/null || { echo "install-deps: run as root or install sudo" >&2; exit 1; }
  as_root=(sudo)
fi
echo "install-deps: installing ${missing[*]}"
"${as_root[@]}" apt-get update -qq
DEBIAN_FRONTEND=noninteractive "${as_root[@]}" apt-get install -y -qq --no-install-recommends "${missing[@]}"

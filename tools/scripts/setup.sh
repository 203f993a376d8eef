#!/usr/bin/env bash
# volpar setup: installs the Debian 12 packages volpar needs (idempotent; apt runs only when something
# is missing), configures and builds, then runs the demo or the whole test suite.
#
#   tools/scripts/setup.sh demo   # Release build, runs scenes/examples/demo.yaml to build/demo.h5
#   tools/scripts/setup.sh test   # RelWithDebInfo build with assertions, runs every test (ctest)
#   tools/scripts/setup.sh bench [ARGS]  # Release build of pile_bench, runs pile-N against Bullet
#                                        # (default: --n 125,1000 --repeats 3 --csv build/pile_bench.csv)
#   tools/scripts/setup.sh deps   # packages only
#
# Run as root, or as a user with sudo.
set -euo pipefail

root=$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)
cd "$root"

packages=(
  build-essential cmake ninja-build pkg-config
  libeigen3-dev libfcl-dev libccd-dev libhdf5-dev libyaml-cpp-dev libcli11-dev
  libgtest-dev libgmock-dev libbenchmark-dev libbullet-dev
  python3 python3-h5py python3-numpy hdf5-tools
)

install_deps() {
  local missing=() p
  for p in "${packages[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q 'install ok installed' || missing+=("$p")
  done
  if ((${#missing[@]} == 0)); then
    echo "setup: all ${#packages[@]} packages present"
    return
  fi
  local sudo=()
  [[ $(id -u) -ne 0 ]] && sudo=(sudo)
  echo "setup: installing ${missing[*]}"
  "${sudo[@]}" apt-get update -q
  DEBIAN_FRONTEND=noninteractive "${sudo[@]}" apt-get install -y -q --no-install-recommends "${missing[@]}"
}

build() {
  cmake --preset "$1"
  cmake --build --preset "$1"
}

case "${1:-}" in
  deps)
    install_deps
    ;;
  bench)
    install_deps
    shift
    cmake --preset release
    cmake --build --preset release --target pile_bench
    if (($# == 0)); then set -- --n 125,1000 --repeats 3 --csv build/pile_bench.csv; fi
    build/release/tools/bench/pile_bench "$@"
    ;;
  demo)
    install_deps
    build release
    build/release/tools/volpar run scenes/examples/demo.yaml -o build/demo.h5
    build/release/tools/volpar inspect build/demo.h5
    echo "setup: trajectory build/demo.h5; open build/demo.xdmf2 in ParaView"
    ;;
  test)
    install_deps
    build dev
    ctest --preset dev
    ;;
  *)
    echo "usage: $0 demo|test|bench [PILE_BENCH ARGS]|deps" >&2
    exit 2
    ;;
esac

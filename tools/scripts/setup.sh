#!/usr/bin/env bash
# volpar setup: installs the Debian 12 packages volpar needs (idempotent; apt runs only when something
# is missing), configures and builds, then runs the demo or the whole test suite.
#
#   tools/scripts/setup.sh demo   # Release build, runs scenes/examples/demo.yaml to build/demo.h5
#   tools/scripts/setup.sh test   # RelWithDebInfo build with assertions, runs every test (ctest), then the
#                                 # hardening build (Clang, ASan + UBSan, libFuzzer) and its short fuzz runs
#   tools/scripts/setup.sh fuzz [SECONDS] [scene|obj|trajectory ...]
#                                 # hardening build, then each fuzzer (default: all three, one after the
#                                 # other) for SECONDS (default 600) over build/hardening/fuzz/long/<name>/
#                                 # corpus, seeded from fuzz/corpus/<name>/; prints executions, coverage and
#                                 # findings (docs/hardening.md)
#   tools/scripts/setup.sh bench [ARGS]  # Release build of pile_bench, runs pile-N against Bullet and Jolt
#                                        # (default: --n 125,1000 --repeats 3 --csv build/pile_bench.csv);
#                                        # Jolt Physics from $VOLPAR_JOLT_SOURCE, or else cloned (v5.5.0) into
#                                        # build/jolt-src; without either, pile_bench runs without Jolt
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
  python3 python3-h5py python3-numpy python3-yaml python3-matplotlib hdf5-tools
  # volpar render: PNG through libpng, MP4 and GIF through the ffmpeg program
  libpng-dev ffmpeg
  # the Python module (python/) and its tests
  pybind11-dev python3-pybind11 python3-dev python3-pytest
  # the hardening preset: Clang 14 and its runtimes (libFuzzer, AddressSanitizer, UBSan: libclang-rt-14-dev)
  clang libclang-rt-dev
  # running across processes (VOLPAR_MPI): Open MPI, and parallel HDF5 beside the serial one
  openmpi-bin libopenmpi-dev libhdf5-openmpi-dev
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

# fuzz SECONDS [TARGET...]: each fuzzer of the hardening build for SECONDS (fuzz/run_fuzzer.py); status 1
# when one has a finding in volpar code
fuzz() {
  local seconds=$1 target found=0
  shift
  local targets=("$@") extra
  ((${#targets[@]})) || targets=(scene obj trajectory)
  export ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
  for target in "${targets[@]}"; do
    [[ -x build/hardening/fuzz/${target}_fuzzer ]] || { echo "setup: no fuzzer '$target' (scene, obj, trajectory)" >&2; exit 2; }
    extra=()
    [[ $target == trajectory ]] && extra=(--third-party libhdf5)
    echo "setup: fuzzing $target for $seconds s"
    /usr/bin/python3 fuzz/run_fuzzer.py "build/hardening/fuzz/${target}_fuzzer" "fuzz/corpus/$target" \
      "build/hardening/fuzz/long/$target" "$seconds" --dict "fuzz/$target.dict" --keep-going "${extra[@]}" || found=1
  done
  return "$found"
}

case "${1:-}" in
  deps)
    install_deps
    ;;
  bench)
    install_deps
    shift
    # Jolt Physics for pile_bench's Jolt variants: $VOLPAR_JOLT_SOURCE, or else a clone of v5.5.0
    jolt=${VOLPAR_JOLT_SOURCE:-}
    if [[ -z $jolt ]]; then
      jolt=$root/build/jolt-src
      if [[ ! -f $jolt/Build/CMakeLists.txt ]]; then
        rm -rf "$jolt"
        if ! git clone --depth 1 --branch v5.5.0 https://github.com/jrouwe/JoltPhysics "$jolt"; then
          echo "setup: cloning Jolt Physics into build/jolt-src failed (no git or network?): no Jolt in pile_bench"
          rm -rf "$jolt"
          jolt=
        fi
      fi
    elif [[ -d $jolt ]]; then
      jolt=$(cd "$jolt" && pwd)  # CMake keeps the path in its cache: absolute
    fi
    cmake --preset release -DVOLPAR_JOLT_SOURCE="$jolt"
    cmake --build --preset release --target pile_bench
    if (($# == 0)); then set -- --n 125,1000 --repeats 3 --csv build/pile_bench.csv; fi
    build/release/tools/bench/pile_bench "$@"
    ;;
  demo)
    install_deps
    # the command line tool and the Python module (where CMake made it a target); the tests and benchmarks
    # are the test and bench commands' to build
    cmake --preset release
    targets=(volpar)
    available=$(cmake --build --preset release --target help)
    if grep -q '^volpar_python:' <<<"$available"; then targets+=(volpar_python); fi
    cmake --build --preset release --target "${targets[@]}"
    build/release/tools/volpar run scenes/examples/demo.yaml -o build/demo.h5
    build/release/tools/volpar inspect build/demo.h5
    echo "setup: trajectory build/demo.h5; open build/demo.xdmf2 in ParaView"
    ;;
  test)
    install_deps
    build dev
    ctest --preset dev
    build hardening
    ctest --preset hardening
    ;;
  fuzz)
    install_deps
    shift
    seconds=${1:-600}
    (($# > 0)) && shift
    [[ $seconds =~ ^[1-9][0-9]*$ ]] || { echo "setup: fuzz SECONDS must be a whole number above 0, got '$seconds'" >&2; exit 2; }
    build hardening
    fuzz "$seconds" "$@"
    ;;
  *)
    echo "usage: $0 demo|test|bench [PILE_BENCH ARGS]|fuzz [SECONDS] [scene|obj|trajectory ...]|deps" >&2
    exit 2
    ;;
esac

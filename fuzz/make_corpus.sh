#!/usr/bin/env bash
# Regenerates the seed corpus in fuzz/corpus/ from the repository's scenes and meshes (docs/hardening.md).
#
#   fuzz/make_corpus.sh [VOLPAR]   # VOLPAR: a volpar binary (default build/release/tools/volpar)
#
# scene/       every scene under scenes/, with mesh shapes replaced by boxes (the fuzzer's scene folder has
#              no meshes), plus the hand-written seeds in fuzz/seeds/ (kept as they are)
# obj/         the OBJ files under scenes/ and tests/data/ (each content once) and in fuzz/seeds/
# trajectory/  short runs (20 steps, a frame every 10; one with a checkpoint) of small scenes, rewritten with h5repack into
#              contiguous datasets (HDF5's original format and its latest one) so that each is a few tens
#              of KB, and two reduced to the objects the reader reads
# Needs h5repack and h5copy (Debian's hdf5-tools).
set -euo pipefail

root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
volpar=${1:-$root/build/release/tools/volpar}
corpus=$root/fuzz/corpus
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

rm -rf "$corpus"
mkdir -p "$corpus/scene" "$corpus/obj" "$corpus/trajectory"

# scenes: mesh shapes become boxes
for scene in "$root"/scenes/*/*.yaml; do
  name=$(basename "$(dirname "$scene")")_$(basename "$scene")
  sed -E 's/\{mesh: \{file: [^}]*\}\}/{box: {size: [0.4, 0.2, 0.3]}}/' "$scene" >"$corpus/scene/$name"
done
cp "$root"/fuzz/seeds/*.yaml "$corpus/scene/"

# meshes: every OBJ file under scenes/ and tests/data/, and the hand-written ones, each content once
declare -A seen=()
while IFS= read -r -d '' mesh; do
  sum=$(md5sum <"$mesh" | cut -c1-32)
  [[ -n ${seen[$sum]:-} ]] && continue
  seen[$sum]=1
  name=$(basename "$mesh")
  [[ -e $corpus/obj/$name ]] && name=$(basename "$(dirname "$mesh")")_$name
  cp "$mesh" "$corpus/obj/$name"
done < <(find "$root/scenes" "$root/tests/data" "$root/fuzz/seeds" -name '*.obj' -print0 | sort -z)

# trajectories
run() {  # run SCENE NAME
  "$volpar" run "$1" -o "$work/$2.h5" --steps 20 --every 10 >/dev/null
}
run "$root/scenes/examples/bounce.yaml" bounce
run "$root/scenes/examples/jelly.yaml" jelly
run "$root/scenes/regression/dzhanibekov.yaml" dzhanibekov
run "$root/fuzz/seeds/small_build.yaml" small
"$volpar" run "$root/fuzz/seeds/small_build.yaml" -o "$work/small_checkpoint.h5" --steps 20 --every 10 --checkpoint-every 10 >/dev/null
h5repack -L -l CONTI "$work/bounce.h5" "$corpus/trajectory/bounce_latest.h5"
h5repack -L -l CONTI "$work/jelly.h5" "$corpus/trajectory/jelly_latest.h5"
h5repack -l CONTI "$work/dzhanibekov.h5" "$corpus/trajectory/dzhanibekov_original.h5"
h5repack -L -l CONTI "$work/small.h5" "$corpus/trajectory/small_latest.h5"
h5repack -L -l CONTI "$work/small_checkpoint.h5" "$corpus/trajectory/small_checkpoint.h5"
# what the reader reads, and nothing else
read_objects=(/h5md /parameters /particles/all/position /particles/all/radius /particles/bodies/name
              /particles/bodies/position /particles/bodies/orientation /observables/kinetic_energy
              /observables/potential_energy /observables/total_energy /patches/offset /patches/count)
reduce() {  # reduce NAME FORMAT_OPTION...
  local name=$1 object
  shift
  for object in "${read_objects[@]}"; do
    h5copy -p -i "$work/$name.h5" -o "$work/$name.reduced.h5" -s "$object" -d "$object"
  done
  h5repack "$@" -l CONTI "$work/$name.reduced.h5" "$corpus/trajectory/${name}_reduced.h5"
}
reduce jelly -L
reduce small
du -sh "$corpus"/*

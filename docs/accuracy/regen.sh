#!/usr/bin/env bash
# Regenerate docs/accuracy/ (results.csv, passes.csv and plots per experiment) and print the
# tables of docs/accuracy.md.
#   docs/accuracy/regen.sh [REF_DIR]
# REF_DIR holds the Mitsuba 3 references of docs/validation/references.sh (default
# target/refs; about 13 minutes to make). Scenes without one (phong_spheres: Mitsuba has no
# Phong) are measured against a long ppm reference that `sweep` renders itself.
# About 3 minutes on 2 cores.
set -euo pipefail
cd "$(dirname "$0")/../.."
REFS="${1:-target/refs}"
OUT=docs/accuracy
cargo build --release --quiet
PB=./target/release/photonbox
SIZE=(--width 256 --height 256)

# scene file : reference file (empty: none)
SCENES=(
  "scenes/cornell.json:$REFS/cornell.ref.exr"
  "scenes/twins/cornell_mirror_glass_twin.json:$REFS/cornell_mirror_glass_twin.ref.exr"
  "scenes/cornell_spheres.json:$REFS/cornell_spheres.ref.exr"
  "scenes/twins/glass_orange_twin.json:$REFS/glass_orange_twin.ref.exr"
  "scenes/knot.json:$REFS/knot.ref.exr"
  "scenes/phong_spheres.json:"
)
for entry in "${SCENES[@]}"; do
  scene="${entry%%:*}"; ref="${entry#*:}"
  name="$(basename "$scene" .json)"
  dir="$OUT/$name"
  rm -rf "$dir"; mkdir -p "$dir"
  refarg=()
  [ -n "$ref" ] && refarg=(--reference "$ref")
  # The seed's experiments, with error beside time: n at k = 10, then k at n = 100k
  # (global map read directly, as the seed did; 4 samples per pixel).
  "$PB" sweep "$scene" "${refarg[@]}" -o "$dir/photons" "${SIZE[@]}" --gather-rays 0 \
    --k 10 --grid n=1000,10000,100000
  [ -z "$ref" ] && refarg=(--reference "$dir/photons/reference.exr")
  "$PB" sweep "$scene" "${refarg[@]}" -o "$dir/k" "${SIZE[@]}" --gather-rays 0 \
    --photons 100000 --caustic-photons 100000 --grid k=1,10,50,100
  # Progressive passes (defaults: 100k + 100k photons per pass, alpha 0.7, auto radius).
  "$PB" sweep "$scene" "${refarg[@]}" -o "$dir/ppm" "${SIZE[@]}" --iterations 256 \
    --grid integrator=ppm
  # Equal time: photon at its defaults, then raytrace and ppm given that much time.
  "$PB" sweep "$scene" "${refarg[@]}" -o "$dir/photon_defaults" "${SIZE[@]}" --grid integrator=photon
  t=$(python3 -c "import csv,sys; print(next(csv.DictReader(open(sys.argv[1])))['total_s'])" \
    "$dir/photon_defaults/results.csv")
  "$PB" sweep "$scene" "${refarg[@]}" -o "$dir/equal_time" "${SIZE[@]}" --iterations 100000 \
    --time-limit "$t" --grid integrator=raytrace,ppm
done

# The point-light originals of the twins (a path tracer cannot render their caustics, so
# there is no Mitsuba reference): against ppm references that sweep renders itself.
for name in cornell_mirror_glass glass_orange; do
  rm -rf "$OUT/originals/$name"
  "$PB" sweep "scenes/$name.json" -o "$OUT/originals/$name" "${SIZE[@]}" --reference-passes 128 \
    --iterations 16 --grid n=10000,100000 integrator=photon,ppm
done

# The caustic scene to convergence (issue 4, acceptance 1): 256 passes of 400k global and
# 2M caustic photons, and one `photon` render with the same photons.
"$PB" sweep scenes/twins/cornell_mirror_glass_twin.json -o "$OUT/convergence" "${SIZE[@]}" \
  --reference "$REFS/cornell_mirror_glass_twin.ref.exr" --photons 400000 --caustic-photons 2000000 \
  --iterations 256 --grid integrator=ppm,photon

python3 docs/accuracy/tables.py "$OUT" target/equal_error/points.jsonl

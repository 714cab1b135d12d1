#!/usr/bin/env bash
# Render the Mitsuba 3 references for docs/validation.md (../shared/refcheck, path tracing).
#   docs/validation/references.sh [OUT_DIR]      (default target/refs; about an hour on 2 cores)
# For each scene: two independent references (seeds 1 and 2), their comparison (the
# reference's own noise floor), and their mean (the reference used).
set -euo pipefail
cd "$(dirname "$0")/../.."
OUT="${1:-target/refs}"
mkdir -p "$OUT"
REF=../shared/refcheck
PY="${REFCHECK_VENV:-$HOME/.cache/refcheck-venv}/bin/python"
W=256; H=256
# scene file : samples per pixel per seed (the rooms' 8,192 since 2026-12-05: with 1,024, at
# 16 s and beyond the references' own noise was much of what the race measured)
SCENES=(
  "scenes/twins/cornell_mirror_glass_twin.json:4096"
  "scenes/twins/glass_orange_twin.json:16384"
  "scenes/cornell_spheres.json:8192"
  "scenes/cornell.json:8192"
  "scenes/knot.json:8192"
)
for entry in "${SCENES[@]}"; do
  scene="${entry%%:*}"; spp="${entry##*:}"
  name="$(basename "$scene" .json)"
  for seed in 1 2; do
    out="$OUT/$name.seed$seed.exr"
    [ -f "$out" ] || "$REF/run" render_ref.py "$scene" "$out" --spp "$spp" --seed "$seed" \
      --width $W --height $H --stats "$OUT/$name.seed$seed.json"
  done
  "$REF/run" compare.py "$OUT/$name.seed1.exr" "$OUT/$name.seed2.exr" > "$OUT/$name.noise.json"
  "$PY" - "$OUT/$name.seed1.exr" "$OUT/$name.seed2.exr" "$OUT/$name.ref.exr" <<'PYEOF'
import sys
sys.path.insert(0, "../shared/refcheck")
from imgio import read_image, write_image
a, b = read_image(sys.argv[1]), read_image(sys.argv[2])
write_image(sys.argv[3], ((a + b) / 2).astype("float32"))
PYEOF
  echo "$name: reference noise (seed 1 vs seed 2): $(tr -d '\n ' < "$OUT/$name.noise.json" | head -c 400)"
done

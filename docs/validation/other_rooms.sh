#!/usr/bin/env bash
# The race (race.py) on rooms that are not built-in scenes (docs/validation/rooms/): does
# `auto` choose well, and stay unbiased, where its rules were not tuned? References as in
# references.sh (two seeds, their mean), then race.py on these rooms alone.
#   docs/validation/other_rooms.sh [OUT_DIR] [SPP] [BUDGETS...]
#   (defaults: target/other_rooms, 2048 spp a seed, budgets 1 4 16; about 30 minutes on 2 cores)
set -euo pipefail
cd "$(dirname "$0")/../.."
OUT="${1:-target/other_rooms}"
SPP="${2:-2048}"
shift $(( $# > 2 ? 2 : $# ))
BUDGETS="${*:-1 4 16}"
mkdir -p "$OUT/refs"
REF=../shared/refcheck
PY="${REFCHECK_VENV:-$HOME/.cache/refcheck-venv}/bin/python"
ROOMS=(docs/validation/rooms/*.json)
for scene in "${ROOMS[@]}"; do
  name="$(basename "$scene" .json)"
  for seed in 1 2; do
    out="$OUT/refs/$name.seed$seed.exr"
    [ -f "$out" ] || "$REF/run" render_ref.py "$scene" "$out" --spp "$SPP" --seed "$seed" \
      --width 256 --height 256 --stats "$OUT/refs/$name.seed$seed.json"
  done
  "$REF/run" compare.py "$OUT/refs/$name.seed1.exr" "$OUT/refs/$name.seed2.exr" \
    > "$OUT/refs/$name.noise.json"
  "$PY" - "$OUT/refs/$name.seed1.exr" "$OUT/refs/$name.seed2.exr" "$OUT/refs/$name.ref.exr" <<'PYEOF'
import sys
sys.path.insert(0, "../shared/refcheck")
from imgio import read_image, write_image
a, b = read_image(sys.argv[1]), read_image(sys.argv[2])
write_image(sys.argv[3], ((a + b) / 2).astype("float32"))
PYEOF
done
cargo build --release --quiet
# shellcheck disable=SC2086
python3 docs/validation/race.py --refs "$OUT/refs" --out "$OUT/race" --scenes \
  --scene-files "${ROOMS[@]}" --integrators auto pt bdpt --budgets $BUDGETS

#!/usr/bin/env bash
# `lt` against Mitsuba 3's own light tracer on the scenes where a light tracer cannot agree
# with a path-traced reference (the camera sees mirrors or glass; docs/validation/ptracer_ref.py
# says why), for docs/performance.md, section 6.
#   docs/validation/lt_agreement.sh [OUT_DIR] [SPP] [SECONDS]
#   (defaults: target/lt-agree, 2048 spp a seed, lt for 64 s; about 15 minutes on 2 cores)
# For each scene: two Mitsuba `ptracer` images (seeds 1 and 2), their comparison (the
# reference's own noise), their mean (the reference), and `photonbox render --integrator lt`
# compared against it.
set -euo pipefail
cd "$(dirname "$0")/../.."
OUT="${1:-target/lt-agree}"
SPP="${2:-2048}"
SECONDS_LT="${3:-64}"
mkdir -p "$OUT"
REF=../shared/refcheck
PY="${REFCHECK_VENV:-$HOME/.cache/refcheck-venv}/bin/python"
[ -x "$PY" ] || bash "$REF/setup.sh" >&2
cargo build --release --quiet
W=256; H=256
for scene in scenes/twins/cornell_mirror_glass_twin.json scenes/twins/glass_orange_twin.json; do
  name="$(basename "$scene" .json)"
  for seed in 1 2; do
    out="$OUT/$name.ptracer.seed$seed.exr"
    [ -f "$out" ] || "$PY" docs/validation/ptracer_ref.py "$scene" "$out" --spp "$SPP" \
      --seed "$seed" --width $W --height $H --stats "$OUT/$name.ptracer.seed$seed.json"
  done
  "$PY" - "$OUT/$name.ptracer.seed1.exr" "$OUT/$name.ptracer.seed2.exr" "$OUT/$name.ptracer.exr" <<'PYEOF'
import sys
sys.path.insert(0, "../shared/refcheck")
from imgio import read_image, write_image
a, b = read_image(sys.argv[1]), read_image(sys.argv[2])
write_image(sys.argv[3], ((a + b) / 2).astype("float32"))
PYEOF
  echo "$name: ptracer noise (seed 1 vs 2): $("$REF/run" compare.py "$OUT/$name.ptracer.seed1.exr" \
    "$OUT/$name.ptracer.seed2.exr" | tr -d '\n ')"
  target/release/photonbox render "$scene" -o "$OUT/$name.lt.png" --exr "$OUT/$name.lt.exr" \
    --width $W --height $H --seed 7 --integrator lt --time-limit "$SECONDS_LT" \
    --stats "$OUT/$name.lt.stats.json"
  echo "$name: lt ($SECONDS_LT s) against ptracer: $("$REF/run" compare.py "$OUT/$name.lt.exr" \
    "$OUT/$name.ptracer.exr" | tr -d '\n ')"
done

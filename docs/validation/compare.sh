#!/usr/bin/env bash
# Render every validated scene with photonbox at the default settings (256x256) and compare it
# with the Mitsuba 3 references made by references.sh. Prints one Markdown table row a scene.
#   docs/validation/compare.sh [REF_DIR] [-- extra photonbox flags]
set -euo pipefail
cd "$(dirname "$0")/../.."
REFS="${1:-target/refs}"; shift || true
[ "${1:-}" = "--" ] && shift
OUT="target/validation"
mkdir -p "$OUT"
cargo build --release --quiet
REF=../shared/refcheck
for scene in scenes/twins/cornell_mirror_glass_twin.json scenes/twins/glass_orange_twin.json \
             scenes/cornell_spheres.json scenes/cornell.json scenes/knot.json; do
  name="$(basename "$scene" .json)"
  ./target/release/photonbox render "$scene" -o "$OUT/$name.png" --exr "$OUT/$name.exr" \
    --stats "$OUT/$name.stats.json" --width 256 --height 256 "$@"
  "$REF/run" compare.py "$OUT/$name.exr" "$REFS/$name.ref.exr" > "$OUT/$name.compare.json"
  "$REF/run" to_png.py "$REFS/$name.ref.exr" "$OUT/$name.ref.png" >/dev/null
  python3 - "$name" "$OUT/$name.compare.json" "$REFS/$name.noise.json" "$OUT/$name.stats.json" <<'PYEOF'
import json, sys
name, cmp, noise, stats = sys.argv[1], *(json.load(open(p)) for p in sys.argv[2:])
m = cmp["mean_ratio"]
ok = abs(m["lum"] - 1) <= 0.02 and cmp["block_err"] <= 0.03
print(f"| {name} | {m['r']:.4f} / {m['g']:.4f} / {m['b']:.4f} / {m['lum']:.4f} | {cmp['block_err']:.4f} | "
      f"{cmp['relmse']:.4f} | {noise['block_err']:.4f} / {noise['relmse']:.4f} | {stats['times']['total']:.2f} s | "
      f"{'pass' if ok else 'FAIL'} |")
PYEOF
done

#!/usr/bin/env bash
# Equal-error time, photonbox against Mitsuba 3 (path tracing), on the small-sphere-light twin
# of the seed's scene (1) at 256x256, against the long reference of references.sh.
#   docs/validation/equal_error.sh [REF_DIR]
# Writes target/equal_error/points.json (time and errors of every render) and prints a table.
set -euo pipefail
cd "$(dirname "$0")/../.."
REFS="${1:-target/refs}"
OUT=target/equal_error
mkdir -p "$OUT"
REF=../shared/refcheck
SCENE=scenes/twins/cornell_mirror_glass_twin.json
cargo build --release --quiet
points="$OUT/points.jsonl"; : > "$points"
record() {  # renderer label seconds exr
  "$REF/run" compare.py "$4" "$REFS/cornell_mirror_glass_twin.ref.exr" > "$OUT/cmp.json"
  python3 -c "import json,sys; c=json.load(open('$OUT/cmp.json')); print(json.dumps({'renderer':'$1','label':'$2','seconds':$3,'relmse':c['relmse'],'relmse_excl_bright':c['relmse_excl_bright'],'block_err':c['block_err'],'mean_ratio':c['mean_ratio']['lum']}))" >> "$points"
  tail -1 "$points"
}
for spp in 16 32 64 128 256 512 1024; do
  "$REF/run" render_ref.py "$SCENE" "$OUT/mi$spp.exr" --spp "$spp" --seed 7 --width 256 --height 256 \
    --stats "$OUT/mi$spp.json" > /dev/null
  t=$(python3 -c "import json; print(json.load(open('$OUT/mi$spp.json'))['times']['render'])")
  record mitsuba "spp=$spp" "$t" "$OUT/mi$spp.exr"
done
while read -r label args; do
  ./target/release/photonbox render "$SCENE" -o "$OUT/pb.png" --exr "$OUT/pb_$label.exr" \
    --stats "$OUT/pb_$label.json" --width 256 --height 256 --seed 7 $args
  t=$(python3 -c "import json; print(json.load(open('$OUT/pb_$label.json'))['times']['total'])")
  record photonbox "$label $args" "$t" "$OUT/pb_$label.exr"
done <<'CONFIGS'
g0-50k --photons 50000 --caustic-photons 50000 --gather-rays 0 --spp 1
g0-100k --photons 100000 --caustic-photons 100000 --gather-rays 0 --spp 1
g0-200k --photons 200000 --caustic-photons 200000 --gather-rays 0 --spp 2
g2-100k --photons 100000 --caustic-photons 100000 --gather-rays 2 --spp 2
g4-200k --photons 200000 --caustic-photons 200000 --gather-rays 4 --spp 4
g8-200k --photons 200000 --caustic-photons 200000 --gather-rays 8 --spp 4
g16-400k --photons 400000 --caustic-photons 400000 --gather-rays 16 --spp 4
g16-1m --photons 1000000 --caustic-photons 1000000 --gather-rays 16 --spp 16
CONFIGS
python3 - "$points" <<'PYEOF'
import json, math, sys
pts = [json.loads(l) for l in open(sys.argv[1])]
def mitsuba_time(metric, target):
    """Path tracing's error falls steadily with samples: interpolate log(error) against
    log(time) between the two sample counts that bracket the target."""
    ps = sorted((p for p in pts if p["renderer"] == "mitsuba"), key=lambda p: p["seconds"])
    for a, b in zip(ps, ps[1:]):
        if a[metric] > target >= b[metric]:
            f = math.log(a[metric] / target) / math.log(a[metric] / b[metric])
            return a["seconds"] * (b["seconds"] / a["seconds"]) ** f
    return ps[0]["seconds"] if ps and ps[0][metric] <= target else None
def photonbox_time(metric, target):
    """The fastest measured photonbox setting that reaches the target (no interpolation)."""
    ok = [p["seconds"] for p in pts if p["renderer"] == "photonbox" and p[metric] <= target]
    return min(ok) if ok else None
print("| metric | target | Mitsuba 3 | photonbox | photonbox / Mitsuba |")
print("|---|---|---|---|---|")
for metric, targets in (("relmse_excl_bright", (0.05, 0.03, 0.02)), ("block_err", (0.05, 0.03, 0.02))):
    for t in targets:
        a, b = mitsuba_time(metric, t), photonbox_time(metric, t)
        ratio = f"{b / a:.3f}" if a and b else "-"
        fa = f"{a:.1f} s" if a else "not reached"
        fb = f"{b:.2f} s" if b else "not reached"
        print(f"| {metric} | {t} | {fa} | {fb} | {ratio} |")
PYEOF

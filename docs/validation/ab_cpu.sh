#!/usr/bin/env bash
# Two builds of photonbox, paired: the CPU time of the same short render, in turn, many times.
#   docs/validation/ab_cpu.sh OLD_BINARY NEW_BINARY [SCENE] [INTEGRATOR] [PAIRS]
# On a shared, virtualised host a render's speed drifts by 20% within a minute, so a few long
# runs cannot resolve a change of a few percent; the median of many adjacent pairs' ratios
# can (its quartiles say how far to trust it). Prints NEW/OLD user CPU: below 1 is faster.
set -euo pipefail
OLD="$1"; NEW="$2"; SCENE="${3:-scenes/knot.json}"; INTEGRATOR="${4:-pt}"; PAIRS="${5:-40}"
cpu() {
  /usr/bin/time -f "%U" "$1" render "$SCENE" -o /tmp/ab_cpu.png --integrator "$INTEGRATOR" \
    --iterations 8 --width 256 --height 256 --seed 1 2>&1 >/dev/null | tail -1
}
for r in $(seq "$PAIRS"); do
  if [ $((r % 2)) = 0 ]; then a=$(cpu "$OLD"); b=$(cpu "$NEW"); else b=$(cpu "$NEW"); a=$(cpu "$OLD"); fi
  echo "$a $b"
done | python3 -c '
import statistics, sys
p = [tuple(map(float, l.split())) for l in sys.stdin]
r = sorted(b / a for a, b in p)
q = len(r) // 4
print(f"new/old user CPU over {len(r)} pairs: median {statistics.median(r):.3f}, "
      f"quartiles {r[q]:.3f}-{r[-q - 1]:.3f}; median old {statistics.median(a for a, _ in p):.2f} s, "
      f"new {statistics.median(b for _, b in p):.2f} s")'

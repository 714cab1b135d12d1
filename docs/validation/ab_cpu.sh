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
source "$(dirname "$0")/ab_pairs.sh"
ab_pairs cpu "$OLD" "$NEW" "$PAIRS" "user CPU"

#!/usr/bin/env bash
# Two builds of photonbox, paired: the wall time of the same whole render (start-up, auto's
# pilot, passes and output: what the race charges), in turn, many times.
#   docs/validation/ab_wall.sh OLD_BINARY NEW_BINARY SCENE PAIRS [render options...]
# e.g. ab_wall.sh old/photonbox new/photonbox scenes/cornell_spheres.json 16 --iterations 2
# As in ab_cpu.sh, the median of adjacent pairs' ratios resolves what a few long runs on a
# shared host cannot. Renders at 256x256, seed 7 (the race's). Prints NEW/OLD wall time:
# below 1 is faster.
set -euo pipefail
OLD="$1"; NEW="$2"; SCENE="$3"; PAIRS="$4"; shift 4
OPTIONS=("$@")
wall() {
  python3 - "$1" "$SCENE" "${OPTIONS[@]}" <<'PYEOF'
import subprocess, sys, time
binary, scene, *options = sys.argv[1:]
t0 = time.perf_counter()
subprocess.run([binary, "render", scene, "-o", "/tmp/ab_wall.png", "--width", "256",
                "--height", "256", "--seed", "7", *options], check=True, capture_output=True)
print(time.perf_counter() - t0)
PYEOF
}
source "$(dirname "$0")/ab_pairs.sh"
ab_pairs wall "$OLD" "$NEW" "$PAIRS" "wall time"

#!/usr/bin/env bash
# Two builds of photonbox, paired: the wall time of the same whole render (start-up, auto's
# pilot, passes and output: what the race charges), in turn, many times.
#   docs/validation/ab_wall.sh OLD_BINARY NEW_BINARY SCENE PAIRS [render options...]
# e.g. ab_wall.sh old/photonbox new/photonbox scenes/cornell_spheres.json 16 --iterations 2
# As ab_cpu.sh, the median of adjacent pairs' ratios resolves what a few long runs on a
# shared host cannot. Renders at 256x256, seed 7 (the race's). Prints NEW/OLD: below 1 is
# faster.
set -euo pipefail
OLD="$1"; NEW="$2"; SCENE="$3"; PAIRS="$4"; shift 4
wall() {
  local bin="$1"; shift
  python3 - "$bin" "$SCENE" "$@" <<'PYEOF'
import subprocess, sys, time
bin, scene, *rest = sys.argv[1:]
t0 = time.perf_counter()
subprocess.run([bin, "render", scene, "-o", "/tmp/ab_wall.png", "--width", "256", "--height",
                "256", "--seed", "7", *rest], check=True, capture_output=True)
print(time.perf_counter() - t0)
PYEOF
}
for r in $(seq "$PAIRS"); do
  if [ $((r % 2)) = 0 ]; then a=$(wall "$OLD" "$@"); b=$(wall "$NEW" "$@"); else b=$(wall "$NEW" "$@"); a=$(wall "$OLD" "$@"); fi
  echo "$a $b"
done | python3 -c '
import statistics, sys
p = [tuple(map(float, l.split())) for l in sys.stdin]
r = sorted(b / a for a, b in p)
q = len(r) // 4
print(f"new/old wall over {len(r)} pairs: median {statistics.median(r):.3f}, "
      f"quartiles {r[q]:.3f}-{r[-q - 1]:.3f}; median old {statistics.median(a for a, _ in p):.3f} s, "
      f"new {statistics.median(b for _, b in p):.3f} s")'

# Sourced by ab_cpu.sh and ab_wall.sh: `ab_pairs MEASURE OLD NEW PAIRS WHAT` runs
# `MEASURE OLD` and `MEASURE NEW` in turn (the order alternating, so that a drift of the
# host's speed falls on both alike) PAIRS times, and prints the median and quartiles of
# NEW/OLD over the pairs, with the medians of each (WHAT names the measure, "user CPU").
ab_pairs() {
  local measure="$1" old="$2" new="$3" pairs="$4" what="$5" a b r
  for r in $(seq "$pairs"); do
    if [ $((r % 2)) = 0 ]; then a=$("$measure" "$old"); b=$("$measure" "$new")
    else b=$("$measure" "$new"); a=$("$measure" "$old"); fi
    echo "$a $b"
  done | python3 -c '
import statistics, sys
what = sys.argv[1]
p = [tuple(map(float, l.split())) for l in sys.stdin]
r = sorted(b / a for a, b in p)
q = len(r) // 4
print(f"new/old {what} over {len(r)} pairs: median {statistics.median(r):.3f}, "
      f"quartiles {r[q]:.3f}-{r[-q - 1]:.3f}; median old {statistics.median(a for a, _ in p):.3f} s, "
      f"new {statistics.median(b for _, b in p):.3f} s")' "$what"
}

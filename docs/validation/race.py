#!/usr/bin/env python3
"""The race (issue 20, acceptance 2): photonbox against Mitsuba 3's path tracer, side by side
in one run, per scene and time budget.

    python3 docs/validation/race.py [--refs target/refs] [--budgets 1 4 16 64]
        [--integrators auto photon ppm pt lt bdpt vcm] [--scenes NAME ...] [--out target/race]

Run by docs/validation/race.sh (which builds photonbox and puts Mitsuba's venv on the path).

For each scene (every scene Mitsuba renders; the twins stand in for the point-light scenes
with specular surfaces) and budget T:

- Mitsuba 3 (refcheck's render_ref.py, path tracing, seed 7, independent of the references'
  seeds 1 and 2) renders a ladder of sample counts bracketing T seconds of its own render
  time; each rung's relmse and block_err against the reference are measured, and
  log(error) is interpolated against log(time) to get Mitsuba's error at exactly T.
- photonbox renders once per integrator with --time-limit (the longest budget) and
  --reference: every pass records its error and its elapsed seconds, so one run gives the
  whole error-against-time curve; the process's own start-up (scene load) is added. A
  one-shot integrator (photon) is one point per setting of a small ladder of photon counts.
- The cell is photonbox's time to reach Mitsuba's error at T (the first pass at or below
  it), over T: below 1, photonbox is faster. The best integrator per cell is reported, and
  each integrator's own figure.

Writes OUT/points.json (every measurement) and prints the Markdown tables.
"""
import argparse
import json
import math
import os
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.abspath(os.path.join(HERE, "..", ".."))
REFCHECK = os.path.abspath(os.path.join(ROOT, "..", "shared", "refcheck"))
PHOTONBOX = os.path.join(ROOT, "target", "release", "photonbox")
W = H = 256

SCENES = {
    "cornell_mirror_glass_twin": ("scenes/twins/cornell_mirror_glass_twin.json", True),
    "glass_orange_twin": ("scenes/twins/glass_orange_twin.json", True),
    "cornell_spheres": ("scenes/cornell_spheres.json", False),
    "cornell": ("scenes/cornell.json", False),
    "knot": ("scenes/knot.json", False),
}


def refcheck(*args):
    out = subprocess.run([os.path.join(REFCHECK, "run"), *args], check=True,
                         capture_output=True, text=True)
    return out.stdout


def compare(exr, ref):
    c = json.loads(refcheck("compare.py", exr, ref))
    return {"relmse": c["relmse"], "block_err": c["block_err"],
            "mean_ratio": c["mean_ratio"]["lum"]}


def mitsuba_ladder(name, scene, ref, budgets, out):
    """Rungs of doubling sample counts until one takes longer than the longest budget."""
    pts, spp = [], 1
    while True:
        exr = os.path.join(out, f"{name}.mi{spp}.exr")
        stats = os.path.join(out, f"{name}.mi{spp}.json")
        refcheck("render_ref.py", scene, exr, "--spp", str(spp), "--seed", "7", "--width",
                 str(W), "--height", str(H), "--pass-spp", str(min(spp, 64)), "--stats", stats)
        t = json.load(open(stats))["times"]["render"]
        p = {"renderer": "mitsuba", "spp": spp, "seconds": t, **compare(exr, ref)}
        pts.append(p)
        print(f"  mitsuba {spp} spp: {t:.2f} s relmse {p['relmse']:.5f} "
              f"block_err {p['block_err']:.5f}", flush=True)
        if t > max(budgets) * 1.05:
            return pts
        spp *= 2


def at_time(pts, metric, t):
    """Mitsuba's error at t seconds: log-log interpolation between bracketing rungs."""
    ps = sorted(pts, key=lambda p: p["seconds"])
    for a, b in zip(ps, ps[1:]):
        if a["seconds"] <= t <= b["seconds"]:
            f = math.log(t / a["seconds"]) / math.log(b["seconds"] / a["seconds"])
            return a[metric] * (b[metric] / a[metric]) ** f
    return None


def photonbox_runs(name, scene, ref, integrator, longest, out):
    """An integrator's error-against-time curve: (seconds, relmse, block_err) points."""
    base = os.path.join(out, f"{name}.{integrator}")
    if integrator == "photon":
        curve = []
        for n, g, spp in [(25_000, 0, 1), (100_000, 0, 1), (200_000, 4, 2), (200_000, 8, 4),
                          (400_000, 16, 4), (1_000_000, 16, 16), (2_000_000, 32, 16)]:
            t0 = time.time()
            run = [PHOTONBOX, "render", scene, "-o", base + ".png", "--exr", base + ".exr",
                   "--width", str(W), "--height", str(H), "--seed", "7",
                   "--photons", str(n), "--caustic-photons", str(n),
                   "--gather-rays", str(g), "--spp", str(spp)]
            subprocess.run(run, check=True, capture_output=True)
            wall = time.time() - t0
            c = compare(base + ".exr", ref)
            curve.append({"seconds": wall, **c})
            if wall > longest:
                break
        return curve
    stats = base + ".stats.json"
    t0 = time.time()
    run = [PHOTONBOX, "render", scene, "-o", base + ".png", "--exr", base + ".exr",
           "--stats", stats, "--width", str(W), "--height", str(H), "--seed", "7",
           "--integrator", integrator, "--time-limit", str(longest), "--reference", ref]
    subprocess.run(run, check=True, capture_output=True)
    wall = time.time() - t0
    s = json.load(open(stats))
    passes = s["ppm"]["history"]
    # The process's time beyond its passes (start-up, scene load, output), spread over none:
    # added to every pass's elapsed time.
    overhead = max(0.0, wall - passes[-1]["elapsed"])
    return [{"seconds": p["elapsed"] + overhead, "relmse": p["error"]["relmse"],
             "block_err": p["error"]["block_err"], "mean_ratio": p["error"]["mean_ratio"]}
            for p in passes]


def time_to(curve, metric, target):
    ok = [p["seconds"] for p in curve if p[metric] <= target]
    return min(ok) if ok else None


def main():
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--refs", default=os.path.join(ROOT, "target", "refs"))
    ap.add_argument("--out", default=os.path.join(ROOT, "target", "race"))
    ap.add_argument("--budgets", type=float, nargs="+", default=[1, 4, 16, 64])
    ap.add_argument("--integrators", nargs="+",
                    default=["auto", "photon", "ppm", "pt", "lt", "bdpt", "vcm"])
    ap.add_argument("--scenes", nargs="+", default=list(SCENES))
    args = ap.parse_args()
    os.makedirs(args.out, exist_ok=True)
    results = {}
    for name in args.scenes:
        scene, caustics = SCENES[name]
        scene = os.path.join(ROOT, scene)
        ref = os.path.join(args.refs, f"{name}.ref.exr")
        print(f"{name}:", flush=True)
        mi = mitsuba_ladder(name, scene, ref, args.budgets, args.out)
        curves = {}
        for integrator in args.integrators:
            curves[integrator] = photonbox_runs(name, scene, ref, integrator,
                                                max(args.budgets), args.out)
            last = curves[integrator][-1]
            print(f"  {integrator}: {len(curves[integrator])} points, last "
                  f"{last['seconds']:.1f} s relmse {last['relmse']:.5f} "
                  f"block_err {last['block_err']:.5f}", flush=True)
        results[name] = {"caustics": caustics, "mitsuba": mi, "photonbox": curves}
        json.dump(results, open(os.path.join(args.out, "points.json"), "w"), indent=1)
    report(results, args.budgets)


def report(results, budgets):
    print("\n### Agreement at the longest budget (the last pass of each run)\n")
    print("| scene | integrator | seconds | mean_ratio | block_err | relmse | within 0.5% and 0.008 |")
    print("|---|---|---|---|---|---|---|")
    for name, r in results.items():
        for integrator, curve in r["photonbox"].items():
            p = curve[-1]
            ok = abs(p["mean_ratio"] - 1) <= 0.005 and p["block_err"] <= 0.008
            print(f"| {name} | {integrator} | {p['seconds']:.0f} | {p['mean_ratio']:.4f} | "
                  f"{p['block_err']:.4f} | {p['relmse']:.5f} | {'yes' if ok else 'no'} |")
    for metric in ("relmse", "block_err"):
        print(f"\n### Time to Mitsuba's {metric} at each budget, as a fraction of the budget\n")
        head = " | ".join(f"{b:g} s" for b in budgets)
        print(f"| scene | goal | integrator | {head} |")
        print("|---|---|---|" + "---|" * len(budgets))
        for name, r in results.items():
            goal = 0.2 if r["caustics"] else 0.33
            rows = {}
            for integrator, curve in r["photonbox"].items():
                cells = []
                for b in budgets:
                    target = at_time(r["mitsuba"], metric, b)
                    t = time_to(curve, metric, target) if target else None
                    cells.append(t / b if t else None)
                rows[integrator] = cells
            best = [min((c[i] for c in rows.values() if c[i] is not None), default=None)
                    for i in range(len(budgets))]
            rows = {"best": best, **rows}
            for integrator, cells in rows.items():
                shown = " | ".join(
                    "not reached" if c is None else
                    (f"**{c:.3f}**" if c > goal else f"{c:.3f}") for c in cells)
                print(f"| {name} | {goal} | {integrator} | {shown} |")


if __name__ == "__main__":
    sys.exit(main())

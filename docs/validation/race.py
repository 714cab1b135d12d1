#!/usr/bin/env python3
"""The race (issue 20, acceptance 2): photonbox against Mitsuba 3's path tracer, side by side
in one run, per scene and time budget.

    python3 docs/validation/race.py [--refs target/refs] [--budgets 1 4 16 64]
        [--integrators auto photon ppm ppm_gather pt lt bdpt vcm] [--scenes NAME ...]
        [--out target/race]

Run by docs/validation/race.sh (which builds photonbox and puts Mitsuba's venv on the path).

For each scene (every scene Mitsuba renders; the twins stand in for the point-light scenes
with specular surfaces) and budget T:

- Mitsuba 3 (refcheck's render_ref.py, path tracing, seed 7, independent of the references'
  seeds 1 and 2) renders a ladder of sample counts bracketing T seconds of its own render
  time; each rung's relmse and block_err against the reference are measured, and
  log(error) is interpolated against log(time) to get Mitsuba's error at exactly T.
- photonbox renders once per integrator with --time-limit (the longest budget) and
  --reference: every pass records its error and its elapsed seconds, so one run gives the
  whole error-against-time curve; the process's own start-up and output (measured by a
  run of one pass without a reference) and auto's pilot are added, the per-pass
  comparisons with the reference (the race's measuring) are not. A
  one-shot integrator (photon) is one point per setting of a small ladder of photon counts.
  `auto` renders once per budget with --time-limit T (what it chooses depends on T: a
  photon render under a short limit on a scene with mirror or glass), its cell at T from
  that run alone.
- The cell is photonbox's time to reach Mitsuba's error at T (the first pass at or below
  it), over T: below 1, photonbox is faster. The best integrator per cell is reported, and
  each integrator's own figure.

Writes OUT/points.json (every measurement) and OUT/host.txt (the CPU it ran on, printed
above the tables: figures compare within one host only), and prints the Markdown tables.
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
# Another build to race (an older commit's, side by side): PHOTONBOX=path/to/photonbox.
PHOTONBOX = os.environ.get("PHOTONBOX", os.path.join(ROOT, "target", "release", "photonbox"))
W = H = 256

SCENES = {
    "cornell_mirror_glass_twin": ("scenes/twins/cornell_mirror_glass_twin.json", True),
    "glass_orange_twin": ("scenes/twins/glass_orange_twin.json", True),
    "cornell_spheres": ("scenes/cornell_spheres.json", False),
    "cornell": ("scenes/cornell.json", False),
    "knot": ("scenes/knot.json", False),
}


# Integrators raced with options of their own: `ppm_gather` is ppm with final gathering, as
# `auto` renders a room without mirror or glass whose light a camera path's bounce finds.
VARIANTS = {"ppm_gather": ["--integrator", "ppm", "--gather-rays", "4", "--spp", "2"]}


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
        if not (os.path.exists(stats) and os.path.exists(exr)):  # kept from an earlier run
            refcheck("render_ref.py", scene, exr, "--spp", str(spp), "--seed", "7", "--width",
                     str(W), "--height", str(H), "--pass-spp", str(min(spp, 64)),
                     "--stats", stats)
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


def auto_runs(name, scene, ref, budgets, out):
    """`auto` once per budget (its choice depends on the budget): each run's points, marked
    with the budget they answer."""
    points = []
    for b in budgets:
        curve = photonbox_runs(name, scene, ref, "auto", b, out, tag=f"auto{b:g}")
        points += [{**p, "budget": b} for p in curve]
    return points


def photonbox_runs(name, scene, ref, integrator, longest, out, tag=None):
    """An integrator's error-against-time curve: (seconds, relmse, block_err) points."""
    base = os.path.join(out, f"{name}.{tag or integrator}")
    if integrator == "photon":
        curve = []
        for n, g, spp in [(25_000, 0, 1), (100_000, 0, 1), (200_000, 4, 2), (200_000, 8, 4),
                          (400_000, 16, 4), (1_000_000, 16, 16), (2_000_000, 32, 16)]:
            t0 = time.time()
            run = [PHOTONBOX, "render", scene, "-o", base + ".png", "--exr", base + ".exr",
                   "--width", str(W), "--height", str(H), "--seed", "7",
                   "--integrator", "photon", "--photons", str(n), "--caustic-photons", str(n),
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
           "--width", str(W), "--height", str(H), "--seed", "7",
           *VARIANTS.get(integrator, ["--integrator", integrator]),
           "--time-limit", str(longest)]
    subprocess.run(run + ["--stats", stats, "--reference", ref], check=True,
                   capture_output=True)
    wall = time.time() - t0
    s = json.load(open(stats))
    how = s.get("effects", {}).get("integrator", {}).get("how", integrator)
    if "ppm" not in s:  # auto chose a one-shot render: one point
        return [{"seconds": wall, **compare(base + ".exr", ref), "integrator": how}]
    passes = s["ppm"]["history"]
    # Pass i ends at its elapsed seconds (the passes' own time) after the process's start-up
    # (scene load, reference load) and auto's pilot; the output is written at the end. The
    # comparison with the reference after every pass is the race's measuring, and not in
    # `elapsed`: with thousands of passes it is seconds, which an overhead taken as the
    # run's wall time less its last pass's elapsed charged to every pass, the first one
    # too. So the start-up and output are measured by a run of one pass without a
    # reference: its wall time less its stats' total (which holds the pilot).
    one = [a.replace(base, base + ".one") for a in run]  # its own outputs
    t1 = time.time()
    subprocess.run(one + ["--iterations", "1", "--stats", base + ".one.stats.json"],
                   check=True, capture_output=True)
    one_total = json.load(open(base + ".one.stats.json"))["times"]["total"]
    start_up = max(0.0, time.time() - t1 - one_total)
    overhead = start_up + s["times"].get("choose", 0.0)
    # Camera paths per second over the passes' render time (one path per pixel and pass;
    # the history thins out after its first passes: the count is the stats' own).
    paths_per_s = s["ppm"]["passes"] * W * H / max(s["times"]["render"], 1e-9)
    return [{"seconds": p["elapsed"] + overhead, "relmse": p["error"]["relmse"],
             "block_err": p["error"]["block_err"], "mean_ratio": p["error"]["mean_ratio"],
             "paths_per_s": paths_per_s, "integrator": how}
            for p in passes]


def host():
    """The machine the race ran on, for its tables (figures compare only within one host):
    the CPU's model name and the cores this process may use."""
    model = "unknown CPU"
    try:
        with open("/proc/cpuinfo") as f:
            model = next((l.split(":", 1)[1].strip() for l in f if l.startswith("model name")),
                         model)
    except OSError:
        pass
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    return f"{model}, {cores} cores"


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
                    default=["auto", "photon", "ppm", "ppm_gather", "pt", "lt", "bdpt", "vcm"])
    ap.add_argument("--scenes", nargs="*", default=list(SCENES),
                    help="built-in scenes to race (none: only --scene-files)")
    ap.add_argument("--scene-files", nargs="+", default=[],
                    help="other scenes to race (JSON; named by their file's stem, their goal "
                         "by whether they hold a mirror or glass; reference REFS/STEM.ref.exr)")
    ap.add_argument("--report-only", action="store_true",
                    help="print the tables and plots of OUT/points.json, render nothing")
    args = ap.parse_args()
    os.makedirs(args.out, exist_ok=True)
    host_file = os.path.join(args.out, "host.txt")
    if args.report_only:  # the host the points were measured on, if it was recorded
        machine = open(host_file).read().strip() if os.path.exists(host_file) else "unrecorded"
    else:
        machine = host()
        with open(host_file, "w") as f:
            f.write(machine + "\n")
    print(f"Host: {machine}", flush=True)
    if args.report_only:
        results = json.load(open(os.path.join(args.out, "points.json")))
        for name, r in results.items():  # the throughput from the stats, as measured
            stats = os.path.join(args.out, f"{name}.pt.stats.json")
            if "pt" in r["photonbox"] and os.path.exists(stats):
                s = json.load(open(stats))
                r["photonbox"]["pt"][-1]["paths_per_s"] = (
                    s["ppm"]["passes"] * W * H / max(s["times"]["render"], 1e-9))
        report(results, args.budgets)
        for name, r in results.items():
            for metric in ("relmse", "block_err"):
                plot(name, r, metric, os.path.join(args.out, f"{name}.{metric}.svg"))
        return 0
    scenes = {name: (os.path.join(ROOT, SCENES[name][0]), SCENES[name][1])
              for name in args.scenes}
    for path in args.scene_files:
        name = os.path.splitext(os.path.basename(path))[0]
        materials = json.load(open(path))["materials"].values()
        specular = any(m["type"] in ("mirror", "dielectric") for m in materials)
        scenes[name] = (os.path.abspath(path), specular)
    results = {}
    for name, (scene, caustics) in scenes.items():
        ref = os.path.join(args.refs, f"{name}.ref.exr")
        print(f"{name}:", flush=True)
        mi = mitsuba_ladder(name, scene, ref, args.budgets, args.out)
        curves = {}
        for integrator in args.integrators:
            curves[integrator] = (
                auto_runs(name, scene, ref, args.budgets, args.out) if integrator == "auto"
                else photonbox_runs(name, scene, ref, integrator, max(args.budgets), args.out))
            last = curves[integrator][-1]
            print(f"  {integrator}: {len(curves[integrator])} points, last "
                  f"{last['seconds']:.1f} s relmse {last['relmse']:.5f} "
                  f"block_err {last['block_err']:.5f}", flush=True)
        results[name] = {"caustics": caustics, "mitsuba": mi, "photonbox": curves}
        json.dump(results, open(os.path.join(args.out, "points.json"), "w"), indent=1)
    report(results, args.budgets)
    for name, r in results.items():
        for metric in ("relmse", "block_err"):
            plot(name, r, metric, os.path.join(args.out, f"{name}.{metric}.svg"))


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
    print("\n### Throughput: camera paths per second, pt against Mitsuba's path tracer\n")
    print("| scene | photonbox pt (passes x pixels / pass time) | Mitsuba (spp x pixels / render time, "
          "longest rung) | ratio |")
    print("|---|---|---|---|")
    for name, r in results.items():
        curve = r["photonbox"].get("pt")
        if not curve or "paths_per_s" not in curve[-1]:
            continue
        ours = curve[-1]["paths_per_s"]
        rung = max(r["mitsuba"], key=lambda p: p["seconds"])
        theirs = rung["spp"] * W * H / rung["seconds"]
        print(f"| {name} | {ours / 1e6:.2f} M/s | {theirs / 1e6:.2f} M/s | {ours / theirs:.2f} |")
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
                    # auto ran once per budget: the run that answers this one; where that
                    # run ends before Mitsuba's error, the longest run if it made the same
                    # choice (its passes are the same, run further: as every other row).
                    own = [p for p in curve if p.get("budget", b) == b]
                    t = time_to(own, metric, target) if target else None
                    if t is None and target and own and "budget" in own[-1]:
                        longest = max(p.get("budget", b) for p in curve)
                        same = [p for p in curve if p.get("budget", b) == longest
                                and p.get("integrator") == own[-1].get("integrator")]
                        t = time_to(same, metric, target)
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


COLORS = {"mitsuba": "#000000", "auto": "#d62728", "photon": "#8c564b", "ppm": "#9467bd",
          "pt": "#1f77b4", "lt": "#7f7f7f", "bdpt": "#2ca02c", "vcm": "#ff7f0e"}
EXTRA_COLORS = ["#17becf", "#e377c2", "#bcbd22", "#393b79"]


def plot(name, r, metric, path):
    """An SVG of `metric` against seconds, both log scales: Mitsuba's rungs and each of our
    integrators' pass curves (no plotting library: the venvs here carry none)."""
    series = {"mitsuba": [(p["seconds"], p[metric]) for p in r["mitsuba"]]}
    for integrator, curve in r["photonbox"].items():
        # auto's runs (one per budget) drawn as one curve through all their points.
        series[integrator] = sorted((p["seconds"], p[metric]) for p in curve)
    pts = [(t, e) for s in series.values() for t, e in s if t > 0 and e > 0]
    if not pts:
        return
    lx = [math.log10(t) for t, _ in pts]
    ly = [math.log10(e) for _, e in pts]
    x0, x1 = math.floor(min(lx)), math.ceil(max(lx))
    y0, y1 = math.floor(min(ly)), math.ceil(max(ly))
    w, h, m = 640, 400, 60
    def sx(t): return m + (math.log10(t) - x0) / max(x1 - x0, 1e-9) * (w - 2 * m)
    def sy(e): return h - m - (math.log10(e) - y0) / max(y1 - y0, 1e-9) * (h - 2 * m)
    out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{h}" '
           f'font-family="sans-serif" font-size="11">',
           f'<rect width="{w}" height="{h}" fill="white"/>',
           f'<text x="{w / 2}" y="18" text-anchor="middle" font-size="13">{name}: {metric} '
           f'against seconds (log-log)</text>']
    for k in range(x0, x1 + 1):
        x = sx(10 ** k)
        out.append(f'<line x1="{x:.1f}" y1="{m}" x2="{x:.1f}" y2="{h - m}" stroke="#ddd"/>')
        out.append(f'<text x="{x:.1f}" y="{h - m + 15}" text-anchor="middle">{10 ** k:g} s</text>')
    for k in range(y0, y1 + 1):
        y = sy(10 ** k)
        out.append(f'<line x1="{m}" y1="{y:.1f}" x2="{w - m}" y2="{y:.1f}" stroke="#ddd"/>')
        out.append(f'<text x="{m - 5}" y="{y + 4:.1f}" text-anchor="end">{10 ** k:g}</text>')
    for i, (label, s) in enumerate(series.items()):
        s = [(t, e) for t, e in sorted(s) if t > 0 and e > 0]
        if not s:
            continue
        # Other builds' curves (auto_<commit>), each in a colour of its own.
        color = COLORS.get(label, EXTRA_COLORS[i % len(EXTRA_COLORS)])
        line = " ".join(f"{sx(t):.1f},{sy(e):.1f}" for t, e in s)
        dash = ' stroke-dasharray="6,3"' if label == "mitsuba" else ""
        out.append(f'<polyline points="{line}" fill="none" stroke="{color}" '
                   f'stroke-width="1.5"{dash}/>')
        out.append(f'<text x="{w - m + 5}" y="{m + 14 * i}" fill="{color}">{label}</text>')
    out.append("</svg>")
    with open(path, "w") as f:
        f.write("\n".join(out) + "\n")


if __name__ == "__main__":
    sys.exit(main())

#!/usr/bin/env python3
"""Tables of docs/accuracy.md from the sweeps of docs/accuracy/regen.sh.

    python3 docs/accuracy/tables.py docs/accuracy [target/equal_error/points.jsonl]

Writes DIR/tables.md and prints it. Standard library only.
"""
import csv
import json
import math
import os
import sys


def rows(path):
    with open(path) as f:
        return list(csv.DictReader(f))


def fit(points):
    """Least-squares slope of log y against log x."""
    pts = [(math.log(x), math.log(y)) for x, y in points if x > 0 and y > 0]
    if len(pts) < 2:
        return float("nan")
    n = len(pts)
    mx = sum(p[0] for p in pts) / n
    my = sum(p[1] for p in pts) / n
    sxx = sum((p[0] - mx) ** 2 for p in pts)
    return sum((p[0] - mx) * (p[1] - my) for p in pts) / sxx


def f(x, d=4):
    return f"{float(x):.{d}f}"


def sec(x):
    x = float(x)
    return f"{x * 1000:.0f} ms" if x < 1 else f"{x:.2f} s"


def grid_table(out, title, path, key, label):
    r = rows(path)
    out.append(f"**{title}**\n")
    out.append(f"| {label} | photons + trees | render | total | relmse | block_err | mean_ratio |")
    out.append("|---|---|---|---|---|---|---|")
    for x in r:
        build = float(x["photon_trace_s"]) + float(x["build_maps_s"])
        render = float(x["precompute_s"]) + float(x["render_s"])
        out.append(
            f"| {x[key]} | {sec(build)} | {sec(render)} | {sec(x['total_s'])} | "
            f"{f(x['relmse'])} | {f(x['block_err'])} | {f(x['mean_ratio'])} |"
        )
    out.append("")


def passes_table(out, title, path, combination="0"):
    p = [x for x in rows(path) if x["combination"] == combination]
    out.append(f"**{title}**\n")
    out.append("| pass | elapsed | radius global / caustic | relmse | block_err | mean_ratio |")
    out.append("|---|---|---|---|---|---|")
    for x in p:
        if int(x["pass"]) in (1, 2, 4, 8, 16, 32, 64, 128, 256):
            out.append(
                f"| {x['pass']} | {sec(x['elapsed_s'])} | {f(x['radius_global'])} / "
                f"{f(x['radius_caustic'])} | {f(x['relmse'])} | {f(x['block_err'])} | "
                f"{f(x['mean_ratio'])} |"
            )
    sr = fit([(float(x["pass"]), float(x["relmse"])) for x in p if int(x["pass"]) >= 4])
    sb = fit([(float(x["pass"]), float(x["block_err"])) for x in p if int(x["pass"]) >= 4])
    out.append(f"\nLog-log slope from pass 4 on: relmse {sr:.2f}, block_err {sb:.2f}.\n")
    return p


def equal_time_table(out, d):
    ph = rows(os.path.join(d, "photon_defaults", "results.csv"))[0]
    eq = rows(os.path.join(d, "equal_time", "results.csv"))
    out.append(f"**Equal time ({sec(ph['total_s'])}, the time of `photon` at its defaults)**\n")
    out.append("| integrator | passes | total | relmse | block_err | mean_ratio |")
    out.append("|---|---|---|---|---|---|")
    for x in [ph] + eq:
        out.append(
            f"| {x['integrator']} | {x['passes']} | {sec(x['total_s'])} | {f(x['relmse'])} | "
            f"{f(x['block_err'])} | {f(x['mean_ratio'])} |"
        )
    out.append("")


def mitsuba_time(points, metric, target):
    ps = sorted((p for p in points if p["renderer"] == "mitsuba"), key=lambda p: p["seconds"])
    for a, b in zip(ps, ps[1:]):
        if a[metric] > target >= b[metric]:
            t = math.log(a[metric] / target) / math.log(a[metric] / b[metric])
            return a["seconds"] * (b["seconds"] / a["seconds"]) ** t
    return ps[0]["seconds"] if ps and ps[0][metric] <= target else None


def ppm_time(passes, metric, target):
    for x in passes:
        if float(x[metric]) <= target:
            return float(x["elapsed_s"])
    return None


def main():
    d = sys.argv[1]
    points_path = sys.argv[2] if len(sys.argv) > 2 else None
    out = []
    for name in ["cornell", "cornell_mirror_glass_twin", "cornell_spheres", "glass_orange_twin",
                 "knot", "phong_spheres"]:
        s = os.path.join(d, name)
        if not os.path.isdir(s):
            continue
        out.append(f"### {name}\n")
        grid_table(out, "n photons per map, k = 10", os.path.join(s, "photons", "results.csv"),
                   "grid_n", "n")
        grid_table(out, "k at n = 100k", os.path.join(s, "k", "results.csv"), "grid_k", "k")
        passes_table(out, "ppm passes (100k + 100k photons per pass)",
                     os.path.join(s, "ppm", "passes.csv"))
        equal_time_table(out, s)
    conv = os.path.join(d, "convergence")
    if os.path.exists(os.path.join(conv, "results.csv")):
        out.append("### Convergence on the caustic scene (cornell_mirror_glass_twin)\n")
        p = passes_table(out, "ppm, 400k global + 2M caustic photons per pass",
                         os.path.join(conv, "passes.csv"))
        r = rows(os.path.join(conv, "results.csv"))
        out.append("| render | total | relmse | block_err | mean_ratio |")
        out.append("|---|---|---|---|---|")
        for x in r:
            what = (f"ppm, {x['passes']} passes" if x["integrator"] == "ppm"
                    else "photon, one render with the same photons (k = 50, G = 8, 4 spp)")
            out.append(f"| {what} | {sec(x['total_s'])} | {f(x['relmse'])} | "
                       f"{f(x['block_err'])} | {f(x['mean_ratio'])} |")
        out.append("")
        if points_path and os.path.exists(points_path):
            pts = [json.loads(l) for l in open(points_path)]
            default_ppm = rows(os.path.join(d, "cornell_mirror_glass_twin", "ppm", "passes.csv"))
            out.append("**Equal error against Mitsuba 3 (path tracing), time to reach a target**\n")
            out.append("| metric | target | Mitsuba 3 | ppm (100k + 100k / pass) | ppm (400k + 2M / pass) |")
            out.append("|---|---|---|---|---|")
            for metric, mi_metric, targets in (("relmse", "relmse", (0.05, 0.03, 0.02)),
                                               ("block_err", "block_err", (0.05, 0.03, 0.02))):
                for t in targets:
                    m = mitsuba_time(pts, mi_metric, t)
                    a = ppm_time(default_ppm, metric, t)
                    b = ppm_time(p, metric, t)
                    cell = lambda x: "not reached" if x is None else sec(x)
                    out.append(f"| {metric} | {t} | {cell(m)} | {cell(a)} | {cell(b)} |")
            out.append("")
    text = "\n".join(out)
    with open(os.path.join(d, "tables.md"), "w") as fh:
        fh.write("<!-- generated by docs/accuracy/regen.sh (tables.py); do not edit -->\n\n" + text)
    print(text)


if __name__ == "__main__":
    main()

#!/usr/bin/env python3
"""A Mitsuba 3 light-tracing reference for photonbox's `lt` (issue 20, acceptance 1).

    ../shared/refcheck/run ../../docs/validation/ptracer_ref.py SCENE.json OUT.exr --spp N \
        [--width W --height H] [--seed S] [--pass-spp P]
    (or run it with refcheck's venv python: docs/validation/lt_agreement.sh does)

Light tracing connects each vertex of a light path to the pinhole camera. A pinhole is a
delta sensor, so no light tracer can carry a path whose camera end is specular: what the
camera sees in a mirror or through glass is black in its image (Veach 1997, section 10.2;
Mitsuba's `ptracer` documents the same). `lt` therefore cannot agree with a path-traced
reference on a scene with visible mirrors or glass, by construction. This renders the scene
with Mitsuba's own light tracer (`ptracer`, the same paths left out), the scene converted by
../shared/refcheck/mi_convert.py as for every other reference, so that `lt` is checked
against an independent renderer of the same technique.
"""
import argparse
import json
import os
import sys
import tempfile
import time

REFCHECK = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "..", "shared",
                        "refcheck")
sys.path.insert(0, os.path.abspath(REFCHECK))
import numpy as np  # noqa: E402

from mi_convert import DEFAULT_MAX_DEPTH, init_mitsuba, load_contract, to_mitsuba_dict  # noqa: E402
from imgio import write_image  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("scene")
    ap.add_argument("out")
    ap.add_argument("--spp", type=int, required=True)
    ap.add_argument("--width", type=int)
    ap.add_argument("--height", type=int)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--pass-spp", type=int, default=64)
    ap.add_argument("--stats", default=None)
    args = ap.parse_args()

    mi = init_mitsuba(None)
    s = load_contract(args.scene)
    base = os.path.dirname(os.path.abspath(args.scene))
    with tempfile.TemporaryDirectory(prefix="ptracer_ref_") as td:
        d = to_mitsuba_dict(s, base, td, spp=args.pass_spp, width=args.width,
                            height=args.height, mi=mi)
        d["integrator"] = {"type": "ptracer", "max_depth": DEFAULT_MAX_DEPTH, "rr_depth": 5,
                           "hide_emitters": False}
        scene = mi.load_dict(d)
    t = time.time()
    acc, done, k = None, 0, 0
    while done < args.spp:
        n = min(args.pass_spp, args.spp - done)
        img = np.asarray(mi.render(scene, spp=n, seed=args.seed * 100003 + k),
                         dtype=np.float64)[..., :3]
        acc = img * n if acc is None else acc + img * n
        done, k = done + n, k + 1
    seconds = time.time() - t
    img = (acc / done).astype(np.float32)
    write_image(args.out, img)
    stats = {"scene": args.scene, "integrator": "ptracer", "variant": mi.variant(), "spp": done,
             "seed": args.seed, "render_seconds": round(seconds, 3),
             "mean_rgb": [float(x) for x in img.reshape(-1, 3).mean(0)],
             "nonfinite": int((~np.isfinite(img)).sum())}
    print(json.dumps(stats))
    if args.stats:
        with open(args.stats, "w") as f:
            json.dump(stats, f, indent=1)


if __name__ == "__main__":
    main()

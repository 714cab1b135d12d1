#!/usr/bin/env python3
"""Two users share a server that renders one job at a time: each submits an `auto` job of
the same scene, and they take turns pass by pass (a running job gives way after a pass
when another user waits, and resumes from its state). Prints the wall time until both are
done and what each job's stats say (passes, render seconds, `times.choose`).

    python3 docs/validation/shared_auto.py [--bin target/release/photonbox]
        [--scene cornell_spheres] [--size 256] [--iterations 16]

The server runs on a free port with a fresh data folder under /tmp, and is stopped after.
"""
import argparse
import json
import os
import re
import subprocess
import tempfile
import time
import urllib.request

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))


def call(url, token, body=None):
    req = urllib.request.Request(url, data=None if body is None else json.dumps(body).encode(),
                                 headers={"Authorization": f"Bearer {token}",
                                          "Content-Type": "application/json"},
                                 method="GET" if body is None else "POST")
    with urllib.request.urlopen(req) as r:
        return json.loads(r.read())


def main():
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bin", default=os.path.join(ROOT, "target", "release", "photonbox"))
    ap.add_argument("--scene", default="cornell_spheres")
    ap.add_argument("--size", type=int, default=256)
    ap.add_argument("--iterations", type=int, default=16)
    args = ap.parse_args()
    data = tempfile.mkdtemp(prefix="shared_auto.")
    tokens = []
    for name in ("ada", "bob"):
        out = subprocess.run([args.bin, "user", "add", name, "--data", data], check=True,
                             capture_output=True, text=True).stdout
        tokens.append(out.split()[-1])
    server = subprocess.Popen([args.bin, "serve", "--addr", "127.0.0.1:0", "--data", data,
                               "--scenes", os.path.join(ROOT, "scenes"), "--max-running", "1"],
                              stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        base = None
        for line in server.stdout:
            m = re.search(r"http://127\.0\.0\.1:\d+", line)
            if m:
                base = m.group(0)
                break
        params = {"integrator": "auto", "width": args.size, "height": args.size,
                  "iterations": args.iterations}
        t0 = time.time()
        jobs = [call(f"{base}/api/jobs", t, {"scene_name": args.scene, "params": params})["id"]
                for t in tokens]
        while True:
            states = [call(f"{base}/api/jobs/{j}", t) for j, t in zip(jobs, tokens)]
            if all(s["status"] in ("done", "failed", "cancelled") for s in states):
                break
            time.sleep(0.05)
        wall = time.time() - t0
        print(f"{args.scene} {args.size}x{args.size}, 2 users, {args.iterations} passes each, "
              f"one job at a time: both done in {wall:.2f} s")
        for s in states:
            st = s.get("stats") or {}
            times = st.get("times", {})
            print(f"  job {s['id']}: {s['status']}, passes {st.get('ppm', {}).get('passes')}, "
                  f"render {times.get('render', 0):.2f} s, choose {times.get('choose', 'n/a')}, "
                  f"{st.get('effects', {}).get('integrator', {}).get('how')}")
    finally:
        server.terminate()
        server.wait()


if __name__ == "__main__":
    main()

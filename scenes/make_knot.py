#!/usr/bin/env python3
"""Write scenes/knot.obj: a (2,3) torus knot tube, 1024 x 56 quads = 114,688 triangles.

    python3 scenes/make_knot.py

Counter-clockwise seen from outside (outward normals), watertight (the tube closes on itself).
The scene format has no transforms, so the knot is written where scenes/knot.json wants it:
scaled by SCALE and centred at CENTRE, inside the Cornell box.
"""
import math
import os

P, Q = 2, 3
SEG, RING, TUBE = 1024, 56, 0.42
SCALE, CENTRE = 0.45, (2.78, 2.5, 2.8)


def curve(t):
    r = math.cos(Q * t) + 2.0
    return (r * math.cos(P * t), r * math.sin(P * t), -math.sin(Q * t))


def sub(a, b):
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


def cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def norm(a):
    l = math.sqrt(a[0] ** 2 + a[1] ** 2 + a[2] ** 2)
    return (a[0] / l, a[1] / l, a[2] / l)


def main():
    verts = []
    for i in range(SEG):
        t = 2 * math.pi * i / SEG
        c = curve(t)
        tangent = norm(sub(curve(t + 1e-4), curve(t - 1e-4)))
        # A frame from the curve's offset from the knot's axis: smooth for this knot.
        radial = norm((c[0], c[1], 0.0))
        b = norm(cross(tangent, radial))
        n = cross(b, tangent)
        for j in range(RING):
            a = 2 * math.pi * j / RING
            ca, sa = math.cos(a), math.sin(a)
            verts.append(tuple(CENTRE[k] + SCALE * (c[k] + TUBE * (ca * n[k] + sa * b[k]))
                               for k in range(3)))
    faces = []
    for i in range(SEG):
        i2 = (i + 1) % SEG
        for j in range(RING):
            j2 = (j + 1) % RING
            a, b_, c_, d = i * RING + j, i2 * RING + j, i2 * RING + j2, i * RING + j2
            faces.append((a, d, c_))
            faces.append((a, c_, b_))
    out = os.path.join(os.path.dirname(os.path.abspath(__file__)), "knot.obj")
    with open(out, "w") as f:
        f.write(f"# (2,3) torus knot, {len(verts)} vertices, {len(faces)} triangles (make_knot.py)\n")
        for v in verts:
            f.write("v %.4f %.4f %.4f\n" % v)
        for a, b_, c_ in faces:
            f.write(f"f {a + 1} {b_ + 1} {c_ + 1}\n")
    print(out, len(verts), "vertices", len(faces), "triangles")


if __name__ == "__main__":
    main()

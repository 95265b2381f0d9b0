#!/usr/bin/env python3
"""Writes scenes/meshes/torus.obj: a closed torus (ring radius 0.45 m, tube radius 0.15 m, lying
in the xz plane, centred at the origin), 48 x 24 quads with outward faces. The mesh collider of
scenes/mesh.ron; generated here, so it is the project's own (MIT OR Apache-2.0)."""
import math
import sys

R, r, SEGMENTS, RINGS = 0.45, 0.15, 48, 24
lines = [
    "# A torus: ring radius 0.45 m, tube radius 0.15 m, in the xz plane, 48 x 24 quads.",
    "# Written by scripts/torus-obj.py (the project's own, MIT OR Apache-2.0).",
]
for i in range(SEGMENTS):
    u = 2 * math.pi * i / SEGMENTS
    for j in range(RINGS):
        v = 2 * math.pi * j / RINGS
        x = (R + r * math.cos(v)) * math.cos(u)
        z = (R + r * math.cos(v)) * math.sin(u)
        y = r * math.sin(v)
        lines.append(f"v {x:.6f} {y:.6f} {z:.6f}")
def index(i, j):
    return (i % SEGMENTS) * RINGS + (j % RINGS) + 1
for i in range(SEGMENTS):
    for j in range(RINGS):
        a, b, c, d = index(i, j), index(i + 1, j), index(i + 1, j + 1), index(i, j + 1)
        # Counter-clockwise seen from outside: the normal points away from the tube's axis.
        lines.append(f"f {a} {d} {c} {b}")
out = sys.argv[1] if len(sys.argv) > 1 else "scenes/meshes/torus.obj"
with open(out, "w") as f:
    f.write("\n".join(lines) + "\n")

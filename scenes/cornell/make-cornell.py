#!/usr/bin/env python3
"""Writes cornell.obj and cornell.mtl: a Cornell-style box (red left wall,
green right wall, white floor, ceiling and back wall, open to the camera
at z = 0), two white blocks, and a glowing panel under the ceiling whose
MTL material gives off light (Ke). Units: the box is 5.5 on a side.
Run from this folder: python3 make-cornell.py"""

import math

S = 5.5
vertices = []
faces = []  # (material, [vertex numbers])


def quad(material, corners):
    base = len(vertices) + 1
    vertices.extend(corners)
    faces.append((material, [base, base + 1, base + 2, base + 3]))


def block(x, z, width, depth, height, turn_deg):
    """A box standing on the floor, centred on (x, z), turned about y."""
    c, s = math.cos(math.radians(turn_deg)), math.sin(math.radians(turn_deg))

    def at(dx, y, dz):
        return (x + c * dx + s * dz, y, z - s * dx + c * dz)

    w, d = width / 2, depth / 2
    ring = [(-w, -d), (w, -d), (w, d), (-w, d)]
    for i in range(4):
        (ax, az), (bx, bz) = ring[i], ring[(i + 1) % 4]
        quad("block", [at(ax, 0, az), at(bx, 0, bz), at(bx, height, bz), at(ax, height, az)])
    quad("block", [at(dx, height, dz) for dx, dz in reversed(ring)])


quad("white", [(0, 0, 0), (S, 0, 0), (S, 0, S), (0, 0, S)])  # floor
quad("white", [(0, S, 0), (0, S, S), (S, S, S), (S, S, 0)])  # ceiling
quad("white", [(0, 0, S), (S, 0, S), (S, S, S), (0, S, S)])  # back wall
# Seen from the camera at z < 0, +x is on the left.
quad("red", [(S, 0, 0), (S, S, 0), (S, S, S), (S, 0, S)])  # left wall
quad("green", [(0, 0, 0), (0, 0, S), (0, S, S), (0, S, 0)])  # right wall
# The panel hangs a little below the ceiling, facing down.
y = S - 0.01
quad("light", [(1.75, y, 2.0), (1.75, y, 3.6), (3.75, y, 3.6), (3.75, y, 2.0)])
block(3.7, 3.6, 1.65, 1.65, 3.3, 17.0)
block(1.9, 2.1, 1.65, 1.65, 1.65, -17.0)

with open("cornell.obj", "w") as f:
    f.write("# Made by make-cornell.py: a Cornell-style box lit by a glowing panel.\n")
    f.write("mtllib cornell.mtl\n")
    for v in vertices:
        f.write("v {:.4f} {:.4f} {:.4f}\n".format(*v))
    current = None
    for material, corners in faces:
        if material != current:
            f.write(f"usemtl {material}\n")
            current = material
        f.write("f " + " ".join(str(i) for i in corners) + "\n")

with open("cornell.mtl", "w") as f:
    f.write("# Made by make-cornell.py.\n")
    for name, kd in [
        ("white", (0.73, 0.71, 0.68)),
        ("red", (0.63, 0.065, 0.05)),
        ("green", (0.14, 0.45, 0.091)),
        ("block", (0.73, 0.71, 0.68)),
    ]:
        f.write(f"newmtl {name}\nKd {kd[0]} {kd[1]} {kd[2]}\nKs 0 0 0\nillum 1\n\n")
    # The panel: its glow (Ke) is what lights the box.
    f.write("newmtl light\nKd 0.78 0.78 0.78\nKe 12 10 8\nillum 1\n")

#!/usr/bin/python3
"""Writes this folder's potted plant (generated here, so free of any
licence): leaves.png, a frond of leaflets on a transparent background
(RGBA: its alpha is the cut-out), and plant.obj / plant.mtl, crossed cards
carrying the frond, whose material names the image both as its colour
(map_Kd) and as its cut-out (map_d), as exporters write leaves."""
import math
import random

from PIL import Image, ImageDraw

random.seed(7)

# The frond: a stem up the middle of the image, leaflets either side.
width, height = 128, 256
frond = Image.new("RGBA", (width, height), (0, 0, 0, 0))
draw = ImageDraw.Draw(frond)
stem = (70, 90, 40, 255)
draw.line([(width // 2, height - 1), (width // 2, 8)], fill=stem, width=3)
for k in range(14):
    y = height - 24 - k * 16
    length = 56 * math.sin(math.pi * (k + 1.5) / 16)
    for side in (-1, 1):
        green = (40 + random.randint(0, 30), 110 + random.randint(0, 50), 35, 255)
        # A leaflet: a thin ellipse leaning up and out from the stem.
        points = []
        for i in range(24):
            a = 2 * math.pi * i / 24
            along = (math.cos(a) + 1) * 0.5 * length
            across = math.sin(a) * 5.5
            x = width / 2 + side * along
            yy = y - along * 0.45 + across
            points.append((x, yy))
        draw.polygon(points, fill=green)
        draw.line([(width / 2, y), (width / 2 + side * length, y - length * 0.45)],
                  fill=(30, 80, 25, 255), width=1)
frond.save("leaves.png", optimize=True)

# Crossed cards around the stem, leaning outwards: each a quad 0.9 wide and
# 1.6 tall whose texture coordinates cover the frond.
vertices, texcoords, faces = [], [], []
cards = 7
for card in range(cards):
    turn = 2 * math.pi * card / cards + random.uniform(-0.2, 0.2)
    lean = math.radians(random.uniform(18, 34))
    tall = random.uniform(1.2, 1.6)
    half = 0.45
    # Card axes: across (horizontal, perpendicular to its outward
    # direction) and up (tilted outwards by `lean`).
    out = (math.cos(turn), 0.0, math.sin(turn))
    across = (-math.sin(turn), 0.0, math.cos(turn))
    up = (out[0] * math.sin(lean), math.cos(lean), out[2] * math.sin(lean))
    base = len(vertices)
    for (s, t) in ((-1, 0), (1, 0), (1, 1), (-1, 1)):
        p = [across[i] * half * s + up[i] * tall * t for i in range(3)]
        p[1] += 0.45  # the pot's rim
        vertices.append(p)
        texcoords.append(((s + 1) / 2, t))
    faces.append((base + 1, base + 2, base + 3, base + 4))

with open("plant.obj", "w") as obj:
    obj.write("# A potted plant's leaves: crossed cards cut out by leaves.png.\n")
    obj.write("mtllib plant.mtl\nusemtl frond\n")
    for v in vertices:
        obj.write("v %.4f %.4f %.4f\n" % tuple(v))
    for t in texcoords:
        obj.write("vt %.4f %.4f\n" % t)
    for f in faces:
        obj.write("f " + " ".join("%d/%d" % (i, i) for i in f) + "\n")

with open("plant.mtl", "w") as mtl:
    mtl.write("newmtl frond\nKd 1 1 1\nKs 0.05 0.05 0.05\nNs 10\n")
    mtl.write("map_Kd leaves.png\nmap_d leaves.png\n")

#!/usr/bin/python3
"""Writes this folder's two textures (generated here, so free of any
licence): tiles.png, a floor of glazed tiles with fine stripes that alias
at a distance unless filtered, and crate.png, the planks of a crate."""
import math
import random

from PIL import Image, ImageDraw

random.seed(31)

size = 256
tiles = Image.new("RGB", (size, size))
px = tiles.load()
colours = [(180, 60, 50), (230, 205, 140), (60, 110, 160), (235, 235, 225)]
for y in range(size):
    for x in range(size):
        tx, ty = x // 64, y // 64
        c = colours[(tx + 2 * ty) % 4]
        gx, gy = x % 64, y % 64
        if gx < 3 or gy < 3:
            c = (40, 40, 40)  # grout
        elif (gx + gy) % 8 < 2:
            c = tuple(int(v * 0.6) for v in c)  # fine diagonal stripes
        px[x, y] = c
tiles.save("tiles.png", optimize=True)

crate = Image.new("RGB", (size, size), (150, 100, 55))
draw = ImageDraw.Draw(crate)
for plank in range(4):
    y0 = plank * 64
    base = 120 + random.randint(-15, 15)
    for y in range(y0, y0 + 64):
        for x in range(size):
            grain = 18 * math.sin(x * 0.09 + 3 * math.sin(y * 0.21 + plank))
            v = base + grain + random.randint(-6, 6)
            crate.putpixel((x, y), (int(v * 1.25), int(v * 0.85), int(v * 0.45)))
    draw.line([(0, y0), (size, y0)], fill=(50, 30, 15), width=3)
draw.rectangle([0, 0, size - 1, size - 1], outline=(60, 35, 18), width=14)
draw.line([(14, 14), (size - 14, size - 14)], fill=(95, 60, 30), width=16)
crate.save("crate.png", optimize=True)

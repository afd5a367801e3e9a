#!/usr/bin/python3
"""Writes this folder's relief maps (generated here, so free of any
licence): bricks.png and bricks-height.png, the colour and height map of a
brick wall (staggered bricks, 64 x 32 texels, sunk mortar joints with
rounded edges), and tiles-normal.png, a tangent-space normal map of
tiles.png's tiles with bevelled edges (red along u, green up the image).
Height and normal maps are data: written as plain bytes, read without the
sRGB curve."""
import math
import random

from PIL import Image

random.seed(48)

size = 256
brick_w, brick_h, mortar, bevel = 64, 32, 4, 5

colour = Image.new("RGB", (size, size))
height = Image.new("L", (size, size))
cpx, hpx = colour.load(), height.load()
tints = {}
for y in range(size):
    row = y // brick_h
    shift = (brick_w // 2) * (row % 2)
    for x in range(size):
        bx = (x + shift) % size
        col = bx // brick_w
        gx, gy = bx % brick_w, y % brick_h
        # Distance into the brick from its nearest joint, in texels.
        inside = min(gx - mortar / 2, brick_w - mortar / 2 - gx,
                     gy - mortar / 2, brick_h - mortar / 2 - gy)
        if (row, col) not in tints:
            tints[(row, col)] = random.uniform(0.8, 1.15)
        if inside < 0:
            cpx[x, y] = (150, 145, 135)
            hpx[x, y] = 20 + random.randint(0, 8)
        else:
            t = tints[(row, col)]
            n = random.randint(-10, 10)
            cpx[x, y] = (int(min(255, 165 * t + n)), int(70 * t + n / 2), int(50 * t + n / 3))
            edge = min(1.0, inside / bevel)
            rounded = math.sin(edge * math.pi / 2)
            hpx[x, y] = int(70 + 170 * rounded + random.randint(-6, 6))
colour.save("bricks.png", optimize=True)
height.save("bricks-height.png", optimize=True)

# tiles.png: 64-texel tiles with 3 texels of grout at their top and left.
normal = Image.new("RGB", (size, size))
npx = normal.load()
tile, grout, slope = 64, 3, 8
for y in range(size):
    for x in range(size):
        gx, gy = x % tile, y % tile
        nx = ny = 0.0
        if gx >= grout and gy >= grout:
            left, right = gx - grout, tile - 1 - gx
            top, bottom = gy - grout, tile - 1 - gy
            if left < slope:
                nx -= 0.8 * (1 - left / slope)
            if right < slope:
                nx += 0.8 * (1 - right / slope)
            # Green is up the image: the top edge leans up, the bottom down.
            if top < slope:
                ny += 0.8 * (1 - top / slope)
            if bottom < slope:
                ny -= 0.8 * (1 - bottom / slope)
        nz = math.sqrt(max(0.0, 1 - nx * nx - ny * ny))
        length = math.sqrt(nx * nx + ny * ny + nz * nz)
        byte = lambda c: max(0, min(255, round(128 + 127 * c / length)))
        npx[x, y] = (byte(nx), byte(ny), byte(nz))
normal.save("tiles-normal.png", optimize=True)

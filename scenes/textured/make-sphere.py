#!/usr/bin/python3
"""Writes sphere.obj: a unit sphere tessellated by latitude and longitude
(48 x 24 quads, each cut in two), its vertex normals the sphere's own, so
it renders smooth and its curvature as the ray cones see it is the
sphere's. No texture coordinates: it is a mirror or glass in the scenes."""
import math

SEGMENTS, RINGS = 48, 24
lines = ["# A unit sphere, 48 x 24, smooth: written by make-sphere.py"]
for ring in range(RINGS + 1):
    theta = math.pi * ring / RINGS
    for segment in range(SEGMENTS):
        phi = 2 * math.pi * segment / SEGMENTS
        p = (math.sin(theta) * math.cos(phi), math.cos(theta), -math.sin(theta) * math.sin(phi))
        lines.append("v %.6f %.6f %.6f" % p)
        lines.append("vn %.6f %.6f %.6f" % p)
for ring in range(RINGS):
    for segment in range(SEGMENTS):
        a = ring * SEGMENTS + segment + 1
        b = ring * SEGMENTS + (segment + 1) % SEGMENTS + 1
        c, d = a + SEGMENTS, b + SEGMENTS
        if ring > 0:
            lines.append("f %d//%d %d//%d %d//%d" % (a, a, c, c, b, b))
        if ring < RINGS - 1:
            lines.append("f %d//%d %d//%d %d//%d" % (b, b, c, c, d, d))
with open("sphere.obj", "w") as f:
    f.write("\n".join(lines) + "\n")

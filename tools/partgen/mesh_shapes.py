"""Small closed meshes built in code (prisms over simple polygons), for the tests.

Units are mm. A prism is the polygon (counter-clockwise, no holes) swept from
z = 0 to z = height; faces wind outward.
"""

import math

import numpy as np


def _cross2(o, a, b):
    return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])


def ear_clip(poly):
    """Triangulates a simple counter-clockwise polygon; returns index triples."""
    idx = list(range(len(poly)))
    tris = []
    guard = 0
    while len(idx) > 3 and guard < 10 * len(poly) ** 2:
        guard += 1
        n = len(idx)
        for k in range(n):
            i0, i1, i2 = idx[k - 1], idx[k], idx[(k + 1) % n]
            a, b, c = poly[i0], poly[i1], poly[i2]
            if _cross2(a, b, c) <= 1e-12:
                continue
            inside = False
            for j in idx:
                if j in (i0, i1, i2):
                    continue
                p = poly[j]
                if _cross2(a, b, p) >= 0 and _cross2(b, c, p) >= 0 and _cross2(c, a, p) >= 0:
                    inside = True
                    break
            if not inside:
                tris.append((i0, i1, i2))
                del idx[k]
                break
    tris.append(tuple(idx))
    return tris


def prism(poly, height):
    """Closed mesh (V, F) of a polygon extruded along +z."""
    poly = [tuple(map(float, p)) for p in poly]
    n = len(poly)
    V = np.array([(x, y, 0.0) for x, y in poly] + [(x, y, float(height)) for x, y in poly])
    F = []
    for a, b, c in ear_clip(poly):
        F.append((a, c, b))              # bottom, facing -z
        F.append((a + n, b + n, c + n))  # top, facing +z
    for i in range(n):
        j = (i + 1) % n
        F.append((i, j, j + n))
        F.append((i, j + n, i + n))
    return V, np.array(F, dtype=np.int64)


def regular_polygon(n, r, phase=0.0):
    return [(r * math.cos(phase + 2 * math.pi * k / n), r * math.sin(phase + 2 * math.pi * k / n))
            for k in range(n)]


def rectangle(sx, sy):
    return [(-sx / 2, -sy / 2), (sx / 2, -sy / 2), (sx / 2, sy / 2), (-sx / 2, sy / 2)]


def rectangle_with_notch(sx, sy, notch_x, notch_w, notch_d):
    """Rectangle centred at 0 with a notch (width notch_w, depth notch_d) cut into
    its +y edge, centred at x = notch_x."""
    x0, x1 = notch_x - notch_w / 2, notch_x + notch_w / 2
    return [(-sx / 2, -sy / 2), (sx / 2, -sy / 2), (sx / 2, sy / 2),
            (x1, sy / 2), (x1, sy / 2 - notch_d), (x0, sy / 2 - notch_d), (x0, sy / 2),
            (-sx / 2, sy / 2)]


def circle_with_keyway(n, r, key_w, key_d, flat_y=None):
    """n-gon circle of radius r with a rectangular key slot of width key_w cut
    key_d deep at +x; with flat_y, also a flat (chord) at y = flat_y > key_w / 2."""
    half = math.asin(key_w / 2 / r)
    pts = [(r - key_d, -key_w / 2), (r - key_d, key_w / 2)]
    cut = None if flat_y is None else (math.asin(flat_y / r), math.pi - math.asin(flat_y / r))
    for k in range(n + 1):
        t = half + (2 * math.pi - 2 * half) * k / n
        if cut and cut[0] < t < cut[1]:
            continue
        pts.append((r * math.cos(t), r * math.sin(t)))
        if cut and k < n and t <= cut[0] < half + (2 * math.pi - 2 * half) * (k + 1) / n:
            pts.append((r * math.cos(cut[0]), flat_y))
            pts.append((r * math.cos(cut[1]), flat_y))
    return pts


def centred(V, F):
    """Mesh shifted so its bounding box is centred at the origin."""
    return V - (V.min(0) + V.max(0)) / 2, F

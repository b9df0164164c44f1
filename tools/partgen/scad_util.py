"""Parameter drawing and OpenSCAD text helpers shared by the part families.

Units: mm and degrees (OpenSCAD's) in the emitted source; radians only inside Python
maths. Every number printed goes through num(), so the same parameters always give
byte-identical source.
"""

import math
import random

GOLDEN = 0.6180339887498949
SIZE_MIN, SIZE_MAX = 15.0, 120.0


class Draw:
    """Seeded parameter draws, recorded by name in self.params (the part's record).

    Only random.Random.random() is used, whose sequence Python keeps stable.
    """

    def __init__(self, seed):
        self.rng = random.Random(seed)
        self.params = {}

    def _put(self, name, value):
        if name in self.params:
            raise KeyError(f"parameter {name} drawn twice")
        self.params[name] = value
        return value

    def uniform(self, name, lo, hi, digits=2):
        return self._put(name, round(lo + (hi - lo) * self.rng.random(), digits))

    def integer(self, name, lo, hi):
        """Uniform integer in [lo, hi]."""
        return self._put(name, min(hi, lo + int(self.rng.random() * (hi - lo + 1))))

    def chance(self, name, p):
        return self._put(name, self.rng.random() < p)

    def choice(self, name, options, weights=None):
        weights = weights or [1.0] * len(options)
        x = self.rng.random() * sum(weights)
        for opt, w in zip(options, weights):
            if x < w:
                return self._put(name, opt)
            x -= w
        return self._put(name, options[-1])

    def set(self, name, value):
        """Records a derived value (not drawn) with the parameters."""
        return self._put(name, round(value, 3) if isinstance(value, float) else value)


def target_size(family_no, index, jitter):
    """Largest extent (mm) for part `index` of a family: a golden-ratio sequence in
    log size over 15..120 mm, so any count of parts spreads over the range and a
    part's size does not change when more parts are asked for. jitter in [0, 1)."""
    u = (GOLDEN * index + 0.29 * family_no + 0.08 * jitter) % 1.0
    return round(SIZE_MIN * (SIZE_MAX / SIZE_MIN) ** u, 2)


def num(x):
    """A number as OpenSCAD text: at most 4 decimals, no trailing zeros, no '-0'."""
    s = f"{float(x):.4f}".rstrip("0").rstrip(".")
    return "0" if s in ("-0", "") else s


def vec(v):
    return "[" + ", ".join(num(x) for x in v) + "]"


def points(pts):
    return "[" + ", ".join(vec(p) for p in pts) + "]"


def polygon(pts):
    return f"polygon(points={points(pts)});"


def header(size):
    """Tessellation settings: at most 6 degrees per segment (chord error below
    0.0007 * diameter, well inside the symmetry tolerance) and segments of at least
    size/150 mm, so small holes stay light."""
    return f"$fa = 6;\n$fs = {num(max(0.3, size / 150.0))};\n"


def indent(text, n=2):
    pad = " " * n
    return "\n".join(pad + line if line else line for line in text.splitlines())


def block(head, *children):
    """'head { child; child; }' with indented children (strings)."""
    inner = "\n".join(c for c in children if c)
    return f"{head} {{\n{indent(inner)}\n}}"


def arc(cx, cy, r, a0, a1, n):
    """n + 1 points on an arc of radius r from angle a0 to a1 (degrees)."""
    return [(cx + r * math.cos(math.radians(a0 + (a1 - a0) * k / n)),
             cy + r * math.sin(math.radians(a0 + (a1 - a0) * k / n))) for k in range(n + 1)]


def segments_for(r, size):
    """Segment count OpenSCAD would use for radius r under header(size)."""
    fs = max(0.3, size / 150.0)
    return max(5, int(math.ceil(min(360.0 / 6.0, 2 * math.pi * r / fs))))


def slot2d(x0, y0, x1, y1, d):
    """Obround slot of width d between two centres (2-D OpenSCAD)."""
    return (f"hull() {{ translate({vec((x0, y0))}) circle(d={num(d)}); "
            f"translate({vec((x1, y1))}) circle(d={num(d)}); }}")


def strip_polygon(path, width):
    """Closed outline of a strip of the given width centred on a smooth polyline
    path (list of (x, y)), with square ends. The path's bends must have radii
    above width / 2 so the inner offset does not fold."""
    left, right = [], []
    n = len(path)
    for i in range(n):
        x0, y0 = path[max(i - 1, 0)]
        x1, y1 = path[min(i + 1, n - 1)]
        tx, ty = x1 - x0, y1 - y0
        ln = math.hypot(tx, ty)
        nx, ny = -ty / ln, tx / ln
        px, py = path[i]
        left.append((px + nx * width / 2, py + ny * width / 2))
        right.append((px - nx * width / 2, py - ny * width / 2))
    return right + left[::-1]


def polyline_with_bends(corners, bend_r, per_90=8):
    """Path through corner points with every interior corner rounded by an arc of
    radius bend_r (mm) tangent to both legs; points every ~90/per_90 degrees."""
    out = [corners[0]]
    for i in range(1, len(corners) - 1):
        p0, p1, p2 = corners[i - 1], corners[i], corners[i + 1]
        d0 = (p1[0] - p0[0], p1[1] - p0[1])
        d1 = (p2[0] - p1[0], p2[1] - p1[1])
        l0, l1 = math.hypot(*d0), math.hypot(*d1)
        u0 = (d0[0] / l0, d0[1] / l0)
        u1 = (d1[0] / l1, d1[1] / l1)
        turn = math.atan2(u0[0] * u1[1] - u0[1] * u1[0], u0[0] * u1[0] + u0[1] * u1[1])
        if abs(turn) < 1e-9:
            out.append(p1)
            continue
        r = min(bend_r, 0.49 * min(l0, l1) / max(math.tan(abs(turn) / 2), 1e-9))
        back = r * math.tan(abs(turn) / 2)
        start = (p1[0] - u0[0] * back, p1[1] - u0[1] * back)
        side = 1.0 if turn > 0 else -1.0
        cx, cy = start[0] - side * u0[1] * r, start[1] + side * u0[0] * r
        a0 = math.atan2(start[1] - cy, start[0] - cx)
        steps = max(2, int(math.ceil(abs(turn) / (math.pi / 2) * per_90)))
        for k in range(steps + 1):
            a = a0 + turn * k / steps
            out.append((cx + r * math.cos(a), cy + r * math.sin(a)))
    out.append(corners[-1])
    return out

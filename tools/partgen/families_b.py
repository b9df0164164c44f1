"""Part families, second part: hex nut, hex bolt (bolt-like parts), hinge leaf,
cup / housing, plate with holes. Same contract as families_a (mm, returns
{"scad", "frame"})."""

import math

from scad_util import arc, block, num, points, polygon, slot2d, vec

TAN30 = math.tan(math.radians(30))
COS30 = math.cos(math.radians(30))


def _hex_prism(e, z0, z1):
    return f"translate([0, 0, {num(z0)}]) linear_extrude(height={num(z1 - z0)}) circle(d={num(e)}, $fn=6);"


# -- hex nut -------------------------------------------------------------------------

def hex_nut(d, size):
    variant = d.choice("variant", ["plain", "flanged", "castle"], [0.55, 0.25, 0.2])
    if variant == "flanged":
        df = size
        s = df / d.uniform("flange_rel", 1.3, 1.5)
    else:
        df = 0.0
        s = size * COS30
    e = s / COS30
    m = s * d.uniform("height_rel", 0.45, 0.9)
    bore = s * d.uniform("bore_rel", 0.55, 0.66)
    both = d.chance("chamfer_both", 0.7) if variant != "flanged" else False
    washer = d.chance("washer_face", 0.3) if variant == "plain" else False
    hw = max(0.4, 0.04 * m) if washer else 0.0
    dw = s * 0.95
    rb = bore / 2
    cb = bore * 0.08
    big = e / 2 + 1
    drop = (big - dw / 2) * TAN30
    pts = [(rb + cb, 0.0)]
    if washer:
        pts += [(dw / 2, 0.0), (dw / 2, hw), (big, hw)]
    elif both:
        pts += [(dw / 2, 0.0), (big, drop)]
    else:
        pts += [(big, 0.0)]
    pts += [(big, m - drop), (dw / 2, m), (rb + cb, m), (rb, m - cb), (rb, cb)]
    d.set("dims_mm", [round(s, 2), round(e, 2), round(m, 2), round(bore, 2)])
    body = block("intersection()", _hex_prism(e, 0, m), f"rotate_extrude() polygon(points={points(pts)});")
    if variant == "flanged":
        tfl = m * 0.22
        fp = [(rb + cb, 0.0), (df / 2, 0.0), (df / 2, tfl * 0.5), (s * 0.48, tfl * 1.6), (rb + cb, tfl * 1.6)]
        body = block("union()", body, f"rotate_extrude() polygon(points={points(fp)});")
    if variant == "castle":
        depth, ws = m * 0.35, s * 0.22
        cuts = [f"rotate([0, 0, {30 + 60 * k}]) translate([0, 0, {num(m - depth + depth / 2 + 0.5)}]) "
                f"cube([{num(e + 2)}, {num(ws)}, {num(depth + 1)}], center=true);" for k in range(3)]
        body = block("difference()", body, *cuts)
    return {"scad": body, "frame": "axis"}


# -- hex bolt and bolt-like parts ----------------------------------------------------

def hex_bolt(d, size):
    variant = d.choice("variant", ["hex", "hex_flange", "socket_cap"], [0.5, 0.25, 0.25])
    L = size
    dia = L * d.uniform("diameter_rel", 0.12, 0.26, 3)
    r = dia / 2
    if variant == "socket_cap":
        k, hs = dia, 1.5 * dia
    else:
        k, hs = 0.65 * dia, 1.5 * dia
    ls = L - k
    threaded = d.chance("thread_step", 0.6)
    lt = ls * d.uniform("thread_rel", 0.35, 1.0) if threaded else 0.0
    rt = r * 0.92 if threaded else r
    c = 0.1 * dia
    washer = d.chance("washer_face", 0.4) if variant == "hex" else False
    hw = max(0.4, 0.05 * k) if washer else 0.0
    e = hs / COS30
    dw = 0.95 * hs
    pts = [(0.0, -ls), (rt - c, -ls), (rt, -ls + c)]
    if threaded and lt < ls - (r - rt) - 0.5:
        pts += [(rt, -ls + lt), (r, -ls + lt + (r - rt))]
    else:
        rt = r
        pts = [(0.0, -ls), (r - c, -ls), (r, -ls + c)]
    if variant == "hex_flange":
        df = hs * 1.4
        tfl = k * 0.3
        pts += [(r, 0.0), (df / 2, 0.0), (df / 2, tfl * 0.5), (hs * 0.48, tfl * 1.5), (0.0, tfl * 1.5)]
    elif washer:
        # The shank goes on into the head: OpenSCAD merely concatenates solids that
        # only touch, which would leave two shells.
        pts += [(r, 0.0), (dw / 2, 0.0), (dw / 2, hw), (r, hw), (r, hw + 0.3 * k), (0.0, hw + 0.3 * k)]
    else:
        pts += [(r, 0.0), (r, 0.01 * k), (0.0, 0.01 * k)]
    shank = f"rotate_extrude() polygon(points={points(pts)});"
    d.set("dims_mm", [round(L, 2), round(dia, 2), round(hs, 2), round(k, 2)])
    if variant == "socket_cap":
        hr = hs / 2
        ch = 0.08 * dia
        hp = [(0.0, 0.0), (hr - ch, 0.0), (hr, ch), (hr, k - ch), (hr - ch, k), (0.0, k)]
        ss = 0.75 * dia
        head = block("difference()", f"rotate_extrude() polygon(points={points(hp)});",
                     _hex_prism(ss / COS30, k - 0.55 * dia, k + 1))
    else:
        big = e / 2 + 1
        drop = (big - dw / 2) * TAN30
        hp = [(0.0, 0.0), (big, 0.0), (big, k - drop), (dw / 2, k), (0.0, k)]
        head = block("intersection()", _hex_prism(e, hw, k), f"rotate_extrude() polygon(points={points(hp)});")
    body = block("union()", shank, head)
    if d.chance("cross_hole", 0.15):
        body = block("difference()", body, f"translate([0, 0, {num(-ls + 0.12 * ls + dia * 0.3)}]) rotate([90, 0, 0]) "
                                           f"cylinder(d={num(dia * 0.3)}, h={num(dia + 2)}, center=true);")
    return {"scad": body, "frame": "axis"}


# -- hinge leaf --------------------------------------------------------------------

def hinge(d, size):
    W = size
    Lf = W * d.uniform("leaf_rel", 0.35, 0.8)
    t = max(1.2, W * d.uniform("thickness_rel", 0.03, 0.06, 3))
    rk = t * d.uniform("knuckle_rel", 1.3, 2.0)
    rp = rk * d.uniform("pin_rel", 0.4, 0.6)
    n_kn = d.choice("knuckles", [3, 5], [0.6, 0.4])
    own_ends = d.chance("owns_end_knuckles", 0.7)
    centred = d.chance("leaf_centred", 0.3)
    g = 0.3
    sl = W / n_kn
    z0, z1 = (-t / 2, t / 2) if centred else (rk - t, rk)
    segs = [(i * sl + (g / 2 if i else 0.0), (i + 1) * sl - (g / 2 if i < n_kn - 1 else 0.0)) for i in range(n_kn)]
    own = [s for i, s in enumerate(segs) if (i % 2 == 0) == own_ends]
    other = [s for i, s in enumerate(segs) if (i % 2 == 0) != own_ends]
    rc = min(Lf * 0.3, W * 0.1) * d.uniform("corner_rel", 0.0, 1.0)
    outline = (f"translate([0, 0]) square([{num(W)}, {num(Lf)}]);" if rc < 0.5 else block(
        "hull()", f"square([{num(W)}, {num(Lf / 2)}]);",
        f"translate({vec((rc, Lf - rc))}) circle(r={num(rc)});",
        f"translate({vec((W - rc, Lf - rc))}) circle(r={num(rc)});"))
    cuts = [f"translate({vec((a - g, -rk - 1))}) square([{num(b - a + 2 * g)}, {num(2 * rk + 1 + g)}]);"
            for a, b in other]
    nh = d.integer("holes", 2, 4)
    hd = min(Lf * 0.25, W / nh * 0.4, max(2.0, t * 2.2))
    yh = (rk + g + Lf) / 2
    two_rows = d.chance("two_rows", 0.3) and Lf - rk > 5 * hd
    holes = []
    for i in range(nh):
        x = W * (i + 0.5) / nh
        y = yh if not two_rows else (rk + g + (Lf - rk) * (0.3 if i % 2 else 0.7))
        holes.append((x, y))
    if d.chance("odd_hole", 0.25):
        holes[0] = (holes[0][0] + hd * 0.8, holes[0][1])
    cuts += [f"translate({vec(h)}) circle(d={num(hd)});" for h in holes]
    leaf = block(f"translate([0, 0, {num(z0)}]) linear_extrude(height={num(z1 - z0)})",
                 block("difference()", outline, *cuts))
    knuckles = [f"translate([{num(a)}, 0, 0]) rotate([0, 90, 0]) linear_extrude(height={num(b - a)}) "
                f"circle(r={num(rk)});" for a, b in own]
    sink = []
    if d.chance("countersunk", 0.5):
        zt = z0 if centred else z1
        sink = [f"translate([{num(x)}, {num(y)}, {num(zt - hd * 0.5)}]) cylinder(d1={num(hd)}, d2={num(hd * 2)}, "
                f"h={num(hd * 0.5 + 0.01)});" for x, y in holes]
    pin = f"translate([-1, 0, 0]) rotate([0, 90, 0]) cylinder(r={num(rp)}, h={num(W + 2)});"
    d.set("dims_mm", [round(W, 2), round(Lf, 2), round(t, 2), round(2 * rk, 2)])
    return {"scad": block("difference()", block("union()", leaf, *knuckles), pin, *sink), "frame": "bbox"}


# -- cup / housing ------------------------------------------------------------------

def cup(d, size):
    aspect = d.uniform("height_to_diameter", 0.35, 1.6)
    lip = d.chance("top_lip", 0.3)
    lip_rel = d.uniform("lip_rel", 1.1, 1.3)
    span = max(1.0, aspect) if not lip else max(lip_rel, aspect)
    D = size / span
    H = D * aspect
    R = D / 2
    w = max(1.0, D * d.uniform("wall_rel", 0.04, 0.1, 3))
    tb = max(1.0, H * d.uniform("bottom_rel", 0.05, 0.15, 3))
    rf = min(w * 1.5, (H - tb) * 0.3) if d.chance("inner_fillet", 0.6) else 0.0
    r0 = R * d.uniform("centre_hole_rel", 0.1, 0.3) if d.chance("centre_hole", 0.3) else 0.0
    cbot = min(w, tb) * 0.5
    ctop = w * 0.3
    pts = [(r0, 0.0), (R - cbot, 0.0), (R, cbot)]
    if lip:
        tl = min(H * 0.25, w * 1.5)
        Rl = R * lip_rel
        pts += [(R, H - tl), (Rl - ctop, H - tl), (Rl, H - tl + ctop), (Rl, H)]
    else:
        pts += [(R, H - ctop), (R - ctop, H)]
    ri = R - w
    pts += [(ri, H)]
    if rf > 0:
        pts += [(ri, tb + rf)] + [p for p in arc(ri - rf, tb + rf, rf, 0, -90, 6)][1:]
    else:
        pts += [(ri, tb)]
    pts += [(r0, tb)]
    d.set("dims_mm", [round(D, 2), round(H, 2), round(w, 2), round(tb, 2)])
    body = f"rotate_extrude() polygon(points={points(pts)});"
    feat = d.choice("feature", ["none", "lug", "side_hole", "cross_holes", "bottom_holes"], [0.3, 0.15, 0.2, 0.1, 0.25])
    zc = tb + (H - tb) * d.uniform("feature_height_rel", 0.35, 0.65)
    hd = min((H - tb) * 0.35, D * 0.2)
    if feat == "lug":
        lw, lh, lo = min(H * 0.5, D * 0.35), min(H * 0.6, D * 0.3), D * 0.25
        lug = block("difference()",
                    f"translate([{num(R - w)}, {num(-lw / 2)}, 0]) cube([{num(w + lo)}, {num(lw)}, {num(lh)}]);",
                    f"translate([{num(R + lo * 0.55)}, 0, -1]) cylinder(d={num(min(lw, lo) * 0.5)}, h={num(lh + 2)});")
        inside = f"translate([0, 0, {num(tb)}]) cylinder(r={num(ri)}, h={num(H)});"
        body = block("difference()", block("union()", body, lug), inside)
    elif feat in ("side_hole", "cross_holes"):
        length = R + 1 if feat == "side_hole" else 2 * R + 2
        start = 0 if feat == "side_hole" else -R - 1
        body = block("difference()", body, f"translate([{num(start)}, 0, {num(zc)}]) rotate([0, 90, 0]) "
                                           f"cylinder(d={num(hd)}, h={num(length)});")
    elif feat == "bottom_holes":
        n = d.integer("bottom_hole_count", 3, 6)
        rr = (r0 + ri) / 2 if r0 else ri * 0.6
        bd = min((ri - r0) * 0.35, 2 * math.pi * rr / n * 0.4)
        holes = [f"rotate([0, 0, {num(360 * i / n)}]) translate([{num(rr)}, 0, -1]) "
                 f"cylinder(d={num(bd)}, h={num(tb + 2)});"
                 for i in range(n)]
        body = block("difference()", body, *holes)
    return {"scad": body, "frame": "axis"}


# -- plate with holes and slots ----------------------------------------------------

def plate(d, size):
    a = size
    b = a if d.chance("square", 0.2) else a * d.uniform("aspect", 0.35, 0.95)
    t = d.uniform("thickness", 1.5, min(8.0, 0.1 * b + 1.5))
    shape = d.choice("outline", ["rect", "rounded", "chamfered", "obround"], [0.25, 0.35, 0.25, 0.15])
    rc = min(a, b) * d.uniform("corner_rel", 0.05, 0.2)
    if shape == "rect":
        outline = f"square([{num(a)}, {num(b)}], center=true);"
    elif shape == "rounded":
        outline = f"offset(r={num(rc)}) square([{num(a - 2 * rc)}, {num(b - 2 * rc)}], center=true);"
    elif shape == "chamfered":
        outline = polygon([(-a / 2 + rc, -b / 2), (a / 2 - rc, -b / 2), (a / 2, -b / 2 + rc), (a / 2, b / 2 - rc),
                           (a / 2 - rc, b / 2), (-a / 2 + rc, b / 2), (-a / 2, b / 2 - rc), (-a / 2, -b / 2 + rc)])
    else:
        outline = slot2d(-(a - b) / 2, 0, (a - b) / 2, 0, b) if a > b else f"circle(d={num(a)});"
    pattern = d.choice("pattern", ["grid", "corners_centre", "random", "slots", "bolt_circle"],
                       [0.25, 0.2, 0.25, 0.15, 0.15])
    hd = max(2.0, min(a, b) * d.uniform("hole_rel", 0.08, 0.16))
    m = max(hd, rc * 0.8) + hd * 0.6 if shape != "obround" else b * 0.3
    circles, slots = [], []
    if pattern == "grid":
        nx, ny = d.integer("grid_x", 2, 4), d.integer("grid_y", 1, 3)
        for i in range(nx):
            for j in range(ny):
                x = -a / 2 + m + (a - 2 * m) * (i / (nx - 1))
                y = 0.0 if ny == 1 else -b / 2 + m + (b - 2 * m) * (j / (ny - 1))
                circles.append((x, y, hd))
    elif pattern == "corners_centre":
        for sx in (-1, 1):
            for sy in (-1, 1):
                circles.append((sx * (a / 2 - m), sy * (b / 2 - m), hd))
        circles.append((0.0, 0.0, min(a - 4 * m, b - 4 * m, b * 0.5)))
    elif pattern == "slots":
        sl = (a - 2 * m) * 0.25
        ns = d.choice("slot_rows", [1, 2])
        for y in ([0.0] if ns == 1 else [-(b / 2 - m), b / 2 - m]):
            for sx in (-1, 1):
                slots.append((sx * (a / 2 - m - sl), y, sx * (a / 2 - m), y, hd))
        circles.append((0.0, 0.0, min(hd * 1.5, b * 0.3)))
    elif pattern == "bolt_circle":
        n = d.integer("bolt_count", 3, 8)
        rbc = min(a, b) / 2 - m
        big = rbc * 0.8
        circles.append((0.0, 0.0, big))
        hd2 = min(hd, (rbc - big / 2) * 0.8, 2 * math.pi * rbc / n * 0.4)
        for i in range(n):
            ang = 2 * math.pi * i / n
            circles.append((rbc * math.cos(ang), rbc * math.sin(ang), hd2))
    else:
        k = d.integer("random_holes", 2, 7)
        for i in range(k):
            for _ in range(30):
                dd = hd * (0.6 + 0.8 * d.rng.random())
                x = (a / 2 - m) * (2 * d.rng.random() - 1)
                y = (b / 2 - m) * (2 * d.rng.random() - 1)
                if all(math.hypot(x - cx, y - cy) > (dd + cd) * 0.75 for cx, cy, cd in circles):
                    circles.append((x, y, dd))
                    break
    if d.chance("odd_feature", 0.35):
        for _ in range(40):
            x = (a / 2 - m) * (2 * d.rng.random() - 1)
            y = (b / 2 - m) * (2 * d.rng.random() - 1)
            if all(math.hypot(x - cx, y - cy) > (hd * 0.5 + cd) * 0.75 for cx, cy, cd in circles) and \
                    all(math.hypot(x - (s[0] + s[2]) / 2, y - s[1]) > hd * 1.5 + abs(s[2] - s[0]) / 2 for s in slots):
                circles.append((x, y, hd * 0.5))
                break
    d.set("holes", [[round(x, 2), round(y, 2), round(dd, 2)] for x, y, dd in circles])
    d.set("dims_mm", [round(a, 2), round(b, 2), round(t, 2)])
    cuts = [f"translate({vec((x, y))}) circle(d={num(dd)});" for x, y, dd in circles]
    cuts += [slot2d(*s) for s in slots]
    return {"scad": block(f"linear_extrude(height={num(t)}, center=true)", block("difference()", outline, *cuts)),
            "frame": "bbox"}

"""Part families, first half: angle bracket, flange, spur gear, stepped shaft.

Each builder takes (d: Draw, size: largest extent in mm) and returns
{"scad": OpenSCAD body text (mm), "frame": "bbox" | "axis"}: "bbox" parts are
centred on their bounding box afterwards, "axis" parts keep x = y = 0 on their axis
(drawn along z) and are centred along z only.
"""

import math

from scad_util import arc, block, num, points, polygon, slot2d, vec


# -- angle bracket ---------------------------------------------------------------

def angle_bracket(d, size):
    la, lb, w = d.uniform("leg_a_rel", 0.55, 1.0), d.uniform("leg_b_rel", 0.45, 1.0), d.uniform("width_rel", 0.3, 0.9)
    if d.chance("equal_legs", 0.25):
        lb = la
    k = size / max(la, lb, w)
    la, lb, w = la * k, lb * k, w * k
    t = max(1.5, min(la, lb) * d.uniform("thickness_rel", 0.07, 0.13, 3))
    ri = t * d.uniform("fillet_rel", 0.5, 1.5) if d.chance("inner_fillet", 0.7) else 0.0
    rc = min(w, la, lb) * d.uniform("corner_rel", 0.05, 0.3) if d.chance("round_corners", 0.6) else 0.0
    gussets = d.choice("gussets", [0, 1, 2], [0.55, 0.2, 0.25])
    g = min(la, lb) * d.uniform("gusset_rel", 0.35, 0.6)
    tg = t
    n_w = 2 if gussets == 1 else d.integer("holes_across", 1, 2)
    slots = d.chance("slots", 0.35)
    hd = max(2.0, min(w / (n_w * 2.6), t * d.uniform("hole_rel", 1.3, 2.4)))
    d.set("dims_mm", [round(la, 2), round(lb, 2), round(w, 2), round(t, 2)])

    def leg2d(length, n_along, extra):
        start = t + max(ri, g if gussets else 0.0) + hd
        end = length - max(hd, rc)
        outline = (f"square([{num(length)}, {num(w)}]);" if rc == 0 else block(
            "hull()", f"square([{num(length / 2)}, {num(w)}]);",
            f"translate({vec((length - rc, rc))}) circle(r={num(rc)});",
            f"translate({vec((length - rc, w - rc))}) circle(r={num(rc)});"))
        outline = block(f"translate([0, {num(-w / 2)}])", outline)
        holes = []
        if end - start > hd:
            xs = [start + (end - start) * (i + 0.5) / n_along for i in range(n_along)]
            ys = [0.0] if n_w == 1 else [-w / 4, w / 4]
            if gussets == 2:
                ys = [y * 0.8 for y in ys]
            for x in xs:
                for y in ys:
                    if slots:
                        half = min(hd, (end - start) / n_along / 2 - hd / 2)
                        holes.append(slot2d(x - half, y, x + half, y, hd))
                    else:
                        holes.append(f"translate({vec((x, y))}) circle(d={num(hd)});")
        holes += extra
        return block("difference()", outline, *holes) if holes else outline

    long_a = la - t > 4 * hd
    n_a = d.integer("holes_along_a", 1, 2) if long_a else 1
    n_b = d.integer("holes_along_b", 1, 2) if lb - t > 4 * hd else 1
    extra = []
    if d.chance("odd_hole", 0.3):
        extra.append(f"translate({vec((la - 1.6 * hd, w / 2 - 1.4 * hd))}) circle(d={num(0.6 * hd)});")
    parts = [
        block(f"linear_extrude(height={num(t)})", leg2d(la, n_a, extra)),
        block(f"translate([{num(t)}, 0, 0]) rotate([0, -90, 0]) linear_extrude(height={num(t)})",
              leg2d(lb, n_b, [])),
    ]
    if ri > 0:
        parts.append(block(f"rotate([90, 0, 0]) linear_extrude(height={num(w)}, center=true)", block(
            "difference()", f"square([{num(t + ri)}, {num(t + ri)}]);",
            f"translate({vec((t + ri, t + ri))}) circle(r={num(ri)});")))
    gus = polygon([(0, 0), (t + g, 0), (t + g, t), (t, t + g), (0, t + g)])
    ys = [] if gussets == 0 else ([0.0] if gussets == 1 else [-(w / 2 - tg / 2), w / 2 - tg / 2])
    for y in ys:
        parts.append(f"translate([0, {num(y + tg / 2)}, 0]) rotate([90, 0, 0]) "
                     f"linear_extrude(height={num(tg)}) {gus}")
    return {"scad": block("union()", *parts), "frame": "bbox"}


# -- flange ------------------------------------------------------------------------

def flange(d, size):
    R = size / 2
    tf = size * d.uniform("plate_rel", 0.07, 0.14, 3)
    hub = d.chance("hub", 0.8)
    rh = R * d.uniform("hub_rel", 0.35, 0.55)
    hh = tf + size * d.uniform("hub_height_rel", 0.08, 0.3, 3) if hub else tf
    rb = rh * d.uniform("bore_rel", 0.45, 0.7) if hub else R * d.uniform("bore_rel_plain", 0.2, 0.45)
    raised = d.chance("raised_face", 0.45)
    hr = max(1.0, tf * 0.2)
    rrf = (rh if hub else rb + (R - rb) * 0.3) * d.uniform("raised_rel", 1.05, 1.25)
    c1 = tf * 0.15
    c2 = min(1.0, (rh - rb) * 0.15) if hub else 0.5
    z0 = -hr if raised else 0.0
    pts = [(rb + c2, z0)]
    if raised:
        pts += [(rrf, z0), (rrf, 0.0)]
    pts += [(R - c1, 0.0), (R, c1), (R, tf - c1), (R - c1, tf)]
    if hub:
        fil = d.chance("hub_fillet", 0.5)
        f = min(tf, (hh - tf)) * 0.5
        if fil:
            pts += [(x, y) for x, y in arc(rh + f, tf + f, f, 270, 180, 6)]
        else:
            pts += [(rh, tf)]
        pts += [(rh, hh - c2), (rh - c2, hh)]
    pts += [(rb + c2, hh), (rb, hh - c2), (rb, z0 + c2)]
    inner_r = rrf if raised else (rh if hub else rb)
    n = d.integer("bolt_holes", 3, 8)
    hd = min((R - inner_r) * d.uniform("hole_rel", 0.3, 0.5), 2 * math.pi * (inner_r + R) / 2 / n / 2.2)
    rbc = (inner_r + hd / 2 + R - hd / 2) / 2
    odd = d.choice("odd_feature", ["none", "different_hole", "rim_notch", "keyway"], [0.45, 0.2, 0.2, 0.15])
    d.set("dims_mm", [round(2 * R, 2), round(tf, 2), round(hh - z0, 2), round(2 * rb, 2)])
    zlo, zhi = z0 - 1, hh + 1
    cuts = []
    for i in range(n):
        dia = hd * 0.6 if (odd == "different_hole" and i == 0) else hd
        cuts.append(f"rotate([0, 0, {num(360 * i / n)}]) translate([{num(rbc)}, 0, {num(zlo)}]) "
                    f"cylinder(d={num(dia)}, h={num(zhi - zlo)});")
    if odd == "rim_notch":
        nw = hd * 0.8
        cuts.append(f"rotate([0, 0, {num(180 / n)}]) translate([{num(R - hd * 0.6)}, {num(-nw / 2)}, {num(zlo)}]) "
                    f"cube([{num(hd)}, {num(nw)}, {num(tf + 2 - z0)}]);")
    if odd == "keyway":
        kw = rb * 0.5
        cuts.append(f"translate([{num(rb - 0.5)}, {num(-kw / 2)}, {num(zlo)}]) cube([{num(rb * 0.25 + 0.5)}, "
                    f"{num(kw)}, {num(zhi - zlo)}]);")
    body = f"rotate_extrude() polygon(points={points(pts)});"
    return {"scad": block("difference()", body, *cuts), "frame": "axis"}


# -- spur gear ---------------------------------------------------------------------

def involute_gear_points(z, m, pressure_deg=20.0, flank_pts=8, tip_pts=3, root_pts=4):
    """Outline (x, y) of a standard spur gear, tooth 0 centred on +x, CCW.

    Pitch radius m z / 2, addendum m, dedendum 1.25 m, no profile shift; the flank
    below the base circle is a radial line (no root fillet)."""
    a = math.radians(pressure_deg)
    rp = m * z / 2
    rb, ra, rf = rp * math.cos(a), rp + m, rp - 1.25 * m
    inv = lambda alpha: math.tan(alpha) - alpha  # noqa: E731
    r0 = max(rb, rf)

    def half_angle(r):   # half the tooth's angular thickness at radius r
        return math.pi / (2 * z) + inv(a) - inv(math.acos(min(1.0, rb / r)))

    radii = [r0 + (ra - r0) * k / flank_pts for k in range(flank_pts + 1)]
    pts = []
    pitch = 2 * math.pi / z
    for i in range(z):
        c = i * pitch
        if rf < r0:
            pts.append((rf * math.cos(c - half_angle(r0)), rf * math.sin(c - half_angle(r0))))
        for r in radii:
            t = c - half_angle(r)
            pts.append((r * math.cos(t), r * math.sin(t)))
        ha = half_angle(ra)
        for k in range(1, tip_pts):
            t = c - ha + 2 * ha * k / tip_pts
            pts.append((ra * math.cos(t), ra * math.sin(t)))
        for r in reversed(radii):
            t = c + half_angle(r)
            pts.append((r * math.cos(t), r * math.sin(t)))
        t0 = c + half_angle(r0)
        t1 = c + pitch - half_angle(r0)
        for k in range(0 if rf < r0 else 1, root_pts):
            t = t0 + (t1 - t0) * k / root_pts
            pts.append((rf * math.cos(t), rf * math.sin(t)))
    return pts


def spur_gear(d, size):
    z = d.integer("teeth", 12, 40)
    m = d.set("module_mm", size / (z + 2))
    b = min(0.6 * size, m * d.uniform("face_width_rel", 3.5, 9.0))
    rf = m * z / 2 - 1.25 * m
    bore = rf * d.uniform("bore_rel", 0.25, 0.45)
    hub = d.chance("hub", 0.8)
    rhub = min(rf - m, bore * d.uniform("hub_rel", 1.6, 2.2))
    hh = m * d.uniform("hub_height_rel", 2.5, 7.0)
    keyway = d.chance("keyway", 0.7)
    kw, kd = bore * 0.5, bore * 0.22
    d.set("dims_mm", [round(m * (z + 2), 2), round(b, 2), round(b + (hh if hub else 0), 2), round(2 * bore, 2)])
    cut = [f"circle(r={num(bore)});"]
    if keyway:
        cut.append(f"translate([{num(bore - 0.5)}, {num(-kw / 2)}]) square([{num(kd + 0.5)}, {num(kw)}]);")
    web = []
    r_in = rhub if hub else bore * 1.6
    if rf - m - r_in > 0.35 * rf and d.chance("lightening_holes", 0.5):
        nl = d.integer("lightening_count", 4, 6)
        rl = (rf - m + r_in) / 2
        dl = min((rf - m - r_in) * 0.75, 2 * math.pi * rl / nl * 0.55)
        web = [f"rotate([0, 0, {num(360 * i / nl + 180 / nl)}]) translate([{num(rl)}, 0]) circle(d={num(dl)});"
               for i in range(nl)]
    gear2d = block("difference()", polygon(involute_gear_points(z, m)), *cut, *web)
    parts = [block(f"linear_extrude(height={num(b)})", gear2d)]
    if hub:
        hub2d = block("difference()", f"circle(r={num(rhub)});", *cut)
        # The hub starts inside the gear body (solids that only touch are not merged).
        parts.append(block(f"translate([0, 0, {num(b / 2)}]) linear_extrude(height={num(hh + b / 2)})", hub2d))
        if d.chance("set_screw", 0.3):
            return {"scad": block("difference()", block("union()", *parts),
                                  f"translate([0, 0, {num(b + hh / 2)}]) rotate([0, 90, 0]) "
                                  f"cylinder(d={num(min(hh * 0.5, bore))}, h={num(rhub + 1)});"),
                    "frame": "axis"}
    return {"scad": block("union()", *parts) if len(parts) > 1 else parts[0], "frame": "axis"}


# -- stepped shaft -------------------------------------------------------------------

def stepped_shaft(d, size):
    L = size
    n = d.integer("steps", 2, 4)
    dmax = L * d.uniform("max_diameter_rel", 0.15, 0.45, 3)
    pattern = d.choice("pattern", ["descending", "shoulder"], [0.5, 0.5])
    rel = sorted([d.uniform(f"diameter_rel_{i}", 0.45, 0.92) for i in range(n - 1)], reverse=True)
    if pattern == "descending":
        dia = [dmax] + [dmax * r for r in rel]
    else:
        mid = n // 2
        rest = [dmax * r for r in rel]
        dia = list(reversed(rest[:mid])) + [dmax] + rest[mid:]
    fr = [d.uniform(f"length_rel_{i}", 0.5, 1.5) for i in range(n)]
    lens = [L * f / sum(fr) for f in fr]
    z = [0.0]
    for ln in lens:
        z.append(z[-1] + ln)
    r = [x / 2 for x in dia]
    c = [min(0.08 * x, 0.25 * ln) for x, ln in zip(dia, lens)]
    centre_holes = d.chance("centre_holes", 0.3)
    ch = min(r) * 0.3
    pts = [(0.0, ch * 1.2)] if centre_holes else [(0.0, 0.0)]
    if centre_holes:
        pts.append((ch, 0.0))
    pts += [(r[0] - c[0], 0.0), (r[0], c[0])]
    groove = d.chance("groove", 0.3)
    gstep = d.integer("groove_step", 0, n - 1)
    for i in range(n):
        if groove and i == gstep and lens[i] > 4 * c[i] + 3:
            gz, gw, gd = z[i] + lens[i] * 0.7, max(0.8, lens[i] * 0.06), r[i] * 0.08
            pts += [(r[i], gz), (r[i] - gd, gz), (r[i] - gd, gz + gw), (r[i], gz + gw)]
        if i == n - 1:
            break
        if r[i + 1] > r[i]:
            pts += [(r[i], z[i + 1]), (r[i + 1] - c[i + 1], z[i + 1]), (r[i + 1], z[i + 1] + c[i + 1])]
        else:
            pts += [(r[i], z[i + 1] - c[i]), (r[i] - c[i], z[i + 1]), (r[i + 1], z[i + 1])]
    pts += [(r[-1], L - c[-1]), (r[-1] - c[-1], L)]
    pts += [(ch, L), (0.0, L - ch * 1.2)] if centre_holes else [(0.0, L)]
    d.set("diameters_mm", [round(x, 2) for x in dia])
    body = f"rotate_extrude() polygon(points={points(pts)});"
    feat = d.choice("feature", ["none", "flat", "keyway", "two_flats", "cross_hole"], [0.12, 0.33, 0.33, 0.1, 0.12])
    k = d.integer("feature_step", 0, n - 1)
    rk, z0, z1 = r[k], z[k] + c[k], z[k + 1] - c[k]
    span = z1 - z0
    fz0, fz1 = (z0, z1) if k in (0, n - 1) and d.chance("open_feature", 0.5) else (z0 + span * 0.2, z1 - span * 0.2)
    if k == 0:
        fz0 = -1.0 if fz0 == z0 else fz0
    if k == n - 1:
        fz1 = L + 1.0 if fz1 == z1 else fz1
    cuts = []
    if feat in ("flat", "two_flats"):
        depth = rk * d.uniform("flat_depth_rel", 0.12, 0.3)
        for ang in ([0] if feat == "flat" else [0, 180]):
            cuts.append(f"rotate([0, 0, {ang}]) translate([{num(rk - depth)}, {num(-rk - 1)}, {num(fz0)}]) "
                        f"cube([{num(depth + 1)}, {num(2 * rk + 2)}, {num(fz1 - fz0)}]);")
    elif feat == "keyway":
        kw = rk * 0.5
        kd = rk * 0.3
        a0, a1 = max(fz0, z0) + kw / 2, min(fz1, z1) - kw / 2
        if a1 > a0:
            cuts.append(block("hull()", *[f"translate([{num(rk - kd)}, 0, {num(zz)}]) rotate([0, 90, 0]) "
                                          f"cylinder(d={num(kw)}, h={num(kd + 1)});" for zz in (a0, a1)]))
    elif feat == "cross_hole":
        zz = (z[k] + z[k + 1]) / 2
        cuts.append(f"translate([0, 0, {num(zz)}]) rotate([90, 0, 0]) cylinder(d={num(rk * 0.5)}, "
                    f"h={num(2 * rk + 2)}, center=true);")
    return {"scad": block("difference()", body, *cuts) if cuts else body, "frame": "axis"}

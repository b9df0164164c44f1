"""Part families, third part: pipe fitting, clip, lever, extruded profile.
Same contract as families_a (mm, returns {"scad", "frame"})."""

import math

import numpy as np

from scad_util import (arc, block, num, points, polygon, polyline_with_bends, segments_for,
                       strip_polygon, vec)
from sweep import ElbowPath, swept_tube


# -- pipe fittings -------------------------------------------------------------------

def pipe_fitting(d, size):
    variant = d.choice("variant", ["elbow", "tee", "reducer"], [0.35, 0.35, 0.3])
    if variant == "reducer":
        return _reducer(d, size)
    do = size * d.uniform("od_rel", 0.22, 0.4, 3)
    w = max(1.0, do * d.uniform("wall_rel", 0.08, 0.15, 3))
    sockets = d.chance("sockets", 0.5)
    ds = do * 1.3 if sockets else do
    dsi = do if sockets else do - 2 * w
    di = do - 2 * w
    outer, inner = [], []
    if variant == "elbow":
        return _elbow(d, size, do, w, sockets)
    # tee: run along x, branch along +z
    db = do if not d.chance("reducing_branch", 0.4) else do * d.uniform("branch_rel", 0.55, 0.85)
    dbi = db - 2 * w
    run = size / 2 * d.uniform("run_rel", 0.8, 1.0)
    br = max(db, run * d.uniform("branch_len_rel", 0.6, 1.0))
    dbs = db * 1.3 if sockets else db
    dbsi = db if sockets else dbi
    sl = do * 0.6 if sockets else 0.0
    # With sockets the plain tube stops inside them, so no two end faces are coplanar.
    # The body is thicker than the socket bore (the pipe OD), so they share wall.
    rl, bl = (run - sl / 2, br - sl / 2) if sockets else (run, br)
    dob, dbb = (do + 0.6 * (ds - do), db + 0.6 * (dbs - db)) if sockets else (do, db)
    outer.append(f"rotate([0, 90, 0]) cylinder(d={num(dob)}, h={num(2 * rl)}, center=true);")
    inner.append(f"rotate([0, 90, 0]) cylinder(d={num(di)}, h={num(2 * run + 2)}, center=true);")
    outer.append(f"cylinder(d={num(dbb)}, h={num(bl)});")
    inner.append(f"cylinder(d={num(dbi)}, h={num(br + 1)});")
    if sockets:
        for sx in (-1, 1):
            place = f"rotate([0, {90 * sx}, 0]) translate([0, 0, {num(run - sl)}])"
            outer.append(f"{place} cylinder(d={num(ds)}, h={num(sl)});")
            inner.append(f"{place} cylinder(d={num(dsi)}, h={num(sl + 1)});")
        outer.append(f"translate([0, 0, {num(br - sl)}]) cylinder(d={num(dbs)}, h={num(sl)});")
        inner.append(f"translate([0, 0, {num(br - sl)}]) cylinder(d={num(dbsi)}, h={num(sl + 1)});")
    d.set("dims_mm", [round(do, 2), round(db, 2), round(2 * run, 2), round(br, 2)])
    return {"scad": block("difference()", block("union()", *outer), block("union()", *inner)), "frame": "bbox"}


def _elbow(d, size, do, w, sockets):
    """Bent tube with straight legs (and socket ends), swept as one polyhedron."""
    ang = d.choice("angle_deg", [90, 45], [0.7, 0.3])
    Rb = do * d.uniform("bend_rel", 0.8, 1.5)
    le1 = do * d.uniform("leg_rel", 0.3, 1.0)
    le2 = le1 if d.chance("equal_legs", 0.7) else do * d.uniform("leg2_rel", 0.3, 1.0)
    ro, ri = do / 2, do / 2 - w
    path = ElbowPath(le1, Rb, ang, le2, arc_steps=max(4, ang // 6))
    S = path.length
    if sockets:
        ls = min(0.8 * min(le1, le2), do * 0.6)
        # Socket: bore = pipe OD (ro) over ls; the body between the sockets is thicker
        # than ro so the socket and the body share wall, not just a circle.
        rso = 0.65 * do
        rb = ro + 0.6 * (rso - ro)
        prof = [(0, rso), (ls, rso), (ls, rb), (S - ls, rb), (S - ls, rso), (S, rso),
                (S, ro), (S - ls, ro), (S - ls, ri), (ls, ri), (ls, ro), (0, ro)]
    else:
        prof = [(0, ro), (S, ro), (S, ri), (0, ri)]
    P, F = swept_tube(prof, path, segments_for(0.65 * do if sockets else ro, size))
    # Scaled as a whole so the largest extent is the target size.
    k = size / float(np.max(np.ptp(P, axis=0)))
    P = P * k
    d.set("scale", k)
    d.set("dims_mm", [round(do * k, 2), round((do - 2 * w) * k, 2), round(Rb * k, 2), ang])
    # OpenSCAD wants polyhedron faces clockwise seen from outside.
    return {"scad": f"polyhedron(points={points(P.tolist())}, faces={points(F[:, ::-1].tolist())});",
            "frame": "bbox"}


def _reducer(d, size):
    L = size
    D1 = L * d.uniform("big_od_rel", 0.5, 1.0)
    D2 = D1 * d.uniform("small_rel", 0.45, 0.8)
    w = max(1.0, D2 * d.uniform("wall_rel", 0.08, 0.14, 3))
    l1, lc = L * d.uniform("big_len_rel", 0.25, 0.4), L * d.uniform("cone_len_rel", 0.2, 0.35)
    l2 = L - l1 - lc
    d.set("dims_mm", [round(D1, 2), round(D2, 2), round(L, 2), round(w, 2)])
    if d.chance("eccentric", 0.25):
        off = (D1 - D2) / 2
        def hull_body(dd1, dd2, extra):
            return block("hull()", f"translate([0, 0, {num(-extra)}]) cylinder(d={num(dd1)}, h={num(l1 + extra)});",
                         f"translate([{num(off)}, 0, {num(l1 + lc)}]) cylinder(d={num(dd2)}, h={num(l2 + extra)});")
        return {"scad": block("difference()", hull_body(D1, D2, 0), hull_body(D1 - 2 * w, D2 - 2 * w, 1)),
                "frame": "bbox"}
    r1, r2 = D1 / 2, D2 / 2
    c = w * 0.3
    pts = [(r1 - w, 0.0), (r1 - c, 0.0), (r1, c), (r1, l1), (r2, l1 + lc), (r2, L - c), (r2 - c, L),
           (r2 - w, L), (r2 - w, l1 + lc), (r1 - w, l1)]
    return {"scad": f"rotate_extrude() polygon(points={points(pts)});", "frame": "axis"}


# -- clips bent from strip -------------------------------------------------------------

def clip(d, size):
    variant = d.choice("variant", ["circlip", "u_clip", "saddle_clamp", "spring_band"], [0.25, 0.3, 0.25, 0.2])
    if variant == "circlip":
        return _circlip(d, size)
    t = max(0.8, size * d.uniform("strip_rel", 0.025, 0.05, 3))
    wz = size * d.uniform("width_rel", 0.2, 0.5)
    rb = t * d.uniform("bend_rel", 1.0, 2.5)
    holes = []
    if variant == "u_clip":
        gap = size * d.uniform("gap_rel", 0.25, 0.55)
        l1 = size
        l2 = l1 if d.chance("equal_legs", 0.6) else l1 * d.uniform("leg2_rel", 0.6, 0.9)
        lip = d.chance("flared_lips", 0.5)
        x0, x1 = -gap / 2, gap / 2
        corners = [(x0, l1), (x0, 0.0), (x1, 0.0), (x1, l2)]
        if lip:
            corners = [(x0 - gap * 0.25, l1 + gap * 0.2)] + corners + [(x1 + gap * 0.25, l2 + gap * 0.2)]
            scale = size / (l1 + gap * 0.2 + t)
            corners = [(x * scale, y * scale) for x, y in corners]
        if d.chance("leg_hole", 0.35):
            holes.append(f"translate([0, {num(corners[-2][1] * 0.6 if lip else l2 * 0.6)}, {num(wz / 2)}]) "
                         f"rotate([0, 90, 0]) cylinder(d={num(wz * 0.35)}, h={num(size * 2)}, center=true);")
    elif variant == "saddle_clamp":
        R = size * d.uniform("saddle_rel", 0.18, 0.3)
        foot = (size / 2 - R - t) * d.uniform("foot_rel", 0.8, 1.0)
        n = 16
        arch = [(R * math.cos(math.pi * (1 - k / n)), R * math.sin(math.pi * (1 - k / n)) + t) for k in range(n + 1)]
        corners = [(-R - foot, 0.0), (-R, 0.0)] + arch[1:-1] + [(R, 0.0), (R + foot, 0.0)]
        for sx in (-1, 1):
            x = sx * (R + foot * 0.55)
            holes.append(f"translate([{num(x)}, 0, {num(wz / 2)}]) rotate([90, 0, 0]) "
                         f"cylinder(d={num(min(foot * 0.45, wz * 0.5))}, h={num(4 * t)}, center=true);")
        rb = min(rb, R * 0.3)
    else:
        R = size * d.uniform("band_rel", 0.3, 0.4)
        open_deg = d.uniform("opening_deg", 30, 70, 1)
        ends = size * 0.5 - R
        pts = arc(0, 0, R, open_deg / 2, 360 - open_deg / 2, 40)
        a0, a1 = math.radians(open_deg / 2), math.radians(360 - open_deg / 2)
        def tip(a, s):   # end of a tab leaving the band at angle a, turned out by 0.6 rad
            return (R * math.cos(a) + ends * math.cos(a + s * 0.6), R * math.sin(a) + ends * math.sin(a + s * 0.6))
        corners = [tip(a0, -1)] + pts + [tip(a1, 1)]
    path = polyline_with_bends(corners, rb) if variant != "spring_band" else corners
    d.set("path_points", len(path))
    body = f"linear_extrude(height={num(wz)}) {polygon(strip_polygon(path, t))}"
    return {"scad": block("difference()", body, *holes) if holes else body, "frame": "bbox"}


def _circlip(d, size):
    R = size / 2 * d.uniform("outer_rel", 0.8, 0.9)
    ri = R * d.uniform("inner_rel", 0.68, 0.8)
    e = (R - ri) * 0.35
    t = max(1.0, size * d.uniform("thickness_rel", 0.03, 0.05, 3))
    gap = ri * d.uniform("gap_rel", 0.35, 0.6)
    rl = (R - ri) * 0.9
    hole = rl * 0.9
    lug_x = math.sqrt(max(ri ** 2 - (gap / 2 + rl) ** 2, 0)) + rl * 0.4
    ring = block("difference()", f"translate([{num(-e)}, 0]) circle(r={num(R)});", f"circle(r={num(ri)});",
                 f"translate([0, {num(-gap / 2)}]) square([{num(R + 2 * e)}, {num(gap)}]);")
    lugs = [f"translate({vec((lug_x, s * (gap / 2 + rl)))}) circle(r={num(rl)});" for s in (-1, 1)]
    holes = [f"translate({vec((lug_x, s * (gap / 2 + rl)))}) circle(d={num(hole)});" for s in (-1, 1)]
    d.set("dims_mm", [round(2 * R, 2), round(2 * ri, 2), round(t, 2), round(gap, 2)])
    return {"scad": block(f"linear_extrude(height={num(t)})",
                          block("difference()", block("union()", ring, *lugs), *holes)), "frame": "bbox"}


# -- lever -------------------------------------------------------------------------------

def lever(d, size):
    R1 = size * d.uniform("big_boss_rel", 0.1, 0.18, 3)
    R2 = R1 * d.uniform("small_boss_rel", 0.45, 0.85)
    L = size - R1 - R2
    ta = max(2.0, size * d.uniform("arm_rel", 0.04, 0.08, 3))
    h1, h2 = ta * d.uniform("boss1_rel", 1.5, 3.0), ta * d.uniform("boss2_rel", 1.2, 2.5)
    centred = d.chance("bosses_centred", 0.5)
    d1, d2 = 2 * R1 * d.uniform("hole1_rel", 0.35, 0.55), 2 * R2 * d.uniform("hole2_rel", 0.35, 0.55)
    tapered = d.chance("tapered_arm", 0.6)
    bell = d.chance("bell_crank", 0.25)
    bell_ang = d.uniform("bell_angle_deg", 90, 130, 1)
    w1, w2 = (R1 * 0.8, R2 * 0.8) if tapered else (R2 * 0.75, R2 * 0.75)
    arms = [block("hull()", f"circle(r={num(w1)});", f"translate([{num(L)}, 0]) circle(r={num(w2)});")]
    centres = [(0.0, 0.0, R1, d1, h1), (L, 0.0, R2, d2, h2)]
    if bell:
        L3 = L * 0.6
        x3, y3 = L3 * math.cos(math.radians(bell_ang)), L3 * math.sin(math.radians(bell_ang))
        arms.append(block("hull()", f"circle(r={num(w1)});", f"translate({vec((x3, y3))}) circle(r={num(w2)});"))
        centres.append((x3, y3, R2, d2, h2))
    cuts = [f"translate({vec((x, y))}) circle(d={num(dd)});" for x, y, _, dd, _ in centres]
    gap = L - R1 - R2
    nl = d.integer("lightening_holes", 0, 3)
    if nl and gap > 3 * ta:
        dl = min(gap / nl * 0.6, min(w1, w2) * 1.1)
        for i in range(nl):
            x = R1 + gap * (i + 0.5) / nl
            wl = w1 + (w2 - w1) * x / L
            cuts.append(f"translate([{num(x)}, 0]) circle(d={num(min(dl, wl * 1.1))});")
    key = d.choice("big_hole_key", ["round", "keyway", "square"], [0.55, 0.3, 0.15])
    boss_cut = [f"circle(d={num(d1)});"]
    if key == "keyway":
        boss_cut.append(f"translate([{num(d1 / 2 - 0.5)}, {num(-d1 * 0.15)}]) "
                        f"square([{num(d1 * 0.2 + 0.5)}, {num(d1 * 0.3)}]);")
    elif key == "square":
        boss_cut = [f"rotate([0, 0, 45]) square({num(d1 * 0.8)}, center=true);"]
    cuts[0] = block("union()", *boss_cut)
    z_arm = (-ta / 2) if centred else 0.0
    parts = [block(f"translate([0, 0, {num(z_arm)}]) linear_extrude(height={num(ta)})",
                   block("difference()", block("union()", *arms), *cuts))]
    for k, (x, y, R, dd, h) in enumerate(centres):
        z0 = -h / 2 if centred else 0.0
        hole = cuts[0] if k == 0 else f"circle(d={num(dd)});"
        parts.append(block(f"translate([{num(x)}, {num(y)}, {num(z0)}]) linear_extrude(height={num(h)})",
                           block("difference()", f"circle(r={num(R)});", hole)))
    d.set("dims_mm", [round(L, 2), round(2 * R1, 2), round(2 * R2, 2), round(ta, 2)])
    return {"scad": block("union()", *parts), "frame": "bbox"}


# -- extruded profiles ---------------------------------------------------------------

def _profile2d(d, kind, a):
    """2-D profile of characteristic size a (mm), roughly centred at the origin."""
    t = max(1.2, a * d.uniform("wall_rel", 0.07, 0.14, 3))
    # Returns (scad 2-D text, bounding box (x0, x1, y0, y1)).
    if kind == "tslot":
        # Aluminium T-slot profile: a square with a slot per side, each opening (so)
        # through the wall t into a trapezoid cavity; the cavities stay inside their
        # quarter (|y| < x for the +x side) so diagonal webs tie core and corners.
        t = min(t, 0.1 * a)
        sides = d.choice("slot_sides", [4, 3, 2], [0.6, 0.2, 0.2])
        so = a * 0.26
        x_out, x_in = a / 2 - t, 0.3 * a - t
        cavity = polygon([(x_in, -0.12 * a), (x_out + 0.01, -0.28 * a), (x_out + 0.01, 0.28 * a), (x_in, 0.12 * a)])
        rc = a * 0.05
        cuts = [f"circle(d={num(a * 0.22)});"]
        for k in range(sides):
            cuts.append(block(f"rotate([0, 0, {90 * k}])",
                              f"translate([{num(x_out - 0.01)}, {num(-so / 2)}]) square([{num(t + 1)}, {num(so)}]);",
                              cavity))
        if d.chance("corner_cavities", 0.5):
            cuts += [f"rotate([0, 0, {45 + 90 * k}]) translate([{num(a * 0.36)}, 0]) circle(d={num(a * 0.08)});"
                     for k in range(4)]
        return block("difference()", f"offset(r={num(rc)}) square({num(a - 2 * rc)}, center=true);",
                     *cuts), (-a / 2, a / 2, -a / 2, a / 2)
    if kind == "u_channel":
        w, h = a, a * d.uniform("u_height_rel", 0.4, 0.9)
        return polygon([(-w / 2, -h / 2), (w / 2, -h / 2), (w / 2, h / 2), (w / 2 - t, h / 2),
                        (w / 2 - t, -h / 2 + t), (-w / 2 + t, -h / 2 + t), (-w / 2 + t, h / 2),
                        (-w / 2, h / 2)]), (-w / 2, w / 2, -h / 2, h / 2)
    if kind == "z_profile":
        h, f = a, a * d.uniform("z_flange_rel", 0.3, 0.55)
        return polygon([(-t / 2, -h / 2), (f, -h / 2), (f, -h / 2 + t), (t / 2, -h / 2 + t), (t / 2, h / 2),
                        (-f, h / 2), (-f, h / 2 - t), (-t / 2, h / 2 - t)]), (-f, f, -h / 2, h / 2)
    if kind == "angle":
        b = a if d.chance("equal_angle", 0.5) else a * d.uniform("angle_leg_rel", 0.5, 0.85)
        return polygon([(0, 0), (a, 0), (a, t), (t, t), (t, b), (0, b)]), (0.0, a, 0.0, b)
    if kind == "rect_tube":
        h = a * d.uniform("tube_aspect", 0.5, 1.0)
        r = t
        return block("difference()", f"offset(r={num(r)}) square([{num(a - 2 * r)}, {num(h - 2 * r)}], center=true);",
                     f"square([{num(a - 2 * t)}, {num(h - 2 * t)}], center=true);"), (-a / 2, a / 2, -h / 2, h / 2)
    fw = a * d.uniform("i_flange_rel", 0.5, 0.9)
    tw = t * 0.7
    return polygon([(-fw / 2, -a / 2), (fw / 2, -a / 2), (fw / 2, -a / 2 + t), (tw / 2, -a / 2 + t),
                    (tw / 2, a / 2 - t), (fw / 2, a / 2 - t), (fw / 2, a / 2), (-fw / 2, a / 2),
                    (-fw / 2, a / 2 - t), (-tw / 2, a / 2 - t), (-tw / 2, -a / 2 + t),
                    (-fw / 2, -a / 2 + t)]), (-fw / 2, fw / 2, -a / 2, a / 2)


def extruded_profile(d, size):
    kind = d.choice("profile", ["tslot", "u_channel", "z_profile", "angle", "rect_tube", "i_beam"],
                    [0.3, 0.15, 0.12, 0.15, 0.13, 0.15])
    if d.chance("slice", 0.2):
        a = size
        L = a * d.uniform("length_rel", 0.3, 0.8)
    else:
        L = size
        a = max(12.0, min(size, L * d.uniform("profile_rel", 0.2, 0.6)))
    prof, (x0, x1, y0, y1) = _profile2d(d, kind, a)
    body = block(f"linear_extrude(height={num(L)})", prof)
    ends = d.choice("end_chamfer", ["none", "one", "both"], [0.6, 0.2, 0.2])
    c = min(a * 0.05, 1.5, L * 0.1)
    if ends != "none":
        # Hull of the profile's bounding box shortened by c at the chamfered ends and
        # the box shrunk by c over the full length: cuts c x 45 degrees off the outer edges.
        lo = c if ends == "both" else 0.0
        body = block("intersection()", body, block(
            "hull()",
            f"translate([{num(x0)}, {num(y0)}, {num(lo)}]) cube([{num(x1 - x0)}, {num(y1 - y0)}, {num(L - lo - c)}]);",
            f"translate([{num(x0 + c)}, {num(y0 + c)}, 0]) "
            f"cube([{num(x1 - x0 - 2 * c)}, {num(y1 - y0 - 2 * c)}, {num(L)}]);"))
    if d.chance("cross_hole", 0.25):
        zh = L * d.uniform("cross_hole_z_rel", 0.15, 0.4)
        body = block("difference()", body, f"translate([0, 0, {num(zh)}]) rotate([90, 0, 0]) "
                                           f"cylinder(d={num(max(2.0, a * 0.15))}, h={num(3 * a)}, center=true);")
    d.set("dims_mm", [round(a, 2), round(L, 2)])
    return {"scad": body, "frame": "bbox"}

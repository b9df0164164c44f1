"""Rotational symmetries of a closed triangle mesh, found from the mesh alone.

A symmetry is a proper rigid motion g (rotation R about the surface centroid c,
x -> R (x - c) + c) with g(surface) = surface within a tolerance: every test point
(all vertices, all triangle centroids, ~8000 area-weighted samples) moved by g lies
within tol of the surface (exact point-to-triangle distance, see surface_distance).
The default tolerance is tol = max(0.1 mm, 0.002 * diameter): features smaller than
that are treated as absent, bigger ones break the symmetry. Mirror symmetries are
not reported (they are not rigid motions of a part in a bin).

Search (nothing about the model frame is assumed):
- the area-weighted second moment of the surface gives principal axes. Every
  symmetry maps each eigenspace onto itself, so when one eigenvalue stands apart the
  axis u of it is invariant and all symmetries are rotations about u or 180-degree
  turns about axes perpendicular to u;
  - about u: a continuous test (several unrelated angles), else n-fold for n = 2..64
    (n >= 3 only when the two other eigenvalues are equal, as it requires);
  - perpendicular flips: candidate axes from vertex pairs (p, q) with equal distance
    to u and opposite height, voting for the bisector angle modulo 180/n degrees,
    plus the in-plane principal axes; a quick necessary test on the (radius, height)
    profile skips the search when no flip can exist;
- when all three eigenvalues are equal (cube-like inertia) candidate rotations come
  from vertex correspondences (two reference vertices of rare radius and all vertex
  pairs that match their radii and distance), then the group is closed.
The output is the full discrete group without the identity (BOP's convention), as
4x4 transforms, and a continuous axis with its offset when found; a continuous axis
also lists one discrete flip when the part can be turned over.
"""

import math

import numpy as np
from scipy.spatial import cKDTree

from mesh_io import diameter
from surface_distance import SurfaceDistance

EIGEN_EQUAL = 0.02          # relative eigenvalue gap below which two moments count as equal
MAX_ORDER = 64
CONTINUOUS_ANGLES = (0.7137, 1.9102, 2.8031, 3.6733, 5.1313)   # rad, unrelated to 2*pi/n, n <= 64
MAX_GROUP = 200


def default_tolerance(diam):
    """Acceptance distance in mm for a part of the given diameter (mm)."""
    return max(0.1, 0.002 * diam)


def rotation(axis, angle):
    """Rotation matrix about a unit axis by angle (rad), right-handed."""
    a = np.asarray(axis, dtype=np.float64)
    a = a / np.linalg.norm(a)
    K = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + math.sin(angle) * K + (1 - math.cos(angle)) * (K @ K)


def surface_moments(V, F):
    """Area-weighted centroid and central second-moment matrix of the surface."""
    a, b, c = V[F[:, 0]], V[F[:, 1]], V[F[:, 2]]
    area = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)
    total = area.sum()
    s = a + b + c
    centroid = (area[:, None] * s).sum(0) / (3 * total)
    # Integral of x x^T over a triangle = area/12 * (sum v v^T + s s^T).
    M = np.einsum("n,nij->ij", area / 12.0,
                  np.einsum("ni,nj->nij", a, a) + np.einsum("ni,nj->nij", b, b)
                  + np.einsum("ni,nj->nij", c, c) + np.einsum("ni,nj->nij", s, s)) / total
    return centroid, M - np.outer(centroid, centroid)


def _perpendicular(u):
    """Unit vector perpendicular to u: the model axis least aligned with u, projected.
    (Only used to pick a tidy representative flip for a continuous axis.)"""
    k = int(np.argmin(np.abs(u)))
    e = np.zeros(3)
    e[k] = 1.0
    w = e - np.dot(e, u) * u
    return w / np.linalg.norm(w)


def _canonical_axis(u):
    """Same line, sign fixed so the largest component is positive."""
    return u if u[int(np.argmax(np.abs(u)))] > 0 else -u


def _close(R1, R2, eps):
    return float(np.max(np.abs(R1 - R2))) < eps


def group_closure(generators, eps=1e-5):
    """All products of the generator rotations (3x3), identity first."""
    elems = [np.eye(3)]
    frontier = [np.eye(3)]
    while frontier and len(elems) < MAX_GROUP:
        new = []
        for e in frontier:
            for g in generators:
                p = g @ e
                if not any(_close(p, x, eps) for x in elems):
                    elems.append(p)
                    new.append(p)
        frontier = new
    return elems


def _axis_angle(R):
    """(unit axis, angle in [0, pi] rad) of a rotation matrix."""
    angle = math.acos(max(-1.0, min(1.0, (np.trace(R) - 1) / 2)))
    if angle < 1e-9:
        return np.array([0.0, 0.0, 1.0]), 0.0
    if math.pi - angle < 1e-4:
        w, v = np.linalg.eigh((R + R.T) / 2)
        return v[:, int(np.argmax(w))], angle
    axis = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    return axis / np.linalg.norm(axis), angle


class _Search:
    """One detection run: the mesh, its tolerance (mm), centroid, principal axes and
    distance oracle; test(R) is one full acceptance test of a rotation about c."""

    def __init__(self, V, F, tol, seed):
        self.V = V
        self.F = F
        self.rng = np.random.default_rng(seed)
        self.diam = diameter(V)
        self.tol = default_tolerance(self.diam) if tol is None else float(tol)
        self.c, M = surface_moments(V, F)
        self.evals, self.evecs = np.linalg.eigh(M)
        self.oracle = SurfaceDistance(V, F, self.tol, self.rng)
        self.P = np.unique(V[np.unique(F)], axis=0) - self.c
        self.tests = 0

    def test(self, R):
        self.tests += 1
        return self.oracle.is_symmetry(R, self.c)[0]

    # -- one invariant axis -------------------------------------------------
    def continuous_about(self, u):
        return all(self.test(rotation(u, a)) for a in CONTINUOUS_ANGLES)

    def order_about(self, u, plane_equal):
        orders = range(2, MAX_ORDER + 1) if plane_equal else [2]
        passing = [n for n in orders
                   if self.oracle.is_symmetry(rotation(u, 2 * math.pi / n), self.c, coarse_only=True)[0]]
        for n in sorted(passing, reverse=True):
            if self.test(rotation(u, 2 * math.pi / n)):
                return n
        return 1

    def flip_profile_possible(self, u):
        """Necessary condition for any flip perpendicular to u: the (radius, height)
        profile of the surface is symmetric under height -> -height."""
        S = self.oracle.samples - self.c
        h = S @ u
        r = np.linalg.norm(S - np.outer(h, u), axis=1)
        # Profile samples repeat a lot (a cylinder's all share one r): keep one per
        # grid cell of tol / 4, which also keeps the tree balanced.
        q = self.tol / 4
        cells = np.unique(np.round(np.stack([r, h], axis=1) / q), axis=0) * q
        tree = cKDTree(cells)
        X = self.oracle.test_points - self.c
        hx = X @ u
        rx = np.linalg.norm(X - np.outer(hx, u), axis=1)
        d, _ = tree.query(np.stack([rx, -hx], axis=1), k=1)
        return bool(np.all(d <= self.tol + 2 * self.oracle.spacing + q))

    def flip_candidates(self, u, a, b, order, extra_dirs):
        """Candidate flip-axis angles in the (a, b) plane, most supported first."""
        period = math.pi / order
        P = self.P
        h = P @ u
        x, y = P @ a, P @ b
        r = np.hypot(x, y)
        theta = np.arctan2(y, x)
        rmax = float(r.max())
        delta = max(self.tol / rmax, 1e-4)
        angles = [math.atan2(float(d @ b), float(d @ a)) % period for d in extra_dirs]
        tree = cKDTree(np.stack([r, h], axis=1))
        refs = np.nonzero(r > 0.1 * rmax)[0]
        if len(refs) > 400:
            refs = np.sort(self.rng.choice(refs, size=400, replace=False))
        votes = []
        for i in refs:
            js = tree.query_ball_point([r[i], -h[i]], self.tol)
            if len(js) > 240:
                continue        # a faceted circle matches everything: no information
            votes.extend(((theta[i] + theta[js]) / 2) % period)
        ranked = []
        if votes:
            votes = np.sort(np.asarray(votes))
            bins = np.floor(votes / delta).astype(np.int64)
            ub, counts = np.unique(bins, return_counts=True)
            for k in np.argsort(-counts, kind="stable")[:24]:
                sel = votes[(bins >= ub[k] - 1) & (bins <= ub[k] + 1)]
                # The mode of the raw angles: exact mirror pairs agree to ~1e-5 rad.
                lo = np.searchsorted(sel, sel - delta / 20)
                hi = np.searchsorted(sel, sel + delta / 20, side="right")
                j = int(np.argmax(hi - lo))
                ranked.append(float(sel[lo[j]:hi[j]].mean()))
        out = []
        for t in angles + ranked:
            if not any(min(abs(t - s), period - abs(t - s)) < delta / 4 for s in out):
                out.append(t)
        return out

    def search_axis(self, u, plane_equal, in_plane):
        """Symmetries when u is an invariant axis. Returns (generators, continuous)."""
        u = _canonical_axis(u / np.linalg.norm(u))
        if self.continuous_about(u):
            w = _perpendicular(u)
            gens = [rotation(w, math.pi)] if self.test(rotation(w, math.pi)) else []
            return gens, u
        order = self.order_about(u, plane_equal)
        gens = [rotation(u, 2 * math.pi / order)] if order > 1 else []
        if self.flip_profile_possible(u):
            a = in_plane[0] - np.dot(in_plane[0], u) * u
            a /= np.linalg.norm(a)
            b = np.cross(u, a)
            for t in self.flip_candidates(u, a, b, order, in_plane):
                F = rotation(math.cos(t) * a + math.sin(t) * b, math.pi)
                if self.test(F):
                    gens.append(F)
                    break
        return gens, None

    # -- isotropic inertia ----------------------------------------------------
    def correspondence_rotations(self, max_hyp=3000):
        P = self.P
        r = np.linalg.norm(P, axis=1)
        order = np.argsort(r, kind="stable")
        rs = r[order]
        count = np.searchsorted(rs, r + self.tol, side="right") - np.searchsorted(rs, r - self.tol)
        cand = np.nonzero(r > 0.3 * r.max())[0]
        i1 = int(cand[np.argmin(count[cand])])
        cosang = (P[cand] @ P[i1]) / (r[cand] * r[i1])
        c2 = cand[np.abs(cosang) < math.cos(math.radians(25))]
        if len(c2) == 0:
            return []
        i2 = int(c2[np.argmin(count[c2])])
        p1, p2 = P[i1], P[i2]
        M1 = np.nonzero(np.abs(r - r[i1]) <= self.tol)[0]
        M2 = np.nonzero(np.abs(r - r[i2]) <= self.tol)[0]
        d12 = np.linalg.norm(p1 - p2)
        hyps = []
        for q1 in M1:
            dist = np.linalg.norm(P[M2] - P[q1], axis=1)
            for q2 in M2[np.abs(dist - d12) <= 2 * self.tol]:
                hyps.append((q1, q2))
        if len(hyps) > max_hyp:
            keep = np.sort(self.rng.choice(len(hyps), size=max_hyp, replace=False))
            hyps = [hyps[k] for k in keep]
        src = np.stack([p1, p2, np.cross(p1, p2) / r[i1]])
        found = []
        for q1, q2 in hyps:
            dst = np.stack([P[q1], P[q2], np.cross(P[q1], P[q2]) / r[i1]])
            U, _, Wt = np.linalg.svd(src.T @ dst)
            D = np.diag([1.0, 1.0, np.sign(np.linalg.det(Wt.T @ U.T))])
            R = Wt.T @ D @ U.T
            if _close(R, np.eye(3), 1e-6) or any(_close(R, g, 1e-3) for g in found):
                continue
            R = _snap(R)
            if self.test(R):
                found.append(R)
        return found

    def run(self):
        """(generator rotations, continuous axis or None) for the whole mesh."""
        l0, l1, l2 = self.evals
        g01, g12 = (l1 - l0) / l2, (l2 - l1) / l2
        self.gaps = (float(g01), float(g12))
        if g01 < EIGEN_EQUAL and g12 < EIGEN_EQUAL:
            found = self.correspondence_rotations()
            for R in found:
                axis, _ = _axis_angle(R)
                if self.continuous_about(axis):
                    return self.search_axis(axis, True, [_perpendicular(axis)])
            return found, None
        k = 0 if g01 >= g12 else 2
        u = self.evecs[:, k]
        others = [self.evecs[:, j] for j in range(3) if j != k]
        plane_gap = g12 if k == 0 else g01
        return self.search_axis(u, plane_gap < EIGEN_EQUAL, others)


def _snap(R):
    """Rounds a rotation's angle to the nearest 2*pi*k/n (n <= 64) when within 2e-3 rad."""
    axis, angle = _axis_angle(R)
    for n in range(2, MAX_ORDER + 1):
        k = round(angle * n / (2 * math.pi))
        if k and abs(angle - 2 * math.pi * k / n) < 2e-3:
            return rotation(axis, 2 * math.pi * k / n)
    return R


def _group_name(n_elements, continuous, rotations):
    if continuous is not None:
        return "D_inf" if n_elements > 1 else "C_inf"
    if n_elements == 1:
        return "C1"
    orders = []
    for R in rotations[1:]:
        _, ang = _axis_angle(R)
        orders.append(round(2 * math.pi / ang) if ang > 1e-6 else 1)
    top = max(orders)
    if n_elements == top:
        return f"C{top}"
    if n_elements == 2 * top:
        return f"D{top}"
    return {12: "T", 24: "O", 60: "I"}.get(n_elements, f"G{n_elements}")


def _clean(x, digits):
    v = round(float(x), digits)
    return 0.0 if v == 0 else v


def detect_symmetries(V, F, tol=None, seed=0):
    """Symmetries of mesh (V mm, F triangles). Deterministic for a given seed.

    Returns a dict: tolerance_mm, diameter_mm, group (C1, Cn, Dn, C_inf, D_inf, T, O,
    I), symmetries_discrete (row-major 4x4 lists, translation in mm, identity not
    listed), symmetries_continuous ([{axis, offset}], offset a point on the axis,
    mm), max_error_mm (largest exact distance of 3000 test points moved by a kept
    symmetry), tests (number of full tests).
    """
    V = np.asarray(V, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64)
    s = _Search(V, F, tol, seed)
    gens, cont = s.run()
    elems = group_closure(gens)
    # Products of accepted generators are symmetries of the exact shape; check them on
    # the mesh too, since tolerances could add up.
    kept = [elems[0]] + [R for R in elems[1:] if s.test(R)]
    discrete = []
    for R in kept[1:]:
        T = np.eye(4)
        T[:3, :3] = R
        T[:3, 3] = s.c - R @ s.c
        # Rotation entries to 1e-6, translations to 1e-4 mm (below the mesh's precision).
        discrete.append([_clean(v, 4 if k in (3, 7, 11) else 6) for k, v in enumerate(T.reshape(-1))])
    discrete.sort()
    # Reported error: exact distances on a point subset, for every element kept.
    checks = kept[1:] + ([rotation(cont, a) for a in CONTINUOUS_ANGLES[:2]] if cont is not None else [])
    error = max([s.oracle.exact_error(R, s.c) for R in checks], default=0.0)
    continuous = []
    if cont is not None:
        continuous.append({"axis": [_clean(v, 6) for v in cont],
                           "offset": [_clean(v, 4) for v in s.c]})
    return {
        "tolerance_mm": round(s.tol, 4),
        "diameter_mm": round(s.diam, 4),
        "group": _group_name(len(kept), cont, kept),
        "symmetries_discrete": discrete,
        "symmetries_continuous": continuous,
        "max_error_mm": round(error, 4),
        "inertia_gaps": [round(g, 5) for g in s.gaps],
        "tests": s.tests,
    }

"""Closed tube meshes swept along a planar straight-arc-straight path (pipe elbows).

OpenSCAD can bend a tube (rotate_extrude with an angle) but joining straight legs
to the bend's end faces puts coplanar faces on irrational positions, which CGAL
turns into slivers and the 6-digit export into open edges. Sweeping the whole tube
here gives one exact polyhedron instead, written into the .scad as polyhedron().

Profile: closed loop of (s, r) points, s = arc length along the path (mm), r =
distance from the path (mm), every r > 0 (a tube, never the axis). The swept solid
is, for each profile point, a circle of radius r around the path at s.
"""

import math

import numpy as np


class ElbowPath:
    """Straight leg of length l1 along +y ending at (R, 0, 0), an arc of radius R
    and angle theta (deg) about the z axis, then a straight leg of length l2."""

    def __init__(self, l1, R, theta_deg, l2, arc_steps):
        self.l1, self.R, self.th, self.l2 = l1, R, math.radians(theta_deg), l2
        self.arc_len = R * self.th
        self.length = l1 + self.arc_len + l2
        self.breaks = [l1 + self.arc_len * k / arc_steps for k in range(arc_steps + 1)]

    def frame(self, s):
        """(centre, normal, binormal) at arc length s; normal in the path's plane."""
        if s <= self.l1:
            return np.array([self.R, s - self.l1, 0.0]), np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.0, 1.0])
        if s <= self.l1 + self.arc_len:
            a = (s - self.l1) / self.R
            n = np.array([math.cos(a), math.sin(a), 0.0])
            return self.R * n, n, np.array([0.0, 0.0, 1.0])
        a = self.th
        n = np.array([math.cos(a), math.sin(a), 0.0])
        t = np.array([-math.sin(a), math.cos(a), 0.0])
        return self.R * n + (s - self.l1 - self.arc_len) * t, n, np.array([0.0, 0.0, 1.0])


def _refine(profile, breaks):
    """Inserts points where a profile edge crosses a path break (so bends are sampled)."""
    out = []
    n = len(profile)
    for k in range(n):
        (s0, r0), (s1, r1) = profile[k], profile[(k + 1) % n]
        out.append((s0, r0))
        if abs(s1 - s0) < 1e-12:
            continue
        inner = [b for b in breaks if min(s0, s1) + 1e-9 < b < max(s0, s1) - 1e-9]
        inner.sort(reverse=s1 < s0)
        for b in inner:
            out.append((b, r0 + (r1 - r0) * (b - s0) / (s1 - s0)))
    return out


def swept_tube(profile, path, segments):
    """(points (n, 3), triangles (m, 3)) of the closed swept solid, outward winding."""
    prof = _refine(profile, path.breaks)
    rings = []
    for s, r in prof:
        c, nrm, bin_ = path.frame(s)
        ang = np.arange(segments) * 2 * math.pi / segments
        rings.append(c + r * (np.cos(ang)[:, None] * nrm + np.sin(ang)[:, None] * bin_))
    P = np.vstack(rings)
    F = []
    m = len(prof)
    for k in range(m):
        a0, b0 = k * segments, ((k + 1) % m) * segments
        for j in range(segments):
            j1 = (j + 1) % segments
            F.append((a0 + j, b0 + j, b0 + j1))
            F.append((a0 + j, b0 + j1, a0 + j1))
    F = np.array(F, dtype=np.int64)
    a, b, c = P[F[:, 0]], P[F[:, 1]], P[F[:, 2]]
    if np.einsum("ij,ij->i", a, np.cross(b, c)).sum() < 0:
        F = F[:, ::-1]
    return P, F

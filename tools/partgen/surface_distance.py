"""Point-to-surface distance tests on a triangle mesh (mm), for symmetry detection.

SurfaceDistance.all_within(X) answers "is every point of X within tol of the mesh
surface?" with exact point-to-triangle distances: a point whose nearest dense surface
sample is within tol passes at once (the sample lies on the surface, so the true
distance is no larger); the others are measured exactly against the triangles of
their k nearest samples. Measured distances are upper bounds of the true distance,
equal to it unless the true nearest triangle has no sample among the k nearest.
"""

import numpy as np
from scipy.spatial import cKDTree


def triangle_areas(V, F):
    return 0.5 * np.linalg.norm(np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]]), axis=1)


def sample_surface(V, F, n, rng):
    """n area-weighted uniform points on the surface and their triangle ids."""
    area = triangle_areas(V, F)
    tri = rng.choice(len(F), size=n, p=area / area.sum())
    r1 = np.sqrt(rng.random(n))
    r2 = rng.random(n)
    w = np.stack([1 - r1, r1 * (1 - r2), r1 * r2], axis=1)
    P = np.einsum("nk,nkd->nd", w, V[F[tri]])
    return P, tri


def _segment_distance(P, A, B):
    ab = B - A
    t = np.einsum("...d,...d->...", P - A, ab) / np.maximum(np.einsum("...d,...d->...", ab, ab), 1e-300)
    t = np.clip(t, 0.0, 1.0)
    return np.linalg.norm(P - (A + t[..., None] * ab), axis=-1)


def point_triangle_distance(P, A, B, C):
    """Exact Euclidean distance from points P to triangles (A, B, C), broadcast over
    leading dimensions. Inside the prism over the triangle it is the plane distance,
    otherwise the distance to the nearest of the three edges."""
    ab, ac = B - A, C - A
    n = np.cross(ab, ac)
    nn = np.einsum("...d,...d->...", n, n)
    ap = P - A
    safe = np.maximum(nn, 1e-300)
    # Barycentric coordinates of the projection of P onto the plane.
    v = np.einsum("...d,...d->...", np.cross(ap, ac), n) / safe
    w = np.einsum("...d,...d->...", np.cross(ab, ap), n) / safe
    inside = (v >= 0) & (w >= 0) & (v + w <= 1) & (nn > 0)
    plane = np.abs(np.einsum("...d,...d->...", ap, n)) / np.sqrt(safe)
    edge = np.minimum(np.minimum(_segment_distance(P, A, B), _segment_distance(P, B, C)),
                      _segment_distance(P, C, A))
    return np.where(inside, plane, edge)


class SurfaceDistance:
    """Dense surface samples of one mesh in a cKDTree, plus the test point sets.

    tol: acceptance distance (mm). rng: numpy Generator (the only randomness).
    """

    def __init__(self, V, F, tol, rng, max_dense=250_000, n_test_random=8000):
        self.V, self.F, self.tol = V, F, float(tol)
        self.A, self.B, self.C = V[F[:, 0]], V[F[:, 1]], V[F[:, 2]]
        area = triangle_areas(V, F)
        total = float(area.sum())
        n_dense = int(np.clip(total / self.tol ** 2, 20_000, max_dense))
        dense, dense_tri = sample_surface(V, F, n_dense, rng)
        # Every triangle, however small, gets its centroid and three near-corner points.
        m = len(F)
        bary = np.array([[1 / 3, 1 / 3, 1 / 3], [0.8, 0.1, 0.1], [0.1, 0.8, 0.1], [0.1, 0.1, 0.8]])
        per_tri = np.einsum("bk,mkd->mbd", bary, V[F]).reshape(-1, 3)
        per_tri_id = np.repeat(np.arange(m), 4)
        self.samples = np.vstack([per_tri, dense])
        self.sample_tri = np.concatenate([per_tri_id, dense_tri])
        self.tree = cKDTree(self.samples)
        self.spacing = float(np.sqrt(total / len(self.samples)))
        # Test points: all vertices, all centroids, area-weighted extras.
        used = np.unique(F)
        rand, _ = sample_surface(V, F, n_test_random, rng)
        self.test_vertices = V[used]
        self.test_points = np.vstack([self.test_vertices, per_tri[::4], rand])
        nv = len(self.test_vertices)
        pick_v = rng.choice(nv, size=min(160, nv), replace=False)
        pick_o = nv + rng.choice(len(self.test_points) - nv, size=min(160, len(self.test_points) - nv),
                                 replace=False)
        self.coarse_points = self.test_points[np.concatenate([pick_v, pick_o])]
        pick = rng.choice(len(self.test_points), size=min(3000, len(self.test_points)), replace=False)
        self.report_points = self.test_points[np.sort(pick)]

    def exact_distance(self, X, k=32):
        """Distance of each point of X to the triangles of its k nearest samples."""
        k = min(k, len(self.samples))
        _, idx = self.tree.query(X, k=k)
        idx = idx.reshape(len(X), k)
        tri = self.sample_tri[idx]
        d = point_triangle_distance(X[:, None, :], self.A[tri], self.B[tri], self.C[tri])
        return d.min(axis=1)

    def max_distance_if_within(self, X):
        """(all points within tol, max measured distance); the max is exact only for
        points that needed the exact path, an upper bound for the others."""
        d, _ = self.tree.query(X, k=1)
        bad = np.nonzero(d > self.tol)[0]
        if len(bad) == 0:
            return True, float(d.max())
        bad = bad[np.argsort(-d[bad], kind="stable")]
        # The farthest points decide a rejection almost always: measure them first.
        head = bad[:16]
        dh = self.exact_distance(X[head])
        if np.any(dh > self.tol):
            still = head[dh > self.tol]
            dh2 = self.exact_distance(X[still], k=128)
            if np.any(dh2 > self.tol):
                return False, float(dh2.max())
        de = self.exact_distance(X[bad])
        still = bad[de > self.tol]
        if len(still):
            de2 = self.exact_distance(X[still], k=128)
            if np.any(de2 > self.tol):
                return False, float(de2.max())
            de[de > self.tol] = de2
        d = d.copy()
        d[bad] = de
        return True, float(d.max())

    def is_symmetry(self, R, center, coarse_only=False):
        """Whether x -> R (x - center) + center maps the surface onto itself within tol.
        Returns (accepted, max measured distance in mm)."""
        R = np.asarray(R, dtype=np.float64)
        t = center - R @ center
        ok, err = self.max_distance_if_within(self.coarse_points @ R.T + t)
        if not ok or coarse_only:
            return ok, err
        return self.max_distance_if_within(self.test_points @ R.T + t)

    def exact_error(self, R, center):
        """Largest exact distance (mm) of 3000 test points moved by the rotation R
        about center: the figure reported for an accepted symmetry."""
        R = np.asarray(R, dtype=np.float64)
        X = self.report_points @ R.T + (center - R @ center)
        return float(self.exact_distance(X).max())

"""Unit tests of symmetry detection on meshes made in code.

Run: /usr/bin/python3 -m unittest discover tests/tools/partgen (ctest: tools.partgen_symmetry)
"""

import math
import os
import sys
import unittest

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "../../../tools/partgen"))

import mesh_io  # noqa: E402
import mesh_shapes as ms  # noqa: E402
from symmetry import detect_symmetries, rotation, surface_moments  # noqa: E402


def _as_matrices(result):
    return [np.array(t).reshape(4, 4) for t in result["symmetries_discrete"]]


def _random_rotation(seed):
    q = np.random.default_rng(seed).normal(size=4)
    q /= np.linalg.norm(q)
    w, x, y, z = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


class SymmetryTest(unittest.TestCase):
    def check_is_symmetry(self, V, T, tol):
        """Every vertex moved by T lands on a vertex (prisms: vertices map to vertices)."""
        W = V @ T[:3, :3].T + T[:3, 3]
        d = np.min(np.linalg.norm(W[:, None, :] - V[None, :, :], axis=2), axis=1)
        self.assertLessEqual(float(d.max()), tol)

    def test_box_three_sides_is_d2(self):
        V, F = ms.centred(*ms.prism(ms.rectangle(40, 30), 20))
        r = detect_symmetries(V, F)
        self.assertEqual(len(r["symmetries_discrete"]), 3)
        self.assertEqual(r["group"], "D2")
        self.assertEqual(r["symmetries_continuous"], [])
        for T in _as_matrices(r):
            self.assertAlmostEqual(np.trace(T[:3, :3]), -1.0, places=5)
            self.check_is_symmetry(V, T, 1e-4)

    def test_square_plate_is_d4(self):
        V, F = ms.centred(*ms.prism(ms.rectangle(50, 50), 6))
        r = detect_symmetries(V, F)
        self.assertEqual(len(r["symmetries_discrete"]), 7)
        self.assertEqual(r["group"], "D4")
        for T in _as_matrices(r):
            self.check_is_symmetry(V, T, 1e-4)

    def test_hexagonal_prism_is_d6(self):
        V, F = ms.centred(*ms.prism(ms.regular_polygon(6, 15, phase=0.3), 12))
        r = detect_symmetries(V, F)
        self.assertEqual(len(r["symmetries_discrete"]), 11)
        self.assertEqual(r["group"], "D6")
        for T in _as_matrices(r):
            self.check_is_symmetry(V, T, 1e-4)

    def test_cylinder_is_continuous_with_flip(self):
        V, F = ms.centred(*ms.prism(ms.regular_polygon(96, 10), 30))
        r = detect_symmetries(V, F)
        self.assertEqual(len(r["symmetries_continuous"]), 1)
        axis = np.array(r["symmetries_continuous"][0]["axis"])
        self.assertGreater(abs(axis[2]), 0.9999)
        np.testing.assert_allclose(r["symmetries_continuous"][0]["offset"], [0, 0, 0], atol=1e-3)
        self.assertEqual(len(r["symmetries_discrete"]), 1)
        T = _as_matrices(r)[0]
        self.assertAlmostEqual(T[2, 2], -1.0, places=5)   # turns the cylinder over
        self.assertEqual(r["group"], "D_inf")

    def test_cylinder_with_full_length_keyway_keeps_one_flip(self):
        # A key slot along the whole prism leaves the turn about the slot's radial line.
        V, F = ms.centred(*ms.prism(ms.circle_with_keyway(96, 12, 4, 2), 25))
        r = detect_symmetries(V, F)
        self.assertEqual(r["symmetries_continuous"], [])
        self.assertEqual(len(r["symmetries_discrete"]), 1)
        T = _as_matrices(r)[0]
        self.assertAlmostEqual(T[0, 0], 1.0, places=5)
        self.assertEqual(r["group"], "C2")

    def test_cylinder_with_keyway_and_flat_has_none(self):
        V, F = ms.centred(*ms.prism(ms.circle_with_keyway(96, 12, 4, 2, flat_y=10.5), 25))
        r = detect_symmetries(V, F)
        self.assertEqual(r["symmetries_discrete"], [])
        self.assertEqual(r["symmetries_continuous"], [])
        self.assertEqual(r["group"], "C1")

    def test_box_with_notch_bigger_than_tolerance_has_none(self):
        V, F = ms.centred(*ms.prism(ms.rectangle_with_notch(40, 30, 9.0, 2.0, 1.0), 20))
        r = detect_symmetries(V, F)
        self.assertGreater(1.0, r["tolerance_mm"])
        self.assertEqual(r["symmetries_discrete"], [])

    def test_box_with_notch_smaller_than_tolerance_keeps_d2(self):
        V, F = ms.prism(ms.rectangle_with_notch(40, 30, 9.0, 2.0, 0.04), 20)
        V = V - np.array([0.0, 0.0, 10.0])
        r = detect_symmetries(V, F)
        self.assertLess(0.04, r["tolerance_mm"])
        self.assertEqual(len(r["symmetries_discrete"]), 3)

    def test_rotated_hex_prism_symmetries_in_rotated_frame(self):
        V0, F = ms.centred(*ms.prism(ms.regular_polygon(6, 15), 12))
        R0 = _random_rotation(7)
        t0 = np.array([3.0, -8.0, 5.0])
        V = V0 @ R0.T + t0
        r = detect_symmetries(V, F, seed=3)
        self.assertEqual(len(r["symmetries_discrete"]), 11)
        # Expected: R0 g R0^T for every g of D6 about the z axis.
        expected = [R0 @ rotation([0, 0, 1], k * math.pi / 3) @ R0.T for k in range(1, 6)]
        expected += [R0 @ rotation([math.cos(k * math.pi / 6), math.sin(k * math.pi / 6), 0], math.pi) @ R0.T
                     for k in range(6)]
        found = _as_matrices(r)
        for E in expected:
            self.assertTrue(any(np.max(np.abs(T[:3, :3] - E)) < 1e-4 for T in found))
        for T in found:
            self.check_is_symmetry(V, T, 1e-3)

    def test_rotated_box_is_d2(self):
        V0, F = ms.centred(*ms.prism(ms.rectangle(40, 30), 20))
        R0 = _random_rotation(11)
        V = V0 @ R0.T + np.array([10.0, 20.0, -5.0])
        r = detect_symmetries(V, F, seed=5)
        self.assertEqual(len(r["symmetries_discrete"]), 3)
        for T in _as_matrices(r):
            self.check_is_symmetry(V, T, 1e-3)

    def test_cube_has_octahedral_group(self):
        V, F = ms.centred(*ms.prism(ms.rectangle(20, 20), 20))
        r = detect_symmetries(V, F)
        self.assertEqual(len(r["symmetries_discrete"]), 23)
        self.assertEqual(r["group"], "O")

    def test_surface_moments_match_samples(self):
        V, F = ms.prism(ms.regular_polygon(5, 10), 7)
        c, M = surface_moments(V, F)
        from surface_distance import sample_surface
        P, _ = sample_surface(V, F, 400_000, np.random.default_rng(0))
        np.testing.assert_allclose(c, P.mean(0), atol=0.05)
        np.testing.assert_allclose(M, np.cov(P.T, bias=True), atol=0.3)


class MeshTest(unittest.TestCase):
    def test_prism_is_closed_and_outward(self):
        V, F = ms.prism(ms.circle_with_keyway(48, 12, 4, 2), 25)
        rep = mesh_io.check_mesh(V, F)
        self.assertTrue(rep["ok"], rep)
        self.assertEqual(rep["components"], 1)

    def test_crease_split_flat_and_smooth(self):
        V, F = ms.prism(ms.regular_polygon(64, 10), 5)
        pos, nrm, faces = mesh_io.crease_split(V, F)
        # Cap vertices have axial normals; side vertices radial ones.
        cap = np.abs(nrm[:, 2]) > 0.999
        side = np.abs(nrm[:, 2]) < 1e-9
        self.assertEqual(int(cap.sum()), 128)
        self.assertEqual(int(side.sum()), 128)
        radial = pos[side, :2] / np.linalg.norm(pos[side, :2], axis=1)[:, None]
        np.testing.assert_allclose(nrm[side, :2], radial, atol=1e-9)

    def test_ply_round_trip(self):
        import tempfile
        V, F = ms.prism(ms.rectangle(10, 20), 3)
        pos, nrm, faces = mesh_io.crease_split(V, F)
        with tempfile.TemporaryDirectory() as d:
            p = os.path.join(d, "x.ply")
            mesh_io.write_ply(p, pos, nrm, faces, "hello")
            P2, N2, F2, comment = mesh_io.read_ply(p)
        self.assertEqual(comment, "hello")
        np.testing.assert_allclose(P2, pos, atol=1e-5)
        np.testing.assert_array_equal(F2, faces)
        self.assertEqual(len(P2), 24)    # a box: 8 corners x 3 faces

    def test_fix_slivers_closes_t_junction(self):
        # A box whose edge (a, b) is split at its midpoint c on one side only, closed
        # by the zero-area triangle (a, b, c), as OpenSCAD's rounding can leave.
        V, F = ms.prism(ms.rectangle(10, 20), 3)
        F = [tuple(int(x) for x in f) for f in F]
        a, b = None, None
        for f in F:
            for k in range(3):
                i, j = f[k], f[(k + 1) % 3]
                if (j, i) in {(g[m], g[(m + 1) % 3]) for g in F for m in range(3)}:
                    a, b, x, face = i, j, f[(k + 2) % 3], f
                    break
            if a is not None:
                break
        c = len(V)
        V = np.vstack([V, (V[a] + V[b]) / 2])
        F.remove(face)
        F += [(a, c, x), (c, b, x), (a, b, c)]
        F = np.array(F, dtype=np.int64)
        before = mesh_io.check_mesh(V, F)
        self.assertEqual(before["degenerate_triangles"], 1)
        F2, n = mesh_io.fix_slivers(V, F)
        after = mesh_io.check_mesh(V, F2)
        self.assertEqual(n, 1)
        self.assertTrue(after["ok"], after)
        self.assertAlmostEqual(after["volume_mm3"], 600.0, places=3)

    def test_weld_is_independent_of_input_order(self):
        V, F = ms.prism(ms.circle_with_keyway(40, 12, 4, 2), 25)
        rng = np.random.default_rng(1)
        perm = rng.permutation(len(V))
        inv = np.argsort(perm)
        V2, F2 = V[perm], inv[F][rng.permutation(len(F))]
        F2 = np.roll(F2, 1, axis=1)          # same triangles, other starting corner
        a, b = mesh_io.weld(V, F), mesh_io.weld(V2, F2)
        np.testing.assert_array_equal(a[0], b[0])
        np.testing.assert_array_equal(a[1], b[1])


if __name__ == "__main__":
    unittest.main()

"""tools/bench/fit_confidence.py against slow, obviously-right twins, on data made in code."""
import itertools
import sys
import unittest
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[3] / "tools/bench"))
import fit_confidence as fc  # noqa: E402


def auc_by_pairs(p, y):
    pos, neg = p[y > 0.5], p[y < 0.5]
    wins = sum(1.0 if a > b else 0.5 if a == b else 0.0 for a, b in itertools.product(pos, neg))
    return wins / (len(pos) * len(neg))


def fit_by_gradient_descent(X, y, ridge, steps=20000, rate=0.5):
    """The same objective (log loss summed, ridge on the weights only), by plain gradient steps."""
    A = np.hstack([np.ones((len(X), 1)), X])
    w = np.zeros(A.shape[1])
    R = ridge * np.eye(A.shape[1])
    R[0, 0] = 0
    for _ in range(steps):
        p = 1 / (1 + np.exp(-(A @ w)))
        w -= rate * (A.T @ (p - y) + R @ w) / len(X)
    return w[0], w[1:]


class FitConfidence(unittest.TestCase):
    def test_auc_matches_every_pair_with_ties(self):
        rng = np.random.default_rng(1)
        for _ in range(20):
            p = np.round(rng.random(40), 1)  # coarse: many ties
            y = (rng.random(40) < 0.4).astype(float)
            if 0 < y.sum() < len(y):
                self.assertAlmostEqual(fc.auc(p, y), auc_by_pairs(p, y), places=12)

    def test_newton_reaches_the_objectives_minimum(self):
        rng = np.random.default_rng(2)
        X = rng.normal(size=(300, 3))
        y = (rng.random(300) < 1 / (1 + np.exp(-(0.5 + X @ np.array([2.0, -1.0, 0.0]))))).astype(float)
        b, w = fc.fit(X, y, ridge=1.0)
        b2, w2 = fit_by_gradient_descent(X, y, ridge=1.0)
        self.assertAlmostEqual(b, b2, places=4)
        np.testing.assert_allclose(w, w2, atol=1e-4)
        # And it recovers the weights the data was drawn from, roughly.
        np.testing.assert_allclose(w, [2.0, -1.0, 0.0], atol=0.6)

    def test_reliability_of_a_calibrated_model_is_near_the_diagonal(self):
        rng = np.random.default_rng(3)
        p = rng.random(20000)
        y = (rng.random(20000) < p).astype(float)
        bins, ece = fc.reliability(p, y)
        self.assertEqual(sum(b["n"] for b in bins), 20000)
        self.assertLess(ece, 0.02)
        # A model that says the opposite is far from it.
        _, bad = fc.reliability(1 - p, y)
        self.assertGreater(bad, 0.3)

    def test_evidence_has_no_margin_without_an_alternative(self):
        m = {"fit_rank": 0.4, "coverage": 0.5, "inlier_fraction": 0.6, "fit_cost_px": 1.5, "has_alternative": 0,
             "alternative_rank": 0.3, "alternative_support": 0.2}
        self.assertEqual(fc.evidence(m), [0.4, 0.5, 0.6, 1.5, 0.0, 0.0, 0.0])
        m["has_alternative"] = 1
        e = fc.evidence(m)
        self.assertEqual(e[4], 1.0)
        self.assertAlmostEqual(e[5], 0.1)
        self.assertEqual(e[6], 0.2)


if __name__ == "__main__":
    unittest.main()

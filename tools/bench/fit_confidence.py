#!/usr/bin/env python3
"""Fit the pipeline's confidence model (vision/pipeline/confidence.hpp) on mfc-eval results.

Every pick candidate of every cycle in the given mfc-eval detect JSONs (the per-type trials'
`candidates` and the all-types cycles' `candidates`) is one sample: its measures, and whether its
pose is right (5 mm / 10 degrees, symmetry-aware). A logistic regression with a small ridge on
the weights is fitted by Newton's method; cross-validation by scene says how well it ranks and
how well its probabilities hold on scenes it did not see. Fit on the generalization bench's dev
split only: the test split is where the model is judged (tools/bench/generalize_report.py).

  fit_confidence.py build/bench/generalize-dev.json [--write] [--json OUT]

--write replaces vision/pipeline/confidence_fitted.hpp with the fitted weights.
"""
import argparse
import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
FITTED = ROOT / "vision/pipeline/confidence_fitted.hpp"
# ConfidenceModel's weights, in its order (PoseEvidence's measures).
FEATURES = ["fit_rank", "coverage", "inlier_fraction", "fit_cost_px", "has_alternative", "alternative_margin",
            "alternative_support"]
RIDGE = 1.0  # on the weights, not the bias: the dev split has a few hundred samples
FOLDS = 5


def evidence(m):
    """PoseCandidate::evidence() from mfc-eval's measures."""
    alt = m.get("has_alternative", 0) > 0.5
    return [m["fit_rank"], m["coverage"], m["inlier_fraction"], m["fit_cost_px"], 1.0 if alt else 0.0,
            m["fit_rank"] - m["alternative_rank"] if alt else 0.0, m["alternative_support"] if alt else 0.0]


def samples(paths):
    """Every candidate with measures: X, y, scene (file, scene id), the input's ambiguous flag and
    score, and for those of an all-types cycle the cycle (file, scene, image) and the height the
    cell's pick weighs (None and 0 for per-type trials)."""
    rows = []
    for path in paths:
        data = json.loads(Path(path).read_text())
        cycles = [(t, None) for t in data["methods"]["fdcm"]["trials"]]
        cycles += [(p, (path, p["scene"], p["image"])) for p in data.get("all_types", [])]
        for cycle, key in cycles:
            for c in cycle.get("candidates", []):
                if "measures" in c:
                    rows.append((evidence(c["measures"]), c["correct"], (path, cycle["scene"]),
                                 c["measures"].get("ambiguous", 0) > 0.5, c["score"], key,
                                 c.get("height_mm", 0.0)))
    if not rows:
        raise SystemExit("fit_confidence: no candidates with measures (an mfc-eval older than the confidence model?)")
    X = np.array([r[0] for r in rows], dtype=float)
    y = np.array([1.0 if r[1] else 0.0 for r in rows])
    return (X, y, [r[2] for r in rows], np.array([r[3] for r in rows]), np.array([r[4] for r in rows]),
            [r[5] for r in rows], np.array([r[6] for r in rows], dtype=float))


def sigmoid(z):
    return 1.0 / (1.0 + np.exp(-np.clip(z, -40, 40)))


def fit(X, y, ridge=RIDGE):
    """Ridge logistic regression by Newton's method; returns (bias, weights)."""
    A = np.hstack([np.ones((len(X), 1)), X])
    w = np.zeros(A.shape[1])
    R = ridge * np.eye(A.shape[1])
    R[0, 0] = 0.0
    for _ in range(100):
        p = sigmoid(A @ w)
        grad = A.T @ (p - y) + R @ w
        H = A.T @ (A * (p * (1 - p))[:, None]) + R + 1e-9 * np.eye(A.shape[1])
        step = np.linalg.solve(H, grad)
        w -= step
        if np.max(np.abs(step)) < 1e-10:
            break
    return w[0], w[1:]


def predict(model, X):
    bias, weights = model
    return sigmoid(bias + X @ weights)


def auc(p, y):
    """Probability that a right sample scores above a wrong one (ties count half)."""
    pos, neg = p[y > 0.5], p[y < 0.5]
    if len(pos) == 0 or len(neg) == 0:
        return float("nan")
    order = np.argsort(np.concatenate([pos, neg]), kind="mergesort")
    ranks = np.empty(len(order))
    values = np.concatenate([pos, neg])[order]
    i = 0
    while i < len(values):  # average ranks over ties
        j = i
        while j + 1 < len(values) and values[j + 1] == values[i]:
            j += 1
        ranks[order[i:j + 1]] = (i + j) / 2.0 + 1
        i = j + 1
    return float((ranks[:len(pos)].sum() - len(pos) * (len(pos) + 1) / 2) / (len(pos) * len(neg)))


def reliability(p, y, bins=10):
    """Per probability bin: count, mean predicted, observed share right; and the expected
    calibration error (count-weighted |observed - predicted|)."""
    edges = np.linspace(0, 1, bins + 1)
    out, ece = [], 0.0
    for k in range(bins):
        sel = (p >= edges[k]) & ((p < edges[k + 1]) if k + 1 < bins else (p <= 1))
        n = int(sel.sum())
        if n:
            out.append({"from": float(edges[k]), "to": float(edges[k + 1]), "n": n,
                        "predicted": float(p[sel].mean()), "observed": float(y[sel].mean())})
            ece += n * abs(p[sel].mean() - y[sel].mean())
    return out, float(ece / max(1, len(p)))


def measures(p, y):
    eps = 1e-12
    logloss = float(-np.mean(y * np.log(p + eps) + (1 - y) * np.log(1 - p + eps)))
    bins, ece = reliability(p, y)
    return {"n": int(len(y)), "right": int(y.sum()), "auc": auc(p, y), "log_loss": logloss,
            "brier": float(np.mean((p - y) ** 2)), "ece": ece, "bins": bins}


def cross_validate(X, y, scenes):
    """Held-out probabilities: scenes dealt into FOLDS folds, each predicted by a fit on the rest."""
    keys = sorted(set(scenes))
    fold_of = {k: i % FOLDS for i, k in enumerate(keys)}
    folds = np.array([fold_of[s] for s in scenes])
    p = np.zeros(len(y))
    for f in range(FOLDS):
        test = folds == f
        if test.any() and (~test).any():
            p[test] = predict(fit(X[~test], y[~test]), X[test])
    return p


def cell_sweep(prob, y, X, cycle, height, thresholds, supports):
    """The cell's pick per all-types cycle (motion::choose_pick with config/sim.yaml's weights:
    score 1, height 0.5 over 100 mm) at each min_score and ambiguity threshold, with the
    candidates' probabilities `prob`: right, wrong and withheld images."""
    cycles = {}
    for k, key in enumerate(cycle):
        if key is not None:
            cycles.setdefault(key, []).append(k)
    has_alt, support = X[:, FEATURES.index("has_alternative")] > 0.5, X[:, FEATURES.index("alternative_support")]
    out = []
    for s in supports:
        for th in thresholds:
            right = wrong = withheld = 0
            for members in cycles.values():
                best, best_u = None, None
                for k in members:
                    if prob[k] < th or (has_alt[k] and support[k] < s):
                        continue
                    u = prob[k] + 0.5 * min(1.0, max(0.0, height[k] / 100.0))
                    if best_u is None or u > best_u:
                        best, best_u = k, u
                if best is None:
                    withheld += 1
                elif y[best] > 0.5:
                    right += 1
                else:
                    wrong += 1
            out.append({"ambiguous_support": s, "min_score": th, "right": right, "wrong": wrong,
                        "withheld": withheld})
    return out


def write_header(model, source, stats):
    bias, weights = model
    fields = ",\n".join(f"    .{name} = {w:.6g}" for name, w in zip(FEATURES, weights))
    FITTED.write_text(f"""#pragma once
// The confidence model's weights as tools/bench/fit_confidence.py fitted them (do not edit; run
// it again): {source}, {stats['n']} candidates ({stats['right']} right), held-out AUC
// {stats['auc']:.3f}, expected calibration error {stats['ece']:.3f} (docs/tuning-log.md).
#include "vision/pipeline/confidence.hpp"

namespace mfcd::vision {{

inline constexpr ConfidenceModel kFittedConfidence{{
    .bias = {bias:.6g},
{fields},
}};

}}  // namespace mfcd::vision
""")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("results", nargs="+", type=Path, help="mfc-eval detect JSON (dev split)")
    ap.add_argument("--write", action="store_true", help=f"write {FITTED.relative_to(ROOT)}")
    ap.add_argument("--json", type=Path, help="the figures as JSON")
    args = ap.parse_args()
    X, y, scenes, ambiguous, score, cycle, height = samples(args.results)
    model = fit(X, y)
    held_out = cross_validate(X, y, scenes)
    report = {
        "inputs": [str(p) for p in args.results],
        "features": FEATURES,
        "bias": float(model[0]),
        "weights": dict(zip(FEATURES, map(float, model[1]))),
        "held_out": measures(held_out, y),
        "in_sample": measures(predict(model, X), y),
        "fit_rank_auc": auc(X[:, 0], y),
        "score_in_input": measures(np.clip(score, 0, 1), y),
        "ambiguous": {"flagged": int(ambiguous.sum()), "flagged_right": int(y[ambiguous].sum()),
                      "unflagged": int((~ambiguous).sum()), "unflagged_right": int(y[~ambiguous].sum())},
    }
    print(f"{len(y)} candidates ({int(y.sum())} right) from {len(set(scenes))} scenes")
    print(f"{'':22} {'AUC':>6} {'logloss':>8} {'Brier':>6} {'ECE':>6}")
    for name in ("held_out", "in_sample", "score_in_input"):
        m = report[name]
        print(f"{name:22} {m['auc']:6.3f} {m['log_loss']:8.3f} {m['brier']:6.3f} {m['ece']:6.3f}")
    print(f"fit_rank alone AUC {report['fit_rank_auc']:.3f}")
    # Each input alone, with the held-out probabilities of the fit on all: a model fitted on
    # several renderers must hold on each.
    report["held_out_per_input"] = {}
    for path in args.results:
        sel = np.array([sc[0] == path for sc in scenes])
        m = measures(held_out[sel], y[sel])
        report["held_out_per_input"][str(path)] = m
        print(f"  held out, {path.name}: {m['n']} candidates ({m['right']} right), AUC {m['auc']:.3f}, "
              f"ECE {m['ece']:.3f}; " + ", ".join(f"{b['from']:.1f}: {b['observed']:.2f}/{b['predicted']:.2f} of {b['n']}"
                                                  for b in m["bins"]))
    print("weights: bias %.3f, " % model[0] + ", ".join(f"{n} {w:.3f}" for n, w in zip(FEATURES, model[1])))
    a = report["ambiguous"]
    print(f"ambiguous (as flagged in the input): {a['flagged']} ({a['flagged_right']} right); "
          f"others {a['unflagged']} ({a['unflagged_right']} right)")
    print("held-out reliability: " + ", ".join(f"{b['from']:.1f}-{b['to']:.1f}: {b['observed']:.2f} of {b['n']}"
                                               for b in report["held_out"]["bins"]))
    sweep = cell_sweep(held_out, y, X, cycle, height, (0.0, 0.1, 0.3, 0.5, 0.7, 0.8, 0.9),
                       (-2.0, 0.0, 0.05, 0.1, 0.2))
    report["cell_sweep"] = sweep
    print("cell's pick, held-out probabilities (ambiguous_support, min_score: right/wrong/withheld):")
    for r in sweep:
        d = r["right"] + r["wrong"]
        print(f"  {r['ambiguous_support']:5.2f} {r['min_score']:.1f}: {r['right']:3d} / {r['wrong']:3d} / "
              f"{r['withheld']:3d}  wrong share {r['wrong'] / d if d else float('nan'):.2f}")
    has_alt = X[:, 4] > 0.5
    for s_ in (0.0, 0.05, 0.1, 0.2, 0.3):
        sel = has_alt & (X[:, 6] < s_)
        print(f"  support < {s_:.2f}: {int(sel.sum())} candidates, {y[sel].mean() if sel.any() else float('nan'):.2f} right")
    if args.json:
        args.json.write_text(json.dumps(report, indent=1))
    if args.write:
        write_header(model, ", ".join(p.name for p in args.results), report["held_out"])
        print(f"wrote {FITTED}")


if __name__ == "__main__":
    sys.exit(main())

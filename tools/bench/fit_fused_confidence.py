#!/usr/bin/env python3
"""Fit the second look's confidence model (FusedConfidenceModel, vision/pipeline/confidence.hpp).

Every fused candidate of every trial in mfc-second-look JSONs (`fused_candidates`) is one sample:
its measures (SecondLookCandidate::evidence()) and whether its pose is right (5 mm / 10 degrees,
symmetry-aware). The fit, cross-validation by scene and the figures are fit_confidence.py's. Fit on
the dev split only; --evaluate judges the written weights on another split without fitting.

  fit_fused_confidence.py build/bench/second-look-dev.json [--write] [--json OUT]
  fit_fused_confidence.py --evaluate build/bench/second-look-test.json

--write replaces vision/pipeline/second_look_fitted.hpp with the fitted weights.
"""
import argparse
import json
import re
import sys
from pathlib import Path

import numpy as np

from fit_confidence import ROOT, cross_validate, fit, measures, predict

FITTED = ROOT / "vision/pipeline/second_look_fitted.hpp"
FEATURES = ["rank_first", "rank_second", "has_alternative", "alternative_margin"]


def samples(paths):
    """X, y and the scene of every fused candidate with measures."""
    X, y, scenes = [], [], []
    for path in paths:
        for t in json.loads(Path(path).read_text())["trials"]:
            for c in t.get("fused_candidates", []):
                X.append([float(c[f]) for f in FEATURES])
                y.append(1.0 if c["right"] else 0.0)
                scenes.append((str(path), t["scene"]))
    if not X:
        raise SystemExit("fit_fused_confidence: no fused_candidates (an mfc-second-look older than the model?)")
    return np.array(X), np.array(y), scenes


def written_model():
    text = FITTED.read_text()
    value = lambda name: float(re.search(rf"\.{name} = ([-0-9.e+]+)", text).group(1))
    return value("bias"), np.array([value(f) for f in FEATURES])


def print_measures(name, m):
    print(f"{name}: {m['n']} candidates ({m['right']} right), AUC {m['auc']:.3f}, ECE {m['ece']:.3f}, "
          f"Brier {m['brier']:.3f}")
    print("  reliability: " + ", ".join(f"{b['from']:.1f}-{b['to']:.1f}: {b['observed']:.2f} of {b['n']} "
                                        f"(mean {b['predicted']:.2f})" for b in m["bins"]))


def best_of_trials(paths, model):
    """Per trial, the best fused candidate's probability and correctness: what a cell's pick sees."""
    p, y = [], []
    for path in paths:
        for t in json.loads(Path(path).read_text())["trials"]:
            cands = t.get("fused_candidates", [])
            if cands:
                x = np.array([[float(cands[0][f]) for f in FEATURES]])
                p.append(float(predict(model, x)[0]))
                y.append(1.0 if cands[0]["right"] else 0.0)
    return np.array(p), np.array(y)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("results", nargs="+", type=Path, help="mfc-second-look JSON")
    ap.add_argument("--evaluate", action="store_true", help="judge the written weights, fit nothing")
    ap.add_argument("--write", action="store_true", help=f"write {FITTED.relative_to(ROOT)}")
    ap.add_argument("--json", type=Path, help="the figures as JSON")
    args = ap.parse_args()
    X, y, scenes = samples(args.results)
    report = {"inputs": [str(p) for p in args.results], "features": FEATURES}
    if args.evaluate:
        model = written_model()
        report["measures"] = measures(predict(model, X), y)
        print_measures("written weights", report["measures"])
    else:
        model = fit(X, y)
        report["held_out"] = measures(cross_validate(X, y, scenes), y)
        report["in_sample"] = measures(predict(model, X), y)
        print_measures("held out (by scene)", report["held_out"])
        print_measures("in sample", report["in_sample"])
    report["bias"], report["weights"] = float(model[0]), dict(zip(FEATURES, map(float, model[1])))
    print("weights: bias %.3f, " % model[0] + ", ".join(f"{n} {w:.3f}" for n, w in zip(FEATURES, model[1])))
    p, yb = best_of_trials(args.results, model)
    report["best_per_trial"] = measures(p, yb)
    print_measures("best fused candidate per trial", report["best_per_trial"])
    for th in (0.3, 0.5, 0.7, 0.9):
        kept = p >= th
        print(f"  score >= {th:.1f}: {int(kept.sum())} of {len(p)} trials kept, "
              f"{int((yb[kept] < 0.5).sum())} of them wrong")
    if args.json:
        args.json.write_text(json.dumps(report, indent=1))
    if args.write and not args.evaluate:
        m = report["held_out"]
        fields = ",\n".join(f"    .{n} = {w:.6g}" for n, w in zip(FEATURES, model[1]))
        FITTED.write_text(f"""#pragma once
// The fused confidence model's weights as tools/bench/fit_fused_confidence.py fitted them (do not
// edit; run it again): {", ".join(p.name for p in args.results)}, {m['n']} candidates ({m['right']} right),
// held-out AUC {m['auc']:.3f}, expected calibration error {m['ece']:.3f} (docs/tuning-log.md).
#include "vision/pipeline/confidence.hpp"

namespace mfcd::vision {{

inline constexpr FusedConfidenceModel kFittedFusedConfidence{{
    .bias = {model[0]:.6g},
{fields},
}};

}}  // namespace mfcd::vision
""")
        print(f"wrote {FITTED}")


if __name__ == "__main__":
    sys.exit(main())

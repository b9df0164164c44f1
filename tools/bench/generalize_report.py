#!/usr/bin/python3
"""Scores a `tools/mfc bench generalize` run and writes docs/generalization.md with its plots.

usage: generalize_report.py RUN.json [--docs DIR]

RUN.json is generalize.py's summary (the splits run, their mfc-eval JSON, teach times, scene
plans). Without --docs it prints the tables only. The scoring rules are stated in the page it
writes (CRITERIA below); every figure comes from the run's JSON.
"""

import argparse
import json
import math
import statistics
import sys
from pathlib import Path

from fit_confidence import auc, reliability

MIN_SCORE = 0.08  # pick.min_score of results that do not name theirs (mfc-eval before --pick-min-score)
CAUSES = ["nothing found", "wrong place", "depth only", "turned in plane", "turned over"]
CRITERIA = """\
A trial is one (image, part type present in it): mfc-detect's pipeline run for that type alone
(the PLC's recipe), its best estimate scored against every instance of the type. It is right when
some instance is within 5 mm (bounding-box centre) and 10 degrees (total rotation angle), after
the model symmetries of `models_info.json` (detected from the mesh by tools/partgen, never declared
by hand). A trial counts at a visibility level when the type's best-visible instance has at least
that `visib_fract`. A wrong estimate's cause, in this order: **nothing found**; **wrong place**
(more than 5 mm off across the optical axis); **depth only** (rotation within 10 degrees, the
distance along the optical axis wrong); **turned in plane** (the rotation error's axis within 45
degrees of the line of sight: turned about it); **turned over** (the axis lies more in the image
plane: flipped or tilted)."""


def cause_of(t):
    if not t.get("found"):
        return "nothing found"
    dx, dy, _ = t["d_t_mm"]
    if math.hypot(dx, dy) > 5:
        return "wrong place"
    if t["rotation_deg"] <= 10:
        return "depth only"
    return "turned in plane" if abs(t["axis_cam"][2]) >= math.cos(math.radians(45)) else "turned over"


def pct(values, q):
    if not values:
        return float("nan")
    v = sorted(values)
    return v[min(len(v) - 1, int(round(q * (len(v) - 1))))]


def load_split(run, parts):
    result = json.loads(Path(run["result"]).read_text())
    family = {p["obj_id"]: p["family"] for p in parts}
    trials = result["methods"]["fdcm"]["trials"]
    for t in trials:
        t["family"] = family.get(t["obj_id"], "?")
        t["cause"] = None if t["correct"] else cause_of(t)
    return result, trials


def failures(trials, level):
    """(wrong, trials) over the trials whose best instance is at least `level` visible."""
    sel = [t for t in trials if t["best_visib_fract"] >= level]
    return sum(not t["correct"] for t in sel), len(sel)


def failure_table(trials, key):
    groups = {}
    for t in trials:
        groups.setdefault(key(t), []).append(t)
    return [(k, failures(g, 0.75), failures(g, 0.5)) for k, g in sorted(groups.items())]


def part_table(trials, parts, lines):
    """One row per part: what an engineer validating that part for a cell looks at first."""
    info = {p["obj_id"]: p for p in parts}
    lines.append("### Per part (best instance >= 75 % visible)\n")
    lines.append("| part | family | symmetry (mesh) | diameter mm | failure | causes of the failures | median score |")
    lines.append("|---|---|---|---:|---:|---|---:|")
    by_part = {}
    for t in trials:
        if t["best_visib_fract"] >= 0.75:
            by_part.setdefault(t["obj_id"], []).append(t)
    for obj, ts in sorted(by_part.items(), key=lambda kv: (info.get(kv[0], {}).get("family", "?"), kv[0])):
        p = info.get(obj, {})
        causes = {}
        for t in ts:
            if t["cause"]:
                causes[t["cause"]] = causes.get(t["cause"], 0) + 1
        scores = [t["score"] for t in ts if t.get("found")]
        lines.append(f"| obj {obj} | {p.get('family', '?')} | {p.get('symmetry', {}).get('group', '?')} | "
                     f"{p.get('diameter_mm', float('nan')):.0f} | {rate(failures(ts, 0.75))} | "
                     f"{', '.join(f'{c} {n}' for c, n in sorted(causes.items())) or '-'} | "
                     f"{statistics.median(scores) if scores else float('nan'):.2f} |")
    lines.append("")


def rate(f):
    bad, n = f
    return f"{bad / n:.2f} ({bad}/{n})" if n else "-"


def cell_view(result):
    right = wrong = withheld = 0
    for p in result.get("all_types", []):
        c = p["cell"][0]
        if not c["picked"]:
            withheld += 1
        elif c["correct"]:
            right += 1
        else:
            wrong += 1
    return right, wrong, withheld


def split_section(split, run, parts, lines, plots):
    result, trials = load_split(run, parts)
    n_images = result["images"]
    lines.append(f"## Split `{split}`: {n_images} images, {len(set(t['obj_id'] for t in trials))} part types\n")
    lines.append("### Failure per family (per-type top-1; best instance >= 75 % / >= 50 % visible)\n")
    lines.append("| family | failure, >= 75 % visible | failure, >= 50 % visible |")
    lines.append("|---|---:|---:|")
    fam = failure_table(trials, lambda t: t["family"])
    for k, f75, f50 in fam:
        lines.append(f"| {k} | {rate(f75)} | {rate(f50)} |")
    all75 = [t for t in trials if t["best_visib_fract"] >= 0.75]
    tot75, tot50 = failures(trials, 0.75), failures(trials, 0.5)
    lines.append(f"| **all** | **{rate(tot75)}** | **{rate(tot50)}** |\n")
    xy_ok = sum(t.get("correct_xy", False) or t["correct"] for t in all75)
    lines.append(f"Over all {len(trials)} trials (any visibility): failure "
                 f"{rate((sum(not t['correct'] for t in trials), len(trials)))}. At >= 75 % visible, "
                 f"{xy_ok} of {len(all75)} best estimates are right when only the position across the "
                 "optical axis and the rotation are asked (`correct_xy`).\n")
    placed = sum(t["correct"] or t["cause"] not in ("nothing found", "wrong place") for t in all75)
    lines.append(f"With rotation and depth ignored (the best estimate within 5 mm of an instance across the "
                 f"optical axis), {placed} of {len(all75)} are right: failure "
                 f"{rate((len(all75) - placed, len(all75)))}.\n")
    part_table(trials, parts, lines)
    lines.append("### Rotation error of the wrong estimates at the right place (>= 75 % visible)\n")
    lines.append("| rotation error | trials |")
    lines.append("|---|---:|")
    turned = [t["rotation_deg"] for t in all75 if t["cause"] in ("turned in plane", "turned over", "depth only")]
    for lo, hi in ((0, 10), (10, 30), (30, 90), (90, 150), (150, 181)):
        label = f"{lo}-{hi} degrees" if hi < 181 else f"over {lo} degrees (turned over or half-turned)"
        lines.append(f"| {label}{' (depth only)' if lo == 0 else ''} | {sum(lo <= r < hi for r in turned)} |")
    lines.append("")
    lines.append("### Failures by cause (>= 75 % visible)\n")
    lines.append("| cause | trials |")
    lines.append("|---|---:|")
    for c in CAUSES:
        lines.append(f"| {c} | {sum(t['cause'] == c for t in all75)} |")
    lines.append("")
    right, wrong, withheld = cell_view(result)
    delivered = right + wrong
    lines.append(f"### The cell's view (recipe 0: all {len(set(t['obj_id'] for t in trials))} types at once)\n")
    min_score = result.get("pick_min_score", MIN_SCORE)
    skip = " and ambiguous candidates passed over" if result.get("pick_skip_ambiguous") else ""
    lines.append(f"Per image, the pick the daemon would deliver (motion::choose_pick with config/sim.yaml's "
                 f"weights, `pick.min_score` {min_score:g}{skip}):\n")
    lines.append("| right | wrong | withheld | wrong share of delivered | images with a pick |")
    lines.append("|---:|---:|---:|---:|---:|")
    lines.append(f"| {right} | {wrong} | {withheld} | "
                 f"{(wrong / delivered if delivered else float('nan')):.2f} | "
                 f"{delivered / n_images if n_images else float('nan'):.2f} |\n")
    sr = [t["score"] for t in trials if t.get("found") and t["correct"]]
    sw = [t["score"] for t in trials if t.get("found") and not t["correct"]]
    lines.append("### Score against correctness (per-type trials, every visibility)\n")
    lines.append(f"Median score of right estimates {statistics.median(sr) if sr else float('nan'):.3f} "
                 f"({len(sr)}), of wrong ones {statistics.median(sw) if sw else float('nan'):.3f} ({len(sw)}).\n")
    lines.append("| threshold | right kept | wrong kept |")
    lines.append("|---:|---:|---:|")
    for th in (0.1, 0.2, 0.3, 0.5, 0.7, 0.9):
        kr = sum(s >= th for s in sr) / len(sr) if sr else float("nan")
        kw = sum(s >= th for s in sw) / len(sw) if sw else float("nan")
        lines.append(f"| {th:.2f} | {kr:.2f} | {kw:.2f} |")
    lines.append("")
    conf = confidence_section(result, lines)
    conf["min_score"] = min_score
    times = [t["times"]["total"] for t in trials]
    stages = ["edges", "lines", "dt", "search", "pose", "refine"]
    all_t = [p["times"]["total"] for p in result.get("all_types", [])]
    teach = [s for s in run["teach_seconds"].values() if s is not None]
    lines.append("### Time\n")
    lines.append(f"Per-type detection: median {pct(times, 0.5):.0f} ms, p90 {pct(times, 0.9):.0f} ms; per stage "
                 "(median ms): " + ", ".join(f"{s} {pct([t['times'][s] for t in trials], 0.5):.1f}" for s in stages)
                 + f". All types at once: median {pct(all_t, 0.5):.0f} ms, p90 {pct(all_t, 0.9):.0f} ms.")
    if teach:
        lines.append(f" Teaching (mfc-teach defaults, K = 300), as timed when each part was taught: median "
                     f"{statistics.median(teach):.0f} s per part, max {max(teach):.0f} s, {len(teach)} parts.")
    lines.append("")
    plots.append((split, fam, sr, sw, conf))
    return {"split": split, "images": n_images, "trials": len(trials), "failure_75": tot75, "failure_50": tot50,
            "causes_75": {c: sum(t["cause"] == c for t in all75) for c in CAUSES},
            "cell": {"right": right, "wrong": wrong, "withheld": withheld},
            "median_score_right": statistics.median(sr) if sr else None,
            "median_score_wrong": statistics.median(sw) if sw else None,
            "detect_ms_median": pct(times, 0.5), "detect_ms_p90": pct(times, 0.9),
            "all_types_ms_median": pct(all_t, 0.5),
            "confidence": {k: conf[k] for k in ("n", "right", "auc", "ece", "ambiguous", "ambiguous_right")}}


def confidence_section(result, lines):
    """Every candidate of every cycle (per type and all types): is its score the probability that
    it is right? A reliability table, the ranking's AUC, and the ambiguous ones."""
    import numpy as np
    cands = [c for t in result["methods"]["fdcm"]["trials"] for c in t.get("candidates", [])]
    cands += [c for p in result.get("all_types", []) for c in p.get("candidates", [])]
    p = np.array([min(1.0, max(0.0, c["score"])) for c in cands])
    y = np.array([1.0 if c["correct"] else 0.0 for c in cands])
    amb = np.array([c.get("measures", {}).get("ambiguous", 0) > 0.5 for c in cands], dtype=bool)
    bins, ece = reliability(p, y) if len(p) else ([], float("nan"))
    out = {"n": int(len(p)), "right": int(y.sum()), "auc": auc(p, y) if len(p) else float("nan"), "ece": ece,
           "bins": bins, "ambiguous": int(amb.sum()), "ambiguous_right": int(y[amb].sum()) if len(p) else 0}
    lines.append("### Confidence: is the score the probability of a right pose?\n")
    lines.append(f"Every candidate of every cycle (per type and all types at once), {out['n']} of them, "
                 f"{out['right']} right. The score ranks right above wrong with AUC {out['auc']:.3f}; "
                 f"expected calibration error {out['ece']:.3f} (the count-weighted gap between a bin's mean "
                 f"score and its share of right poses). Flagged ambiguous: {out['ambiguous']}, of which "
                 f"{out['ambiguous_right']} right.\n")
    lines.append("| score | candidates | mean score | share right |")
    lines.append("|---|---:|---:|---:|")
    for b in bins:
        lines.append(f"| {b['from']:.1f}-{b['to']:.1f} | {b['n']} | {b['predicted']:.2f} | {b['observed']:.2f} |")
    lines.append("")
    return out


def save(fig, ax, title, path):
    """Titles, lays out, writes and closes a plot; returns the file's name."""
    import matplotlib.pyplot as plt
    ax.set_title(title)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path.name


def draw(plots, img_dir):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    img_dir.mkdir(parents=True, exist_ok=True)
    names = []
    for split, fam, sr, sw, conf in plots:
        fig, ax = plt.subplots(figsize=(8, 3.6))
        labels = [k for k, _, _ in fam]
        f75 = [f[0] / f[1] if f[1] else 0 for _, f, _ in fam]
        f50 = [f[0] / f[1] if f[1] else 0 for _, _, f in fam]
        x = range(len(labels))
        ax.bar([i - 0.2 for i in x], f75, 0.4, label=">= 75 % visible")
        ax.bar([i + 0.2 for i in x], f50, 0.4, label=">= 50 % visible")
        ax.set_xticks(list(x), labels, rotation=40, ha="right", fontsize=8)
        ax.set_ylim(0, 1)
        ax.set_ylabel("top-1 failure")
        name = save(fig, ax, f"Failure per family, {split} split", img_dir / f"generalize-{split}-families.png")
        fig, ax = plt.subplots(figsize=(6, 3.2))
        bins = [i / 40 for i in range(41)]
        ax.hist(sr, bins=bins, alpha=0.6, label=f"right ({len(sr)})")
        ax.hist(sw, bins=bins, alpha=0.6, label=f"wrong ({len(sw)})")
        ax.axvline(conf["min_score"], color="k", lw=0.8, ls="--", label="pick.min_score")
        ax.set_xlabel("score of the best estimate")
        ax.set_ylabel("trials")
        name2 = save(fig, ax, f"Score vs correctness, {split} split", img_dir / f"generalize-{split}-scores.png")
        fig, ax = plt.subplots(figsize=(4.2, 4.2))
        ax.plot([0, 1], [0, 1], color="k", lw=0.8, ls="--", label="perfectly calibrated")
        b = conf["bins"]
        ax.plot([x["predicted"] for x in b], [x["observed"] for x in b], "o-", label="candidates per score bin")
        for x in b:
            ax.annotate(str(x["n"]), (x["predicted"], x["observed"]), fontsize=7, xytext=(3, -8),
                        textcoords="offset points")
        ax.set_xlim(0, 1), ax.set_ylim(0, 1)
        ax.set_xlabel("score (predicted probability right)")
        ax.set_ylabel("share right")
        name3 = save(fig, ax, f"Reliability, {split} split", img_dir / f"generalize-{split}-reliability.png")
        names.append((split, name, name2, name3))
    return names


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("run", type=Path)
    ap.add_argument("--docs", type=Path)
    args = ap.parse_args()
    run = json.loads(args.run.read_text())
    parts = json.loads(Path(run["parts"]).read_text())["parts"]
    lines, plots, summary = [], [], []
    for r in run["runs"]:
        summary.append(split_section(r["split"], r, parts, lines, plots))
    body = "\n".join(lines)
    print(body)
    (args.run.parent / args.run.name.replace("-run.json", "-summary.json")).write_text(json.dumps(summary, indent=1))
    if not args.docs:
        return
    names = draw(plots, args.docs / "img")
    head = Path(__file__).with_name("generalize_intro.md").read_text()
    run_par = (f"**Run.** {run['date']}, {run['cpu_model']} ({run['cpus']} cores), {run['wall_s']:.0f} s in all "
               f"(rendering and teaching included unless cached), Cycles {run['samples']} samples per pixel. "
               "Commands: " + "; ".join(f"`{r['eval_command']}`" for r in run["runs"]) + ".\n")
    figs = "\n".join(f"![failure per family, {s}](img/{a})\n![score vs correctness, {s}](img/{b})\n"
                     f"![reliability, {s}](img/{c})\n" for s, a, b, c in names)
    text = head + "\n## How a trial is scored\n\n" + CRITERIA + "\n\n" + run_par + "\n" + body + "\n" + figs
    (args.docs / "generalization.md").write_text(text)
    print(f"wrote {args.docs / 'generalization.md'}", file=sys.stderr)


if __name__ == "__main__":
    main()

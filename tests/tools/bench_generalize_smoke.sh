#!/usr/bin/env bash
# The generalization bench end to end in small (docs/generalization.md): tools/partgen makes one
# part, Blender renders one 160x120 bin of it at 4 samples, tools/benchgen/check_scene.py checks
# its ground truth, mfc-teach teaches it with its defaults and mfc-eval scores per type and over
# all types. Asserts that every stage produced what the next one reads: one trial per type present
# with its errors or 'nothing found', the cell's pick, a report. Exit 77 (skipped) without Blender
# or OpenSCAD.
set -euo pipefail
BUILD="$1" SRC="$2" OUT="$3"
for tool in blender openscad; do
  command -v "$tool" >/dev/null || { echo "SKIP: $tool not installed (tools/mfc setup)"; exit 77; }
done
rm -rf "$OUT" && mkdir -p "$OUT"
/usr/bin/python3 "$SRC/tools/bench/generalize.py" "$BUILD" --smoke --cache "$OUT/cache" --out "$OUT"
/usr/bin/python3 - "$OUT" <<'PY'
import json, sys
from pathlib import Path
out = Path(sys.argv[1])
run = json.loads((out / "generalize-smoke-run.json").read_text())
assert len(run["runs"]) == 1, run
r = run["runs"][0]
result = json.loads(Path(r["result"]).read_text())
trials = result["methods"]["fdcm"]["trials"]
types = {i for s in r["plan"] for i in s["obj_ids"]}
assert result["images"] == 1, result["images"]
assert {t["obj_id"] for t in trials} == types, (trials, types)
for t in trials:
    assert 0 <= t["best_visib_fract"] <= 1, t
    if t["found"]:
        assert {"position_mm", "rotation_deg", "axis_cam", "score"} <= t.keys(), t.keys()
picks = result["all_types"]
assert len(picks) == 1 and "cell" in picks[0], picks
summary = json.loads((out / "generalize-smoke-summary.json").read_text())
assert summary[0]["trials"] == len(trials), summary
assert all(v is not None for v in r["teach_seconds"].values()), r["teach_seconds"]
print(f"smoke: {len(trials)} trial(s), correct {[t['correct'] for t in trials]}, "
      f"cell pick {picks[0]['cell'][0]}, teach {r['teach_seconds']}")
PY

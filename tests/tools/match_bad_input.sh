#!/usr/bin/env bash
# mfc-match refuses bad input with a clear message and a non-zero exit, and writes nothing.
set -u
BIN="$1"
T=$(mktemp -d); trap 'rm -rf "$T"' EXIT
fail=0
expect() {  # expect <exit code> <message fragment> -- command...
  local code="$1" frag="$2"; shift 3
  local out rc
  out=$("$@" 2>&1); rc=$?
  if [[ $rc -ne $code || "$out" != *"$frag"* ]]; then
    echo "FAIL: $* -> exit $rc, wanted $code with '$frag'; output:"; echo "$out" | head -5; fail=1
  else
    echo "ok: $frag"
  fi
}
"$BIN/mfc-synth-2d" --out "$T" --copies 2 > /dev/null
printf 'mfcd-lines 1\nq 60\nsize 100 100\n1 2 3\n' > "$T/bad.lines"
printf 'mfcd-lines 1\nq 0\nsize 100 100\n1 2 30 40\n' > "$T/q0.lines"
printf 'mfcd-lines 1\nq 60\nsize 100 100\n5 5 5.3 5.2\n' > "$T/zero.lines"
printf 'not an image' > "$T/garbage.png"
: > "$T/empty.png"
expect 1 "bad.lines:4: segment 'x1 y1 x2 y2': expected 4 numbers, got 3" -- "$BIN/mfc-match" --template "$T/bad.lines" --query "$T/query.png"
expect 1 "q0.lines:2: q must be an integer" -- "$BIN/mfc-match" --template "$T/q0.lines" --query "$T/query.png"
expect 1 "zero.lines:4: zero-length segment" -- "$BIN/mfc-match" --template "$T/zero.lines" --query "$T/query.png"
expect 1 "garbage.png: not a readable image" -- "$BIN/mfc-match" --template "$T/garbage.png" --query "$T/query.png"
expect 1 "empty.png: not a readable image" -- "$BIN/mfc-match" --template "$T/template_tnut.png" --query "$T/empty.png"
expect 1 "missing.png: no such file" -- "$BIN/mfc-match" --template "$T/missing.png" --query "$T/query.png"
expect 2 "--query is required" -- "$BIN/mfc-match" --template "$T/template_tnut.png"
expect 2 "unknown option '--frobnicate'" -- "$BIN/mfc-match" --frobnicate
expect 2 "expects a number" -- "$BIN/mfc-match" --template "$T/template_tnut.png" --query "$T/query.png" --threshold abc
expect 1 "threshold must be > 0" -- "$BIN/mfc-match" --template "$T/template_tnut.png" --query "$T/query.png" --threshold -1
expect 1 "q must be in 1..180" -- "$BIN/mfc-match" --template "$T/template_tnut.png" --query "$T/query.png" --q 0
[[ ! -e "$T/out.json" ]] || { echo "FAIL: wrote output on error"; fail=1; }
# And the good path writes JSON and an overlay.
"$BIN/mfc-match" --template "$T/template_tnut.png" --query "$T/query.png" --json "$T/out.json" --overlay "$T/o.png" > /dev/null || fail=1
grep -q '"detections"' "$T/out.json" && [[ -s "$T/o.png" ]] || { echo "FAIL: no JSON/overlay"; fail=1; }
exit $fail

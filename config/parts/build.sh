#!/usr/bin/env bash
# Renders every config/parts/*.scad to OUTDIR/<name>.stl with OpenSCAD (headless; no
# display needed for STL export). Skips parts whose STL is newer than the source.
# Usage: config/parts/build.sh OUTDIR
set -euo pipefail
[[ $# -eq 1 ]] || { echo "usage: $0 OUTDIR" >&2; exit 2; }
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
out="$1"
command -v openscad >/dev/null || { echo "$0: openscad not found (apt-get install openscad openscad-mcad)" >&2; exit 1; }
mkdir -p "$out"
pids=()
for src in "$here"/*.scad; do
  name="$(basename "$src" .scad)"
  dst="$out/$name.stl"
  if [[ -f "$dst" && "$dst" -nt "$src" ]]; then continue; fi
  # Write to a temporary name so an interrupted run never leaves a truncated STL behind.
  ( openscad -q -o "$dst.tmp.stl" "$src" && mv "$dst.tmp.stl" "$dst" ) &
  pids+=($!)
  # Two at a time: the target machines have two cores.
  if (( ${#pids[@]} >= 2 )); then wait "${pids[0]}"; pids=("${pids[@]:1}"); fi
done
for p in "${pids[@]}"; do wait "$p"; done
for src in "$here"/*.scad; do
  [[ -s "$out/$(basename "$src" .scad).stl" ]] || { echo "$0: failed to render $src" >&2; exit 1; }
done
# Mark every STL as up to date (build systems compare its time with this script too).
touch "$out"/*.stl

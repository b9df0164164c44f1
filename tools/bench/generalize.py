#!/usr/bin/python3
"""tools/mfc bench generalize: the pipeline on parts and images nobody designed it for.

Parts from tools/partgen (a dev and a test split by seed), bins of them path-traced by Blender
Cycles (tools/benchgen/render_bin.py, no code shared with vision/render), every part taught with
mfc-teach's defaults for a camera made from the dataset, then mfc-eval detect per part type (the
PLC's recipe) and over all types at once (recipe 0), scored with the symmetries models_info.json
gives (detected from the meshes). tools/bench/generalize_report.py writes docs/generalization.md.

Everything generated is cached outside the checkout (--cache, default $MFC_BENCH_CACHE or
~/.cache/mfcd-bench), keyed by what made it: the part generator's version, the renderer
modules' hash, the camera and the teacher binary's hash. A scene folder or template file that exists is
complete (both are written under a temporary name and renamed), so an interrupted run resumes.
"""

import argparse
import hashlib
import json
import os
import random
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
PY = "/usr/bin/python3" if os.path.exists("/usr/bin/python3") else sys.executable

# The cameras of the two splits: neither is config/camera-sim.yaml's (f 1100 px, 300 mm, ring
# 40 mm at 0 deg), and they differ from each other, so nothing fitted to one camera carries over
# unnoticed. The renderer moves the bin floor per scene around floor_mm.
CAMERAS = {
    "dev": {"fx": 1150.0, "fy": 1150.0, "cx": 318.4, "cy": 241.3, "width": 640, "height": 480,
            "floor_mm": 295.0, "ring_radius_mm": 38.0, "ring_first_deg": -5.0},
    "test": {"fx": 1000.0, "fy": 1000.0, "cx": 321.7, "cy": 238.2, "width": 640, "height": 480,
             "floor_mm": 310.0, "ring_radius_mm": 45.0, "ring_first_deg": 10.0},
    # ctest's smoke run: a small image so that one scene renders in seconds.
    "smoke": {"fx": 550.0, "fy": 550.0, "cx": 160.2, "cy": 119.6, "width": 320, "height": 240,
              "floor_mm": 300.0, "ring_radius_mm": 40.0, "ring_first_deg": 0.0},
}
SCENE_SEED_BASE = {"dev": 100000, "test": 200000, "smoke": 900000}


def say(msg):
    print(f"[generalize] {msg}", file=sys.stderr, flush=True)


def run(cmd, **kw):
    """Runs a command; on failure shows it and its output and stops the bench."""
    r = subprocess.run([str(c) for c in cmd], capture_output=True, text=True, **kw)
    if r.returncode != 0:
        sys.stderr.write(r.stdout[-4000:] + r.stderr[-4000:])
        raise SystemExit(f"generalize: failed ({r.returncode}): {' '.join(str(c) for c in cmd)}")
    return r


def digest(*parts):
    h = hashlib.sha256()
    for p in parts:
        h.update(p if isinstance(p, bytes) else str(p).encode())
    return h.hexdigest()[:12]


def file_digest(path):
    return digest(Path(path).read_bytes())


def program_digest(path):
    """A program's digest without the commit hash its --version names (cmake/MfcVersion.cmake): the
    same code built at another commit teaches the same templates."""
    data = Path(path).read_bytes()
    out = subprocess.run([str(path), "--version"], capture_output=True, text=True).stdout
    m = re.search(r"\(([^()]+)\)\s*$", out)
    if m:
        data = data.replace(m.group(1).encode(), b"#" * len(m.group(1)))
    return digest(data)


def renderer_digest():
    """What the images depend on: every module of the renderer (not its checker)."""
    files = sorted(p for p in (ROOT / "tools/benchgen").glob("*.py") if p.name != "check_scene.py")
    return digest(*(f.name.encode() + f.read_bytes() for f in files))


def flash_positions(cam):
    import math
    out = []
    for k in range(8):
        a = math.radians(cam["ring_first_deg"] + 45.0 * k)
        out.append([cam["ring_radius_mm"] * math.cos(a), cam["ring_radius_mm"] * math.sin(a), 0.0])
    return out


def write_camera_files(cam, folder):
    """camera.yaml (mfc-teach, docs/camera.md) and camera-render.json (the renderer)."""
    folder.mkdir(parents=True, exist_ok=True)
    yaml = f"""%YAML:1.0
---
# Made by tools/bench/generalize.py from the bench dataset's camera.
image_width: {cam['width']}
image_height: {cam['height']}
camera_matrix: !!opencv-matrix
   rows: 3
   cols: 3
   dt: d
   data: [ {cam['fx']}, 0., {cam['cx']}, 0., {cam['fy']}, {cam['cy']}, 0., 0., 1. ]
distortion_coefficients: !!opencv-matrix
   rows: 1
   cols: 5
   dt: d
   data: [ 0., 0., 0., 0., 0. ]
working_distance_mm: {cam['floor_mm']}
flashes:
   ring_radius_mm: {cam['ring_radius_mm']}
   first_angle_deg: {cam['ring_first_deg']}
   step_deg: 45.
   plane_z_mm: 0.
   count: 8
"""
    (folder / "camera.yaml").write_text(yaml)
    render = {k: cam[k] for k in ("fx", "fy", "cx", "cy", "width", "height")}
    render["flash_positions_mm"] = flash_positions(cam)
    render["floor_distance_mm"] = cam["floor_mm"]
    (folder / "camera-render.json").write_text(json.dumps(render, indent=1))
    return folder / "camera.yaml", folder / "camera-render.json"


def make_parts(args, cache):
    """tools/partgen into the cache (it skips parts it already made)."""
    out = cache / "parts"
    cmd = [PY, ROOT / "tools/partgen/partgen.py", "--out", out]
    cmd += ["--families", "plate", "--count-per-family", 1] if args.smoke else ["--count-per-family", args.parts_per_family]
    say(f"parts: {' '.join(str(c) for c in cmd[1:])}")
    t0 = time.time()
    subprocess.run([str(c) for c in cmd], check=True)
    parts = json.loads((out / "parts.json").read_text())
    say(f"parts: {len(parts['parts'])} in {time.time() - t0:.0f} s (generator {parts['generator_version']})")
    return out, parts


def split_parts(parts, split):
    wanted = "dev" if split == "smoke" else split
    return [p for p in parts["parts"] if p["split"] == wanted]


def scene_plan(split, n_scenes, obj_ids, smoke):
    """The part types of each scene, drawn from its seed: 1-3 types per scene."""
    plan = []
    for i in range(1, n_scenes + 1):
        seed = SCENE_SEED_BASE[split] + i
        rng = random.Random(seed)
        k = 1 if smoke else rng.choice([1, 2, 2, 3])
        plan.append({"scene_id": i, "seed": seed, "obj_ids": sorted(rng.sample(obj_ids, min(k, len(obj_ids))))})
    return plan


def prepare_dataset(args, cache, parts_dir, parts, split):
    """The split's BOP dataset folder: its models, camera files and scene plan."""
    cam = CAMERAS[split]
    key = digest(parts["generator_version"], renderer_digest(), json.dumps(cam, sort_keys=True), args.samples)
    root = cache / f"scenes-{split}-{key}"
    if args.second_view_deg:  # two-view scenes: their own folder, never a one-view one
        key = digest(key, f"second_view_deg={args.second_view_deg!r}")
        root = cache / f"scenes-{split}-2view{args.second_view_deg:g}-{key}"
    models_src = parts_dir / ("dev" if split == "smoke" else split) / "models"
    mine = split_parts(parts, split)
    if split == "smoke":
        mine = mine[:1]
    n_scenes = 1 if split == "smoke" else (args.scenes_test if split == "test" else args.scenes_dev)
    plan = scene_plan(split, n_scenes, [p["obj_id"] for p in mine], split == "smoke")
    # The parts the scenes hold, in the order they first appear: what is taught and looked for.
    ids = list(dict.fromkeys(i for s in plan for i in s["obj_ids"]))
    models = root / "models"
    models.mkdir(parents=True, exist_ok=True)
    info = json.loads((models_src / "models_info.json").read_text())
    for i in ids:
        name = f"obj_{i:06d}.ply"
        if not (models / name).exists():
            shutil.copyfile(models_src / name, models / name)
    (models / "models_info.json").write_text(json.dumps({str(i): info[str(i)] for i in ids}, indent=1))
    cam_yaml, cam_render = write_camera_files(cam, root)
    (root / "camera.json").write_text(json.dumps({k: cam[k] for k in ("fx", "fy", "cx", "cy", "width", "height")}
                                                 | {"depth_scale": 0.1}, indent=1))
    (root / "plan.json").write_text(json.dumps(plan, indent=1))
    return root, cam_yaml, cam_render, ids, plan


def run_check(root, *args):
    """tools/benchgen/check_scene.py on the dataset's split `test`: (passed, its output)."""
    check = [str(c) for c in (PY, ROOT / "tools/benchgen/check_scene.py", "--dataset", root, "--split", "test", *args)]
    r = subprocess.run(check, capture_output=True, text=True)
    return r.returncode == 0, r.stdout + r.stderr


def check_scene(root, folder, scene_id):
    return run_check(root, "--scene", scene_id, "--overlay", folder / "overlay.png")


def render_scenes(args, root, cam_render, plan, split):
    """Every planned scene not yet in the cache, rendered and checked. A scene failing its check is
    kept aside (never evaluated) and the others still render; the bench stops after them. A scene
    kept aside by an earlier run is checked again first (the check may have been mended since)."""
    renderer = ROOT / "tools/benchgen/render_bin.py"
    models = root / "models"
    n_scenes = len(plan)
    failed = []
    for s in plan:
        folder = root / "test" / f"{s['scene_id']:06d}"
        aside = folder.with_name(f".failed-check-{folder.name}")
        if not folder.exists() and aside.exists():
            aside.rename(folder)  # the checker reads the scene where the dataset has it
            ok, output = check_scene(root, folder, s["scene_id"])
            if not ok:
                folder.rename(aside)
                sys.stderr.write(output[-4000:])
                failed.append(s["scene_id"])
                continue
            say(f"{split}: scene {s['scene_id']}, kept aside before, passes its check now")
        if folder.exists():
            continue
        cmd = ["blender", "-b", "--factory-startup", "-noaudio", "--python", renderer, "--",
               "--models", models, "--obj-ids", ",".join(map(str, s["obj_ids"])), "--camera", cam_render,
               "--out", root, "--split", "test", "--scene-id", s["scene_id"], "--seed", s["seed"],
               "--samples", args.samples]
        if split == "smoke":
            cmd += ["--parts", "2,3"]
        if args.second_view_deg:
            cmd += ["--second-view-deg", args.second_view_deg]
        t0 = time.time()
        run(cmd)
        say(f"{split}: scene {s['scene_id']}/{n_scenes} rendered in {time.time() - t0:.0f} s (types {s['obj_ids']})")
        ok, output = check_scene(root, folder, s["scene_id"])
        if not ok:
            shutil.rmtree(aside, ignore_errors=True)
            folder.rename(aside)
            sys.stderr.write(output[-4000:])
            failed.append(s["scene_id"])
            say(f"{split}: scene {s['scene_id']} failed its ground-truth check (kept in {aside})")
            continue
        say(f"{split}: scene {s['scene_id']} check: {output.strip().splitlines()[-1]}")
    if failed:
        raise SystemExit(f"generalize: {split} scene(s) {', '.join(map(str, failed))} failed their ground-truth check")
    # The camera's alignment over every scene pooled: one scene's parts scatter it too much.
    ok, output = run_check(root, "--split-alignment")
    say(f"{split}: {(output.strip().splitlines() or ['(no output)'])[-1]}")
    if not ok:
        sys.stderr.write(output[-4000:])
        raise SystemExit(f"generalize: {split}: the rendered images are not aligned with their ground truth")


def teach(args, cache, build, root, cam_yaml, ids):
    """Every part's template database with mfc-teach's defaults, cached by teacher, camera and model."""
    teacher = build / "tools/teach/mfc-teach"
    key = digest(program_digest(teacher), file_digest(cam_yaml))
    out = cache / f"templates-{key}"
    out.mkdir(parents=True, exist_ok=True)
    times = {}
    times_file = out / "teach-seconds.json"
    if times_file.exists():
        times = json.loads(times_file.read_text())
    for n, i in enumerate(ids, 1):
        model = root / "models" / f"obj_{i:06d}.ply"
        tdb = out / f"obj_{i:06d}-{file_digest(model)}.tdb"
        link = out / f"obj_{i:06d}.tdb"
        if not tdb.exists():
            tmp = tdb.with_suffix(".tmp")
            t0 = time.time()
            run([teacher, model, "--camera", cam_yaml, "--out", tmp, "--quiet"])
            times[str(i)] = time.time() - t0
            tmp.rename(tdb)
            times_file.write_text(json.dumps(times, indent=1))
            say(f"teach: obj {i} ({n}/{len(ids)}) in {times[str(i)]:.0f} s")
        if link.is_symlink() or link.exists():
            link.unlink()
        link.symlink_to(tdb.name)
    return out, {i: times.get(str(i)) for i in ids}


def evaluate(args, build, root, templates, ids, split, out_dir):
    """mfc-eval detect per type and over all types; its JSON in out_dir/generalize-<split>.json."""
    parts_csv = out_dir / f"generalize-{split}-parts.csv"
    parts_csv.write_text("name,obj_id,symmetry\n" + "".join(f"obj_{i:06d},{i},none\n" for i in ids))
    out = out_dir / f"generalize-{split}.json"
    overlays = out_dir / f"generalize-{split}-overlays"
    shutil.rmtree(overlays, ignore_errors=True)
    cmd = [build / "tools/eval/mfc-eval", "detect", "--dataset", root, "--templates", templates, "--parts", parts_csv,
           "--model-symmetries", "--methods", "fdcm", "--all-types", "--overlay", overlays, "--out", out, "--quiet"]
    # The plan's scenes only (one image each, in scene order): the folder may hold more, rendered
    # by a run with more scenes.
    n = len(json.loads((root / "plan.json").read_text()))
    cmd += ["--max-images", min(args.max_images, n) if args.max_images else n]
    say(f"{split}: mfc-eval detect ({len(ids)} types)")
    t0 = time.time()
    r = run(cmd)
    say(f"{split}: evaluated in {time.time() - t0:.0f} s: {r.stdout.strip().splitlines()[0]}")
    return out, " ".join(str(c) for c in cmd)


def main():
    ap = argparse.ArgumentParser(prog="tools/mfc bench generalize", description=__doc__.split("\n\n")[0])
    ap.add_argument("build", type=Path, help="release build tree")
    ap.add_argument("--splits", default="test,dev", help="splits to run, in order (default test,dev)")
    ap.add_argument("--scenes-test", type=int, default=40, help="scenes of the test split (default 40)")
    ap.add_argument("--scenes-dev", type=int, default=20, help="scenes of the dev split (default 20)")
    ap.add_argument("--parts-per-family", type=int, default=5, help="parts per family (default 5: 2 dev, 3 test)")
    ap.add_argument("--samples", type=int, default=16, help="Cycles samples per pixel (default 16)")
    ap.add_argument("--max-images", type=int, default=0, help="evaluate only the first N images (default all)")
    ap.add_argument("--cache", type=Path, default=Path(os.environ.get("MFC_BENCH_CACHE",
                                                                       Path.home() / ".cache/mfcd-bench")))
    ap.add_argument("--out", type=Path, help="JSON and overlays (default <build>/../bench)")
    ap.add_argument("--docs", type=Path, default=ROOT / "docs", help="where generalization.md goes")
    ap.add_argument("--no-docs", action="store_true", help="do not write docs/")
    ap.add_argument("--stages", default="teach,render,eval",
                    help="what to run of teach,render,eval (default all; eval also teaches what is missing)")
    ap.add_argument("--smoke", action="store_true",
                    help="one generated part, one small scene at few samples, detect, score (ctest)")
    ap.add_argument("--second-view-deg", type=float, default=0.0,
                    help="render two-view scenes (render_bin.py --second-view-deg) into their own cache folder, "
                         "for mfc-second-look --views dataset; needs --stages without eval (default 0: one view)")
    args = ap.parse_args()
    build = args.build.resolve()
    out_dir = (args.out or build.parent / "bench").resolve()
    out_dir.mkdir(parents=True, exist_ok=True)
    splits = ["smoke"] if args.smoke else [s for s in args.splits.split(",") if s]
    for s in splits:
        if s not in CAMERAS:
            ap.error(f"--splits: unknown split '{s}' (known: test, dev)")
    if args.smoke:
        args.samples = 4
    cache = args.cache.resolve()
    cache.mkdir(parents=True, exist_ok=True)
    t_start = time.time()
    parts_dir, parts = make_parts(args, cache)
    runs = []
    stages = set(args.stages.split(","))
    unknown = stages - {"teach", "render", "eval"}
    if unknown:
        ap.error(f"--stages: unknown stage(s) {', '.join(sorted(unknown))} (known: teach, render, eval)")
    if args.second_view_deg and "eval" in stages:
        ap.error("--second-view-deg: the one-view evaluation and report do not take two-view scenes; "
                 "give --stages render (or teach,render)")
    if "eval" in stages:
        stages.add("teach")  # the evaluation needs the templates (cached ones cost nothing)
    for split in splits:
        root, cam_yaml, cam_render, ids, plan = prepare_dataset(args, cache, parts_dir, parts, split)
        if "teach" in stages:
            templates, teach_s = teach(args, cache, build, root, cam_yaml, ids)
        if "render" in stages:
            render_scenes(args, root, cam_render, plan, split)
            if args.second_view_deg:
                say(f"{split}: two-view scenes ({args.second_view_deg:g} deg) in {root}")
        if "eval" in stages:
            result, command = evaluate(args, build, root, templates, ids, split, out_dir)
            runs.append({"split": split, "dataset": str(root), "templates": str(templates), "result": str(result),
                         "eval_command": command, "teach_seconds": teach_s, "plan": plan})
    if "eval" not in stages:
        say(f"done (stages {args.stages}) in {time.time() - t_start:.0f} s")
        return
    summary = out_dir / ("generalize-smoke-run.json" if args.smoke else "generalize-run.json")
    summary.write_text(json.dumps({"date": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
                                   "wall_s": time.time() - t_start, "samples": args.samples,
                                   "parts": str(parts_dir / "parts.json"), "runs": runs,
                                   "cpu_model": cpu_model(), "cpus": os.cpu_count()}, indent=1))
    report = [PY, ROOT / "tools/bench/generalize_report.py", summary]
    if not (args.no_docs or args.smoke):
        report += ["--docs", args.docs]
    r = subprocess.run([str(c) for c in report])
    if r.returncode != 0:
        raise SystemExit(r.returncode)
    say(f"done in {time.time() - t_start:.0f} s; {summary}")


def cpu_model():
    try:
        for line in open("/proc/cpuinfo"):
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return "unknown"


if __name__ == "__main__":
    main()

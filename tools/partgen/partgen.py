#!/usr/bin/python3
"""Procedural industrial parts as a BOP models folder, for the generalization bench.

  /usr/bin/python3 tools/partgen/partgen.py --out DIR [--count-per-family 5]
      [--families all|a,b,...] [--jobs 2] [--only-ids 1,2]

Writes DIR/{dev,test}/models/obj_NNNNNN.ply (mm, binary PLY with crease-split
normals) and models_info.json per split (BOP keys; symmetries detected from the
mesh, see symmetry.py), DIR/scad/obj_NNNNNN.scad (the source of each mesh, in the
PLY's frame) and DIR/parts.json (every part's family, seed, parameters, symmetry,
mesh checks). Part i of a family (i = 0, 1, ...) has seed 1000 * (family number + 1)
+ i and is a dev part when i < 2, else a test part; obj_id = family number *
count + i + 1, so the full default run numbers 1..N. The models and scad folders
hold exactly the parts of this command. Built parts are kept in
DIR/cache/<family>-<seed>.{ply,scad,json}; one whose key (GENERATOR_VERSION +
parameters + source) is unchanged is not rebuilt, whatever the count or families.
The same command writes byte-identical files.
"""

import argparse
import concurrent.futures as cf
import hashlib
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import numpy as np  # noqa: E402

import families_a as fa  # noqa: E402
import families_b as fb  # noqa: E402
import families_c as fc  # noqa: E402
import mesh_io  # noqa: E402
from scad_util import Draw, header, indent, num, target_size  # noqa: E402
from symmetry import detect_symmetries  # noqa: E402

GENERATOR_VERSION = "partgen-1.1"
DEV_PER_FAMILY = 2
OPENSCAD_TIMEOUT_S = 900

FAMILIES = [
    ("angle_bracket", fa.angle_bracket),
    ("flange", fa.flange),
    ("spur_gear", fa.spur_gear),
    ("stepped_shaft", fa.stepped_shaft),
    ("hex_nut", fb.hex_nut),
    ("hex_bolt", fb.hex_bolt),
    ("hinge", fb.hinge),
    ("cup", fb.cup),
    ("plate", fb.plate),
    ("pipe_fitting", fc.pipe_fitting),
    ("clip", fc.clip),
    ("lever", fc.lever),
    ("extruded_profile", fc.extruded_profile),
]


def plan(families, count):
    """Every part to make: dicts with obj_id, family, family_no, index, seed, split."""
    out = []
    for fno, (name, _) in enumerate(FAMILIES):
        if name not in families:
            continue
        for i in range(count):
            out.append({"obj_id": fno * count + i + 1, "family": name, "family_no": fno, "index": i,
                        "seed": 1000 * (fno + 1) + i, "split": "dev" if i < DEV_PER_FAMILY else "test"})
    return out


def design(p):
    """Draws the part's parameters and OpenSCAD body. Returns (params, size, body, frame, key)."""
    d = Draw(p["seed"])
    size = target_size(p["family_no"], p["index"], d.rng.random())
    d.set("size_target_mm", size)
    spec = dict(FAMILIES)[p["family"]](d, size)
    body = spec["scad"]
    blob = json.dumps({"version": GENERATOR_VERSION, "family": p["family"], "seed": p["seed"],
                       "params": d.params, "scad": body, "frame": spec["frame"]}, sort_keys=True)
    return d.params, size, body, spec["frame"], hashlib.sha256(blob.encode()).hexdigest()[:20]


def scad_source(size, body, translation, family, seed):
    return (f"// partgen {GENERATOR_VERSION}: family {family}, seed {seed}; mm\n"
            + header(size)
            + f"translate([{', '.join(num(x) for x in translation)}]) part();\n\n"
            + "module part() {\n" + indent(body) + "\n}\n")


def cache_names(out, p):
    """Cache files of a part, named by family and seed (not obj_id, which depends on
    --count-per-family), so runs with other counts or families reuse them."""
    stem = os.path.join(out, "cache", f"{p['family']}-{p['seed']}")
    return stem + ".ply", stem + ".scad", stem + ".json"


def cached(out, p, key):
    ply, scad, rec = cache_names(out, p)
    try:
        with open(rec, encoding="utf-8") as f:
            record = json.load(f)
    except (OSError, ValueError):
        return None
    if record.get("key") != key or record.get("status") != "ok" or not os.path.exists(scad):
        return None
    comment = mesh_io.ply_comment(ply)
    return record if comment and f"key={key}" in comment else None


def build(out, p):
    """Makes one part into the cache (or finds it there). Returns (record, timings);
    the record has no obj_id or split (those come from the plan)."""
    t0 = time.time()
    params, size, body, frame, key = design(p)
    hit = cached(out, p, key)
    if hit is not None:
        return hit, {"cached": True, "total": time.time() - t0}
    ply, scad, rec = cache_names(out, p)
    record = {"family": p["family"], "seed": p["seed"], "generator_version": GENERATOR_VERSION,
              "key": key, "params": params}
    timing = {"cached": False}
    work = tempfile.mkdtemp(prefix="partgen-")
    try:
        src = os.path.join(work, "part.scad")
        off = os.path.join(work, "part.off")
        with open(src, "w", encoding="utf-8") as f:
            f.write(header(size) + "part();\n\nmodule part() {\n" + indent(body) + "\n}\n")
        t1 = time.time()
        run = subprocess.run(["openscad", "-o", off, src], capture_output=True, text=True,
                             timeout=OPENSCAD_TIMEOUT_S)
        timing["openscad"] = time.time() - t1
        if run.returncode != 0 or not os.path.exists(off):
            tail = " | ".join(run.stderr.strip().splitlines()[-3:])
            raise RuntimeError(f"openscad failed ({run.returncode}): {tail}")
        V, F = mesh_io.weld(*mesh_io.read_off(off))
    except Exception as exc:  # a failed part is reported, the run goes on
        record.update({"status": "failed", "reason": str(exc)})
        return record, timing
    finally:
        shutil.rmtree(work, ignore_errors=True)
    F, slivers = mesh_io.fix_slivers(V, F)
    # Orientation is global: a closed mesh whose volume comes out negative is inside out.
    flipped = mesh_io.signed_volume(V, F) < 0
    if flipped:
        F = F[:, ::-1].copy()
    F = mesh_io.canonical_faces(F)
    check = mesh_io.check_mesh(V, F)
    check["slivers_fixed"] = slivers
    check["reoriented"] = bool(flipped)
    lo, hi = V.min(0), V.max(0)
    centre = (lo + hi) / 2
    shift = -centre if frame == "bbox" else np.array([0.0, 0.0, -centre[2]])
    shift = np.round(shift, 4) + 0.0
    V = V + shift
    t2 = time.time()
    sym = detect_symmetries(V, F, seed=p["seed"])
    timing["symmetry"] = time.time() - t2
    pos, nrm, faces = mesh_io.crease_split(V, F)
    lo, hi = V.min(0), V.max(0)
    record.update({
        "status": "ok" if check["ok"] else "failed",
        "frame": frame, "frame_shift_mm": [float(x) for x in shift],
        "diameter_mm": sym["diameter_mm"],
        "bbox_min_mm": [round(float(x), 4) for x in lo], "bbox_size_mm": [round(float(x), 4) for x in hi - lo],
        "mesh_check": check, "ply_vertices": int(len(pos)),
        "symmetry": {k: sym[k] for k in ("group", "tolerance_mm", "max_error_mm", "inertia_gaps",
                                         "symmetries_discrete", "symmetries_continuous")},
    })
    if not check["ok"]:
        record["reason"] = "mesh check failed: " + json.dumps(check, sort_keys=True)
        return record, timing
    os.makedirs(os.path.dirname(ply), exist_ok=True)
    with open(scad, "w", encoding="utf-8") as f:
        f.write(scad_source(size, body, shift, p["family"], p["seed"]))
    mesh_io.write_ply(ply, pos, nrm, faces, f"partgen {GENERATOR_VERSION} key={key} {p['family']} seed {p['seed']} mm")
    with open(rec, "w", encoding="utf-8") as f:
        json.dump(record, f, indent=1, sort_keys=True)
        f.write("\n")
    timing["total"] = time.time() - t0
    return record, timing


def publish(src, dst):
    """Copies src to dst unless dst already holds the same bytes (keeps mtimes)."""
    with open(src, "rb") as f:
        data = f.read()
    try:
        with open(dst, "rb") as f:
            if f.read() == data:
                return
    except OSError:
        pass
    os.makedirs(os.path.dirname(dst), exist_ok=True)
    with open(dst, "wb") as f:
        f.write(data)


def publish_all(out, parts, records):
    """Makes DIR/{dev,test}/models and DIR/scad hold exactly this run's parts: cached
    meshes copied in under their obj_id, files of other runs' plans removed."""
    wanted = {}
    for p in parts:
        r = records.get(p["obj_id"])
        if r is None or r["status"] != "ok":
            continue
        oid = f"obj_{p['obj_id']:06d}"
        ply, scad, _ = cache_names(out, p)
        wanted[os.path.join(out, p["split"], "models", oid + ".ply")] = ply
        wanted[os.path.join(out, "scad", oid + ".scad")] = scad
    for folder in (os.path.join(out, "dev", "models"), os.path.join(out, "test", "models"), os.path.join(out, "scad")):
        if os.path.isdir(folder):
            for name in sorted(os.listdir(folder)):
                path = os.path.join(folder, name)
                if name.startswith("obj_") and path not in wanted:
                    os.remove(path)
    for dst in sorted(wanted):
        publish(wanted[dst], dst)


def models_info(records):
    info = {}
    for r in records:
        lo, size = r["bbox_min_mm"], r["bbox_size_mm"]
        e = {"diameter": r["diameter_mm"], "min_x": lo[0], "min_y": lo[1], "min_z": lo[2],
             "size_x": size[0], "size_y": size[1], "size_z": size[2]}
        if r["symmetry"]["symmetries_discrete"]:
            e["symmetries_discrete"] = r["symmetry"]["symmetries_discrete"]
        if r["symmetry"]["symmetries_continuous"]:
            e["symmetries_continuous"] = r["symmetry"]["symmetries_continuous"]
        info[str(r["obj_id"])] = e
    return info


def write_json(path, obj):
    os.makedirs(os.path.dirname(path), exist_ok=True)
    with open(path, "w", encoding="utf-8") as f:
        json.dump(obj, f, indent=1, sort_keys=True)
        f.write("\n")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", required=True)
    ap.add_argument("--count-per-family", type=int, default=5)
    ap.add_argument("--families", default="all")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--only-ids", default="")
    a = ap.parse_args(argv)
    known = [n for n, _ in FAMILIES]
    fams = known if a.families == "all" else [x.strip() for x in a.families.split(",") if x.strip()]
    unknown = sorted(set(fams) - set(known))
    if unknown:
        ap.error(f"unknown families {unknown}; known: {', '.join(known)}")
    parts = plan(set(fams), a.count_per_family)
    only = {int(x) for x in a.only_ids.split(",") if x.strip()}
    todo = [p for p in parts if not only or p["obj_id"] in only]
    start = time.time()
    records = {}
    with cf.ProcessPoolExecutor(max_workers=max(1, a.jobs)) as pool:
        futs = {pool.submit(build, a.out, p): p for p in todo}
        for n, fut in enumerate(cf.as_completed(futs), 1):
            p = futs[fut]
            rec, tm = fut.result()
            rec = {"obj_id": p["obj_id"], "split": p["split"], **rec}
            records[p["obj_id"]] = rec
            sym = rec.get("symmetry", {}).get("group", "-")
            how = "cached" if tm.get("cached") else (
                f"openscad {tm.get('openscad', 0):.1f} s, symmetry {tm.get('symmetry', 0):.1f} s")
            print(f"[{n}/{len(todo)}] {p['family']:<17} obj {p['obj_id']:>3} {p['split']:<4} "
                  f"{tm.get('total', 0):6.1f} s ({how}) {rec['status']} {sym}"
                  + (f" -- {rec.get('reason')}" if rec["status"] != "ok" else ""), file=sys.stderr, flush=True)
    # Parts not rebuilt in this run (--only-ids) come from their cache records.
    for p in parts:
        if p["obj_id"] not in records:
            key = design(p)[4]
            hit = cached(a.out, p, key)
            if hit is not None:
                records[p["obj_id"]] = {"obj_id": p["obj_id"], "split": p["split"], **hit}
    publish_all(a.out, parts, records)
    ok = [records[k] for k in sorted(records) if records[k]["status"] == "ok"]
    for split in ("dev", "test"):
        write_json(os.path.join(a.out, split, "models", "models_info.json"),
                   models_info([r for r in ok if r["split"] == split]))
    write_json(os.path.join(a.out, "parts.json"), {
        "generator_version": GENERATOR_VERSION,
        "units": "mm",
        "symmetry_tolerance": "max(0.1 mm, 0.002 * diameter): a symmetry is accepted when every test point "
                              "(vertices, triangle centroids, area-weighted samples) moved by it lies within "
                              "this distance of the surface",
        "count_per_family": a.count_per_family,
        "families": [n for n in known if n in fams],
        "parts": [{k: v for k, v in records[i].items() if k != "key"} for i in sorted(records)],
    })
    failed = [r for r in records.values() if r["status"] != "ok"]
    print(f"partgen: {len(ok)} parts ok, {len(failed)} failed, {time.time() - start:.1f} s wall",
          file=sys.stderr)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())

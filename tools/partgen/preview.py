#!/usr/bin/python3
"""Contact sheet of partgen PLYs, for a look by eye (not used by the generator).

  /usr/bin/python3 tools/partgen/preview.py --out DIR --png sheet.png [--ids 1,2,3] [--cols 5]

Each tile is one part seen from an oblique direction, flat-shaded with a fixed light,
titled with its id, family and detected symmetry group (from DIR/parts.json).
"""

import argparse
import json
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from mpl_toolkits.mplot3d.art3d import Poly3DCollection  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import mesh_io  # noqa: E402


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", required=True)
    ap.add_argument("--png", required=True)
    ap.add_argument("--ids", default="")
    ap.add_argument("--cols", type=int, default=5)
    ap.add_argument("--elev", type=float, default=28)
    ap.add_argument("--azim", type=float, default=-55)
    a = ap.parse_args()
    with open(os.path.join(a.out, "parts.json"), encoding="utf-8") as f:
        parts = [p for p in json.load(f)["parts"] if p["status"] == "ok"]
    want = {int(x) for x in a.ids.split(",") if x}
    parts = [p for p in parts if not want or p["obj_id"] in want]
    rows = (len(parts) + a.cols - 1) // a.cols
    fig = plt.figure(figsize=(3.2 * a.cols, 3.2 * rows))
    light = np.array([0.4, -0.5, 0.77])
    light /= np.linalg.norm(light)
    for k, p in enumerate(parts):
        ply = os.path.join(a.out, p["split"], "models", f"obj_{p['obj_id']:06d}.ply")
        V, _, F, _ = mesh_io.read_ply(ply)
        n, _ = mesh_io.face_normals_areas(V, F)
        # Back faces are culled: matplotlib sorts polygons by depth only roughly.
        el, az = np.radians(a.elev), np.radians(a.azim)
        eye = np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
        front = n @ eye > 0
        F, n = F[front], n[front]
        shade = 0.25 + 0.75 * np.clip(n @ light, 0, 1)
        ax = fig.add_subplot(rows, a.cols, k + 1, projection="3d")
        col = Poly3DCollection(V[F], facecolors=np.outer(shade, [0.75, 0.8, 0.9]), edgecolors="none")
        ax.add_collection3d(col)
        lo, hi = V.min(0), V.max(0)
        c, r = (lo + hi) / 2, (hi - lo).max() / 2
        ax.set_xlim(c[0] - r, c[0] + r)
        ax.set_ylim(c[1] - r, c[1] + r)
        ax.set_zlim(c[2] - r, c[2] + r)
        ax.view_init(elev=a.elev, azim=a.azim)
        ax.set_axis_off()
        ax.set_title(f"{p['obj_id']} {p['family']} {p['symmetry']['group']}\n"
                     f"{(hi - lo).max():.0f} mm", fontsize=8)
    fig.tight_layout()
    fig.savefig(a.png, dpi=80)


if __name__ == "__main__":
    main()

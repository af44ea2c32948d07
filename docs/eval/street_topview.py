#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""The street clip seen from above: wallar's trajectory, the ground truth aligned to it, and the
walls' outlines, as CSV for street_topview.gp. Python 3 with numpy only.

  wallar track STREET --out traj.tum --walls walls.json
  docs/eval/street_topview.py traj.tum walls.json STREET/mav0/state_groundtruth_estimate0/data.csv OUTDIR

The world is wallar's (the first rectified left camera: x right, y down, z forward), so "from
above" is x against z. The ground truth (positions only: the clip's orientations are
placeholders) is aligned by the SE(3) Umeyama fit of positions at the frame times, as --eval does.
"""
import csv
import json
import sys

import numpy as np


def read_tum(path):
    rows = [l.split() for l in open(path) if l.strip() and not l.startswith("#")]
    return np.array([float(r[0]) for r in rows]), np.array([[float(v) for v in r[1:4]] for r in rows])


def read_gt(path):
    rows = [r for r in csv.reader(open(path)) if r and not r[0].startswith("#")]
    return np.array([int(r[0]) * 1e-9 for r in rows]), np.array([[float(v) for v in r[1:4]] for r in rows])


def umeyama_se3(src, dst):
    """R, t minimising |dst - (R src + t)|."""
    ms, md = src.mean(0), dst.mean(0)
    u, _, vt = np.linalg.svd((dst - md).T @ (src - ms))
    s = np.eye(3)
    s[2, 2] = np.sign(np.linalg.det(u @ vt))
    r = u @ s @ vt
    return r, md - r @ ms


def main():
    traj, walls, gt_csv, out = sys.argv[1:5]
    t, p = read_tum(traj)
    tg, pg = read_gt(gt_csv)
    gt_at = np.stack([np.interp(t, tg, pg[:, k]) for k in range(3)], 1)
    r, tr = umeyama_se3(gt_at, p)  # ground truth into wallar's world
    gt_w = gt_at @ r.T + tr
    ate = np.sqrt(np.mean(np.sum((gt_w - p) ** 2, 1)))
    with open(f"{out}/street_topview_path.csv", "w") as f:
        f.write("x_m,z_m,gt_x_m,gt_z_m\n")
        for a, b in zip(p, gt_w):
            f.write(f"{a[0]:.3f},{a[2]:.3f},{b[0]:.3f},{b[2]:.3f}\n")
    model = json.load(open(walls))
    with open(f"{out}/street_topview_walls.csv", "w") as f:
        f.write("x_m,z_m,kind\n")
        for s in model["surfaces"]:
            ext = s["extent"] + s["extent"][:1]
            for v in ext:
                f.write(f"{v[0]:.3f},{v[2]:.3f},{s['kind']}\n")
            f.write("\n\n")  # one gnuplot data block per surface
    print(f"ATE {ate:.3f} m RMS over {len(t)} frames; {len(model['surfaces'])} surfaces")


if __name__ == "__main__":
    main()

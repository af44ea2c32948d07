#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""The client API's predicted poses against a synthetic recording's ground truth.

usage: prediction_error.py MAV0 TRAJECTORY_TUM PRINT_PLANES_OUT [--json]

PRINT_PLANES_OUT holds print_planes' "pose t_ns=... t_pose_ns=... p=... q=..." lines (the pose
predicted for a display time t_ns from the newest pose at t_pose_ns). The world of both is the
run's: the first body pose (trajectory.tum's first row). The ground truth (EuRoC
state_groundtruth_estimate0, body = IMU) is brought into it by its pose at that first time and
interpolated (position linearly, attitude by slerp). Prints, over the tracked poses: the
prediction's error (rotation, position) at the display time, the error of holding the pose it
came from (the same tracked pose, unpredicted), and how far ahead of the pose each was asked.
"""
import bisect
import json
import math
import sys


def quat_to_rot(x, y, z, w):
    n = math.sqrt(x * x + y * y + z * z + w * w)
    x, y, z, w = x / n, y / n, z / n, w / n
    return [[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]]


def transpose(R):
    return [list(r) for r in zip(*R)]


def matmul(A, B):
    return [[sum(A[i][k] * B[k][j] for k in range(3)) for j in range(3)] for i in range(3)]


def matvec(A, v):
    return [sum(A[i][k] * v[k] for k in range(3)) for i in range(3)]


def sub(a, b):
    return [x - y for x, y in zip(a, b)]


def norm(a):
    return math.sqrt(sum(x * x for x in a))


def slerp(q0, q1, f):
    d = sum(a * b for a, b in zip(q0, q1))
    if d < 0:
        q1, d = [-x for x in q1], -d
    if d > 0.9995:
        q = [a + f * (b - a) for a, b in zip(q0, q1)]
    else:
        a = math.acos(d)
        q = [(math.sin((1 - f) * a) * x + math.sin(f * a) * y) / math.sin(a) for x, y in zip(q0, q1)]
    n = norm(q)
    return [x / n for x in q]


def angle_deg(Ra, Rb):
    M = matmul(transpose(Ra), Rb)
    c = (M[0][0] + M[1][1] + M[2][2] - 1) / 2
    return math.degrees(math.acos(max(-1.0, min(1.0, c))))


def percentile(v, q):
    if not v:
        return float('nan')
    s = sorted(v)
    return s[min(len(s) - 1, int(round(q / 100 * (len(s) - 1))))]


def main():
    mav0, tum, pp = sys.argv[1:4]
    gt = []
    for line in open(f'{mav0}/state_groundtruth_estimate0/data.csv'):
        if line.startswith('#') or not line.strip():
            continue
        v = line.split(',')
        gt.append([int(v[0])] + [float(x) for x in v[1:8]])
    t_gt = [g[0] for g in gt]

    def gt_at(t):
        i = bisect.bisect_left(t_gt, t)
        if i <= 0 or i >= len(t_gt):
            return None
        a, b = gt[i - 1], gt[i]
        f = (t - t_gt[i - 1]) / (t_gt[i] - t_gt[i - 1])
        p = [(1 - f) * x + f * y for x, y in zip(a[1:4], b[1:4])]
        qa = [a[5], a[6], a[7], a[4]]  # EuRoC: w x y z -> x y z w
        qb = [b[5], b[6], b[7], b[4]]
        q = slerp(qa, qb, f)
        return quat_to_rot(*q), p

    traj = {}
    first = None
    for line in open(tum):
        v = line.split()
        t = int(round(float(v[0]) * 1e9))
        traj[t] = (quat_to_rot(*map(float, v[4:8])), [float(x) for x in v[1:4]])
        if first is None:
            first = t
    R0, p0 = gt_at(first)

    def truth(t):
        g = gt_at(t)
        if g is None:
            return None
        R, p = g
        return matmul(transpose(R0), R), matvec(transpose(R0), sub(p, p0))

    def nearest_traj(t):
        k = min(traj, key=lambda s: abs(s - t))
        return traj[k] if abs(k - t) < 1_000_000 else None

    rot, pos, hold_rot, hold_pos, ahead = [], [], [], [], []
    for line in open(pp):
        if not line.startswith('pose ') or 'flags=15' not in line:
            continue
        f = dict(kv.split('=', 1) for kv in line.split()[1:])
        t, t_pose = int(f['t_ns']), int(f['t_pose_ns'])
        T = truth(t)
        held = nearest_traj(t_pose)
        if T is None or held is None:
            continue
        p = [float(x) for x in f['p'].split(',')]
        R = quat_to_rot(*map(float, f['q'].split(',')))
        rot.append(angle_deg(R, T[0]))
        pos.append(1e3 * norm(sub(p, T[1])))
        hold_rot.append(angle_deg(held[0], T[0]))
        hold_pos.append(1e3 * norm(sub(held[1], T[1])))
        ahead.append((t - t_pose) / 1e6)
    # The tracker's own error at its poses, for scale.
    track_rot, track_pos = [], []
    for t, (R, p) in traj.items():
        T = truth(t)
        if T is not None:
            track_rot.append(angle_deg(R, T[0]))
            track_pos.append(1e3 * norm(sub(p, T[1])))
    pc = percentile
    out = {
        'poses': len(rot),
        'ahead_ms': {'median': pc(ahead, 50), 'min': min(ahead, default=0), 'max': max(ahead, default=0)},
        'predicted': {'rot_deg_median': pc(rot, 50), 'rot_deg_p95': pc(rot, 95),
                      'pos_mm_median': pc(pos, 50), 'pos_mm_p95': pc(pos, 95)},
        'held': {'rot_deg_median': pc(hold_rot, 50), 'rot_deg_p95': pc(hold_rot, 95),
                 'pos_mm_median': pc(hold_pos, 50), 'pos_mm_p95': pc(hold_pos, 95)},
        'tracker': {'rot_deg_median': pc(track_rot, 50), 'pos_mm_median': pc(track_pos, 50)},
    }
    print(json.dumps(out, indent=1) if '--json' in sys.argv else out)


if __name__ == '__main__':
    main()

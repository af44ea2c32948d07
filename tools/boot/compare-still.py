#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""The HIL boot test's trajectory check (tools/boot-test --hil): the guest's trajectory, tracked
from vivid's looped playback of the bundled still recording, against `wallar track` on the same
recording on the host.

  compare-still.py HOST.tum GUEST.tum [--limit-m 0.01]

Both are TUM files (t x y z qx qy qz qw) in the world of their first body pose. The guest's
frames carry vivid's capture times, not the recording's, and loop over it, so frames cannot be
matched by time; the recording is a head held still, so every guest pose is compared with the
host trajectory's mean position (and its first attitude). Prints
one line (poses, max and RMS position difference, max rotation difference, the host's own
spread) and exits 0 when the max position difference is within the limit, 1 otherwise.
"""
import math
import sys


def read_tum(path):
    rows = []
    with open(path) as f:
        for line in f:
            if line.strip() and not line.startswith("#"):
                v = [float(x) for x in line.split()]
                rows.append(v)
    return rows


def angle_deg(q1, q2):
    dot = abs(sum(a * b for a, b in zip(q1, q2)))
    return math.degrees(2.0 * math.acos(min(1.0, dot)))


def main():
    args = sys.argv[1:]
    limit = 0.01
    if "--limit-m" in args:
        i = args.index("--limit-m")
        limit = float(args[i + 1])
        del args[i : i + 2]
    if len(args) != 2:
        print("usage: compare-still.py HOST.tum GUEST.tum [--limit-m M]", file=sys.stderr)
        return 2
    host, guest = read_tum(args[0]), read_tum(args[1])
    if not host or not guest:
        print(f"trajectory check: host {len(host)} poses, guest {len(guest)} poses")
        return 1
    mean = [sum(r[k] for r in host) / len(host) for k in (1, 2, 3)]
    q_ref = host[0][4:8]
    spread = max(math.dist(r[1:4], mean) for r in host)
    d = [math.dist(r[1:4], mean) for r in guest]
    rms = math.sqrt(sum(x * x for x in d) / len(d))
    rot = max(angle_deg(r[4:8], q_ref) for r in guest)
    ok = max(d) <= limit
    print(
        f"trajectory within {limit * 100:.0f} cm of wallar track: {len(guest)} guest poses, "
        f"max {max(d) * 1000:.2f} mm, RMS {rms * 1000:.2f} mm, rotation max {rot:.3f} deg "
        f"(host: {len(host)} poses within {spread * 1000:.2f} mm of their mean)"
    )
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())

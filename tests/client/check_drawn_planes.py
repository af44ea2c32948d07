#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""Checks examples/draw_planes' output and last frame, and its final plane set.

usage: check_drawn_planes.py OUTPUT FRAME.ppm FINAL_OUTPUT WALLS.json --rate HZ --duration S
                             --fov-deg DEG [--strict]

OUTPUT is the stdout of a draw_planes run for --duration S at --rate HZ, FRAME.ppm its --out;
FINAL_OUTPUT that of one that ran until the firmware stopped, WALLS.json the run's. Its frames
plus the refreshes it skipped are its rate times its duration (--strict: a plain build, which
must also keep up); each eye pose is the body pose times the view; the frame is the plane set
it had (as it printed it) seen from its last eye pose: a ray per pixel of a 4-pixel grid
through the same pinhole, the nearest polygon hit (or none) names the colour the pixel must
have. The final set (the firmware's last model, sent as it stops) is walls.json's: ids,
labels and world corners. Prints one line of figures; exits 1 with the reason otherwise.
"""
import argparse
import json
import math
import sys

RGB = {'floor': (40, 200, 60), 'wall': (40, 90, 230), 'ceiling': (230, 200, 40),
       'unknown': (150, 150, 150), 'none': (0, 0, 0)}


def fields(line):
    return dict(kv.split('=', 1) for kv in line.split()[1:] if '=' in kv)


def rotate(q, v):
    x, y, z, w = q
    tx, ty, tz = 2 * (y * v[2] - z * v[1]), 2 * (z * v[0] - x * v[2]), 2 * (x * v[1] - y * v[0])
    return (v[0] + w * tx + (y * tz - z * ty), v[1] + w * ty + (z * tx - x * tz),
            v[2] + w * tz + (x * ty - y * tx))


def sub(a, b):
    return tuple(p - q for p, q in zip(a, b))


def dot(a, b):
    return sum(p * q for p, q in zip(a, b))


def cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def read_ppm(path):
    data = open(path, 'rb').read()
    parts = data.split(maxsplit=4)
    assert parts[0] == b'P6' and parts[3] == b'255', parts[:4]
    w, h = int(parts[1]), int(parts[2])
    pixels = parts[4]
    assert len(pixels) == 3 * w * h, (len(pixels), w, h)
    return w, h, pixels


def compose(a, b):
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (aw * bx + ax * bw + ay * bz - az * by, aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw, aw * bw - ax * bx - ay * by - az * bz)


def vec(text):
    return tuple(map(float, text.split(',')))


def plane_sets(lines):
    """[(line index, {id: (label, [corner, ...])})] for each "planes" block."""
    sets = []
    for i, l in enumerate(lines):
        if l.startswith('planes '):
            sets.append((i, {}))
        elif l.startswith('plane '):
            f = fields(l)
            sets[-1][1][int(f['id'])] = (f['label'], [vec(c) for c in f['world'].split(';')])
    return sets


def polygon_hit(c, origin, d):
    """Distance along d to the convex polygon with corners c, or None."""
    n = (0.0, 0.0, 0.0)
    for i in range(len(c)):  # Newell's normal: counter-clockwise about it
        n = tuple(a + b for a, b in zip(n, cross(c[i], c[(i + 1) % len(c)])))
    den = dot(n, d)
    if abs(den) < 1e-12:
        return None
    t = dot(n, sub(c[0], origin)) / den
    if t < 0.05:  # draw_planes' near plane
        return None
    p = tuple(o + t * k for o, k in zip(origin, d))
    sides = [dot(n, cross(sub(c[(i + 1) % len(c)], c[i]), sub(p, c[i]))) for i in range(len(c))]
    return t if min(sides) >= 0 or max(sides) <= 0 else None


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument('output')
    ap.add_argument('ppm')
    ap.add_argument('final_output')
    ap.add_argument('walls')
    ap.add_argument('--rate', type=float, required=True)
    ap.add_argument('--duration', type=float, required=True)
    ap.add_argument('--fov-deg', type=float, required=True)
    ap.add_argument('--strict', action='store_true')
    a = ap.parse_args()
    lines = open(a.output).read().splitlines()
    walls = json.load(open(a.walls))
    summary = fields(next(l for l in lines if l.startswith('summary ')))
    frames, drawn, missed = (int(summary[k]) for k in ('frames', 'drawn', 'missed'))
    # The display's refreshes over --duration: each drawn, or skipped when too late.
    ticks = a.rate * a.duration
    assert abs(frames + missed - ticks) <= 2, ('frames + missed', frames, missed, ticks)
    assert drawn > 0, summary
    if a.strict:
        assert missed <= 0.1 * ticks, ('too many skipped refreshes', summary)
    # The eye: the located body pose times the view (T_body_view), in every drawn frame.
    view = fields(next(l for l in lines if l.startswith('view ')))
    q_bv, p_bv = vec(view['q_body_view']), vec(view['p_body_view'])
    assert abs(sum(x * x for x in q_bv) - 1) < 1e-5, view
    drawn_lines = [i for i, l in enumerate(lines) if l.startswith('frame ') and 'draw_ms=' in l]
    assert len(drawn_lines) == drawn, (len(drawn_lines), summary)
    for i in drawn_lines:
        f = fields(lines[i])
        q_wb, p_wb = vec(f['q_world_body']), vec(f['p_world_body'])
        p_wv = tuple(a + b for a, b in zip(p_wb, rotate(q_wb, p_bv)))
        q_wv = compose(q_wb, q_bv)
        assert max(abs(a - b) for a, b in zip(p_wv, vec(f['p_world_view']))) < 1e-5, lines[i]
        assert max(abs(a - b) for a, b in zip(q_wv, vec(f['q_world_view']))) < 1e-5, lines[i]
    last = drawn_lines[-1]
    # The plane set of the last frame: the newest before it.
    sets = [ps for i, ps in plane_sets(lines) if i < last]
    assert sets and sets[-1], 'no plane drawn in the last frame'
    drawn_set = sets[-1]
    f = fields(lines[last])
    assert int(f['planes']) == len(drawn_set), (f, drawn_set)
    # Served while the run goes on, not only in the final fit: the floor and a wall by name (the
    # reconstruction searches again once the attitude filter has gravity).
    assert {'floor', 'wall'} <= {v[0] for v in drawn_set.values()}, ('drawn set', drawn_set)
    p, q = vec(f['p_world_view']), vec(f['q_world_view'])
    w, h, pixels = read_ppm(a.ppm)
    f_px = 0.5 * w / math.tan(math.radians(a.fov_deg) / 2)
    step, agree, total = 4, 0, 0
    expected_count = {k: 0 for k in RGB}
    seen_count = {k: 0 for k in RGB}
    for v in range(step // 2, h, step):
        for u in range(step // 2, w, step):
            d = rotate(q, ((u + 0.5 - w / 2) / f_px, (v + 0.5 - h / 2) / f_px, 1.0))
            hits = [(t, label) for label, corners in drawn_set.values()
                    for t in [polygon_hit(corners, p, d)] if t is not None]
            expected = min(hits)[1] if hits else 'none'
            rgb = pixels[3 * (v * w + u):3 * (v * w + u) + 3]
            seen = min(RGB, key=lambda k: sum((x - y) ** 2 for x, y in zip(RGB[k], rgb)))
            expected_count[expected] += 1
            seen_count[seen] += 1
            agree += seen == expected
            total += 1
    share = {k: round(100.0 * n / total, 1) for k, n in expected_count.items() if n}
    # The final set: walls.json's surfaces (the firmware's model as it stopped).
    final = plane_sets(open(a.final_output).read().splitlines())
    assert final, 'no plane set in the final output'
    final = final[-1][1]
    want = {s['id']: s['kind'] for s in walls['surfaces']}
    assert {i: v[0] for i, v in final.items()} == want, ('final set', final, 'walls.json', want)
    assert {'floor', 'wall'} <= set(want.values()), want
    for s in walls['surfaces']:
        corners = final[s['id']][1]
        assert len(corners) == len(s['extent']), (s['id'], corners, s['extent'])
        for c in s['extent']:  # the same corners, from any start (printed to 1e-6 m)
            assert min(max(abs(x - y) for x, y in zip(c, k)) for k in corners) < 2e-6, (s['id'], c)
    print(f'{drawn} of {frames} frames drawn ({missed} refreshes skipped); last frame: '
          f'{100.0 * agree / total:.1f}% of {total} pixels as its planes '
          f'{ {i: v[0] for i, v in drawn_set.items()} } fall from its eye pose (expected %: '
          f'{share}; drawn: {seen_count}); predicted {summary["past_pose_ms_mean"]} ms past the '
          f'pose, draw {summary["draw_ms_mean"]} ms mean, {summary["draw_ms_max"]} ms max; '
          f'final set {want} as walls.json')
    # The planes fill a real part of the view, and the frame shows each in its label's colour
    # where it falls (the pixels that disagree lie on the polygons' edges).
    assert total - expected_count['none'] > 0.05 * total, share
    assert agree >= 0.97 * total, ('pixels as expected', agree, total, expected_count, seen_count)


if __name__ == '__main__':
    try:
        main()
    except AssertionError as e:
        print(f'check_drawn_planes: {e}', file=sys.stderr)
        sys.exit(1)

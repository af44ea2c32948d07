#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# CLI tests of the wallar binary: conventions (help, exit codes, errors on one stderr line,
# JSON on request), replay --stats of the bundled recording, and the record -> replay round trip.
#
# usage: test_cli.sh WALLAR_BINARY SOURCE_DIR CASE    (WALLAR_EMULATOR may hold e.g. qemu-aarch64)
set -uo pipefail
bin=$1
src=$2
case_name=$3
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
rec="$src/tests/data/euroc_v1_01_still"
fail() { echo "FAIL [$case_name]: $*" >&2; exit 1; }
wallar() { ${WALLAR_EMULATOR:-} "$bin" "$@"; }
# Runs wallar, keeping stdout, stderr and the exit code.
run() { wallar "$@" >"$tmp/out" 2>"$tmp/err"; echo $? >"$tmp/rc"; }
rc() { cat "$tmp/rc"; }
expect_rc() { [ "$(rc)" = "$1" ] || fail "exit code $(rc), expected $1; stderr: $(cat "$tmp/err")"; }
expect_err() { grep -qF -- "$1" "$tmp/err" || fail "stderr lacks '$1': $(cat "$tmp/err")"; }
expect_out() { grep -qF -- "$1" "$tmp/out" || fail "stdout lacks '$1': $(cat "$tmp/out")"; }
one_err_line() { [ "$(grep -c . "$tmp/err")" = 1 ] || fail "expected one stderr line: $(cat "$tmp/err")"; }
json() { python3 -c "import json,sys; d=json.load(open('$tmp/out')); print($1)"; }
# still_imu FILE SEED NG KG NA KA: an EuRoC imu0/data.csv of two minutes at rest at 200 Hz,
# white noise NG / NA and bias random walk KG / KA (gyro / accelerometer, continuous-time
# densities in their discrete forms), for `calibrate imu-noise`.
still_imu() {
  python3 - "$@" <<'PY'
import math, random, sys
path, seed = sys.argv[1], int(sys.argv[2])
ng, kg, na, ka = (float(v) for v in sys.argv[3:7])
random.seed(seed)
rate, n = 200.0, 24000
bg, ba = [0.0] * 3, [0.0] * 3
with open(path, 'w') as f:
    f.write('#timestamp [ns],w_x,w_y,w_z,a_x,a_y,a_z\n')
    for k in range(n):
        g = [bg[i] + ng * math.sqrt(rate) * random.gauss(0, 1) for i in range(3)]
        a = [ba[i] + na * math.sqrt(rate) * random.gauss(0, 1) + (9.81 if i == 2 else 0.0) for i in range(3)]
        for i in range(3):
            bg[i] += kg / math.sqrt(rate) * random.gauss(0, 1)
            ba[i] += ka / math.sqrt(rate) * random.gauss(0, 1)
        f.write('%d,%s\n' % (10**9 + k * 5000000, ','.join('%.9g' % v for v in g + a)))
PY
}
# Starts `wallar run` on the sim board serving live on a free port, stdout to $1.json and stderr
# to $1.err, for $2 seconds (more arguments follow); sets pid and url (ws://127.0.0.1:PORT/).
start_live() {
  local out=$1 secs=$2
  shift 2
  ${WALLAR_EMULATOR:-} "$bin" run --board "$src/board/sim.yaml" --live 127.0.0.1:0 --loop 0 \
    --duration "$secs" --no-view "$@" >"$out.json" 2>"$out.err" &
  pid=$!
  url=
  for _ in $(seq 1 300); do
    url=$(grep -o 'ws://127\.0\.0\.1:[0-9]*/' "$out.err" | head -1)
    [ -n "$url" ] && break
    kill -0 $pid 2>/dev/null || break
    sleep 0.1
  done
  [ -n "$url" ] || fail "no live server URL on stderr: $(cat "$out.err")"
}

case "$case_name" in
help)
  run --help; expect_rc 0; expect_out "replay"; expect_out "record"; expect_out "run"
  run replay --help; expect_rc 0; expect_out "--stats"
  run --version; expect_rc 0; expect_out "wallar"
  ;;
usage_errors)
  run; expect_rc 2; expect_err "wallar:"
  run frobnicate; expect_rc 2
  run replay; expect_rc 2; expect_err "recording"
  run replay "$rec" --rate -3; expect_rc 2
  ;;
replay_stats)
  run replay "$rec" --stats --fast; expect_rc 0
  expect_out "cam0      40 samples"; expect_out "imu0     491 samples"
  expect_out "40 pairs, unpaired left 0, right 0"; expect_out "0 gaps"
  run replay "$rec" --stats --fast --json; expect_rc 0
  [ "$(json "d['streams']['imu0']['count']")" = 491 ] || fail "imu count"
  [ "$(json "round(d['streams']['cam1']['mean_rate_hz'])")" = 20 ] || fail "cam rate"
  [ "$(json "d['replay']['pairing']['pairs']")" = 40 ] || fail "pairs"
  [ "$(json "d['streams']['cam0']['gaps']")" = 0 ] || fail "gaps"
  ;;
replay_bad_input)
  mkdir -p "$tmp/r"; cp -r "$rec/mav0" "$tmp/r/"; chmod -R u+w "$tmp/r"
  sed -i '5s/.*/1403715273462142976,0.1,zz,0.3,0.4,0.5,0.6/' "$tmp/r/mav0/imu0/data.csv"
  run replay "$tmp/r" --fast; expect_rc 2; one_err_line
  expect_err "imu0/data.csv:5: w_y (column 3) must be a finite number, got 'zz'"
  cp "$rec/mav0/imu0/data.csv" "$tmp/r/mav0/imu0/data.csv"
  sed -i '7d' "$tmp/r/mav0/cam1/data.csv"   # a left frame without its right
  run replay "$tmp/r" --fast --strict; expect_rc 2; one_err_line
  expect_err "cam0/data.csv:7: left frame 1403715273512143104 has no right frame"
  run replay "$tmp/r" --fast --stats; expect_rc 0
  expect_out "unpaired left 1, right 0"
  expect_err "cam0 frame 1403715273512143104 has no partner"
  ;;
record_roundtrip)
  run record --board "$src/board/sim.yaml" --out "$tmp/copy" --fast; expect_rc 0
  expect_out "recorded 491 IMU rows, 40 + 40 frames"
  for f in cam0/data.csv cam1/data.csv imu0/data.csv; do
    cmp -s "$rec/mav0/$f" "$tmp/copy/mav0/$f" || fail "$f differs"
  done
  python3 - "$rec" "$tmp/copy" <<'PY' || fail "images differ"
import sys, zlib, struct
def pixels(path):  # decode an 8-bit gray non-interlaced PNG with the standard library
    data = open(path, 'rb').read()
    pos, idat, w, h = 8, b'', 0, 0
    while pos < len(data):
        n, kind = struct.unpack('>I4s', data[pos:pos + 8])
        body = data[pos + 8:pos + 8 + n]
        if kind == b'IHDR': w, h = struct.unpack('>II', body[:8])
        if kind == b'IDAT': idat += body
        pos += 12 + n
    raw, out, prev = zlib.decompress(idat), bytearray(), bytearray(w)
    for y in range(h):
        f, line = raw[y * (w + 1)], bytearray(raw[y * (w + 1) + 1:(y + 1) * (w + 1)])
        for x in range(w):
            a = line[x - 1] if x else 0; b = prev[x]; c = prev[x - 1] if x else 0
            if f == 1: line[x] = (line[x] + a) & 255
            elif f == 2: line[x] = (line[x] + b) & 255
            elif f == 3: line[x] = (line[x] + (a + b) // 2) & 255
            elif f == 4:
                p = a + b - c; pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                line[x] = (line[x] + (a if pa <= pb and pa <= pc else b if pb <= pc else c)) & 255
        out += line; prev = line
    return w, h, bytes(out)
import os
a, b = sys.argv[1], sys.argv[2]
for cam in ('cam0', 'cam1'):
    names = sorted(os.listdir(f'{a}/mav0/{cam}/data'))
    assert names == sorted(os.listdir(f'{b}/mav0/{cam}/data')), cam
    for n in names[::9]:
        assert pixels(f'{a}/mav0/{cam}/data/{n}') == pixels(f'{b}/mav0/{cam}/data/{n}'), n
PY
  run replay "$tmp/copy" --stats --fast; expect_rc 0
  expect_out "40 pairs, unpaired left 0, right 0"; expect_out "imu0     491 samples"
  run record --board "$src/board/sim.yaml" --out "$tmp/copy" --fast; expect_rc 2
  expect_err "already holds a recording"
  # Rotation: 2 MiB segments under a 5 MiB cap (the 40 pairs take ~13 MiB). The kept segments
  # are each a recording, whole pairs only, and the last one ends with the stream.
  run record --board "$src/board/sim.yaml" --out "$tmp/rot" --fast --segment-mb 2 --max-mb 5 \
    --json; expect_rc 0
  [ "$(json "d['rotation']['segments_deleted'] >= 3")" = True ] || fail "segments deleted"
  [ "$(json "d['rotation']['segments_kept']")" = "$(ls "$tmp/rot" | wc -l)" ] || fail "kept"
  [ "$(du -s --apparent-size -k "$tmp/rot" | cut -f1)" -le $((7 * 1024)) ] || fail "over the cap"
  for seg in "$tmp"/rot/*; do
    run replay "$seg" --stats --fast; expect_rc 0; expect_out "unpaired left 0, right 0"
  done
  last=$(ls "$tmp/rot" | tail -1)
  [ "$(tail -1 "$tmp/rot/$last/mav0/cam0/data.csv" | cut -d, -f1)" = \
    "$(tail -1 "$rec/mav0/cam0/data.csv" | cut -d, -f1)" ] || fail "the last segment ends early"
  run record --board "$src/board/sim.yaml" --out "$tmp/rot" --fast --segment-mb 2; expect_rc 2
  expect_err "already holds recording segments"
  run record --board "$src/board/sim.yaml" --out "$tmp/rot2" --fast --max-mb 5; expect_rc 2
  expect_err "--max-mb needs --segment-mb"
  ;;
run_sim)
  # The appliance on the sim board at real time (the README's first command), JSON summary.
  run run --board "$src/board/sim.yaml" --out "$tmp/out_dir" --json --view-every 20; expect_rc 0
  [ "$(json "d['replay']['pairing']['pairs']")" = 40 ] || fail "pairs"
  [ "$(json "d['frames']['in']")" = 40 ] || fail "frames in"
  [ "$(json "d['imu']['dropped']")" = 0 ] || fail "IMU samples dropped"
  [ "$(json "d['stop_reason']")" = "end of replay" ] || fail "stop reason"
  [ -s "$tmp/out_dir/run_summary.json" ] || fail "no run_summary.json"
  # Every tracked frame's pose (at 1x under an emulator tracking skips frames: fewer than 40).
  tracked=$(json "d['frames']['tracked']")
  [ "$tracked" -ge 1 ] && [ "$(grep -c . "$tmp/out_dir/trajectory.tum")" = "$tracked" ] || fail "trajectory.tum"
  head -c 3 "$tmp/out_dir/map.ply" | grep -q ply || fail "no map.ply"
  [ -s "$tmp/out_dir/view/view_000000.png" ] || fail "no view PNG"
  python3 -c "import struct,sys; b=open('$tmp/out_dir/view/view_000000.png','rb').read(24); sys.exit(0 if struct.unpack('>II', b[16:24]) == (1280, 720) else 1)" || fail "view size"
  # Heap allocations on the fixed-rate threads after start-up: none (counted by the wallar
  # binary's malloc family, which operator new, Eigen and OpenCV use; null in sanitizer builds,
  # which keep their own).
  python3 - "$tmp/out" <<'PY' || fail "allocations on fixed-rate threads"
import json, sys
d = json.load(open(sys.argv[1]))
rows = {t['name']: t for t in d['threads']}
for name in ("tracking", "supervisor", "reconstruct", "log"):
    assert name in rows, rows.keys()
for name in ('tracking', 'supervisor'):
    a = rows[name]['allocations_after_start']
    assert a is None or a == 0, (name, a)
names = [s['name'] for s in d['stages']]
for stage in ('tracking', 'render', 'camera -> display', 'reconstruction'):
    assert stage in names, names
PY
  # The real scene: one floor about 0.9 m under the first camera, gravity-aligned search.
  python3 - "$tmp/out_dir/walls.json" <<'PY' || fail "walls.json of the real recording"
import json, sys
d = json.load(open(sys.argv[1]))
assert d['mode'].startswith('2-D'), d['mode']
floors = [s for s in d['surfaces'] if s['kind'] == 'floor']
assert len(floors) == 1, d['surfaces']
assert 0.5 < -floors[0]['d'] < 1.5, floors[0]['d']
assert floors[0]['inliers'] > 100, floors[0]
PY
  # Text output with --stats: the wall model and the table of threads and stages.
  run run --board "$src/board/sim.yaml" --out "$tmp/out2" --fast --no-view --stats; expect_rc 0
  expect_out "wall model (2-D"; expect_out "floor"; expect_out "thread       policy"
  expect_out "capture -> tracking"
  # Without --view-every the view is drawn but no PNG is written (the unit's default on a
  # headset: PNGs every few frames forever would fill and wear its SD card).
  run run --board "$src/board/sim.yaml" --out "$tmp/out3" --fast --json; expect_rc 0
  [ "$(json "d['frames']['in']")" = 40 ] || fail "frames in (no PNGs)"
  [ ! -e "$tmp/out3/view" ] || fail "PNGs written without --view-every"
  run run --board "$src/board/sim.yaml" --check; expect_rc 0; expect_out "board sim: ok"
  expect_out "replay.recording"
  # The Pi board on a machine that is not a Pi: its calibration file (exit 2) and each device.
  run run --board "$src/board/rpi5.yaml" --check; expect_rc 2; expect_out "board rpi5"
  expect_err "rpi5.yaml: calibration: /etc/wallar/calibration/rig.yaml: no such file"
  expect_err "rpi5.yaml: display.card: /dev/dri/by-path/platform-axi:gpu-card: no such device"
  # The same board against a fake Raspberry Pi 5 device tree (kernel 6.6.45+: the RP1 header
  # chip is gpiochip0, labelled pinctrl-rp1; the udev links of both cameras and the display;
  # i2c-1's controller and driver for the bus recovery): every device resolves.
  pi=$tmp/pi5
  mkdir -p "$pi/dev/v4l/by-path" "$pi/dev/dri/by-path" "$pi/etc/wallar/calibration"
  for n in video0 video2 i2c-1 gpiochip0 gpiochip10 dri/card1; do : >"$pi/dev/$n"; done
  ln -s ../../video0 "$pi/dev/v4l/by-path/platform-xhci-hcd.1-usb-0:1:1.0-video-index0"
  ln -s ../../video2 "$pi/dev/v4l/by-path/platform-xhci-hcd.0-usb-0:1:1.0-video-index0"
  ln -s ../card1 "$pi/dev/dri/by-path/platform-axi:gpu-card"
  chip() {  # chip NODE SYSFS-CLASS-NAME LABEL LINES
    mkdir -p "$pi/sys/bus/gpio/devices/$1/gpio/$2"
    echo "$3" >"$pi/sys/bus/gpio/devices/$1/gpio/$2/label"
    echo "$4" >"$pi/sys/bus/gpio/devices/$1/gpio/$2/ngpio"
  }
  chip gpiochip0 gpiochip512 pinctrl-rp1 54
  chip gpiochip10 gpiochip566 gpio-brcmstb@107d508500 32
  ctl=$pi/sys/devices/platform/axi/1000120000.pcie/1f00074000.i2c
  mkdir -p "$ctl/i2c-1" "$pi/sys/bus/i2c/devices" "$pi/sys/bus/platform/drivers/i2c_designware"
  ln -s ../../../devices/platform/axi/1000120000.pcie/1f00074000.i2c/i2c-1 "$pi/sys/bus/i2c/devices/i2c-1"
  ln -s ../../../../../bus/platform/drivers/i2c_designware "$ctl/driver"
  run eval synth-rig --out "$tmp/pical" --duration 0.5 --camera-rate 30 --imu-only; expect_rc 0
  cp "$tmp/pical/mav0/camchain-imucam.yaml" "$pi/etc/wallar/calibration/rig.yaml"
  run run --board "$src/board/rpi5.yaml" --check --root "$pi"; expect_rc 0; expect_out "board rpi5: ok"
  for line in "imu.data_ready.chip  *pinctrl-rp1 -> /dev/gpiochip0 (54 lines" \
      "cameras.left.device  */dev/v4l/by-path/platform-xhci-hcd.1-usb-0:1:1.0-video-index0 -> /dev/video0" \
      "cameras.right.device  */dev/v4l/by-path/platform-xhci-hcd.0-usb-0:1:1.0-video-index0 -> /dev/video2" \
      "display.card  */dev/dri/by-path/platform-axi:gpu-card -> /dev/dri/card1" \
      "imu.bus_recovery  *rebinds 1f00074000.i2c (i2c_designware)" "input.exit_button.chip  *pinctrl-rp1" \
      "cameras.left mode  *640x480 YUYV @ 30 Hz, as calibrated" "camera modes  *not asked"; do
    grep -q -- "$line" "$tmp/out" || fail "--check --root: no '$line': $(cat "$tmp/out")"
  done
  # An older kernel numbered the same chip gpiochip4: found by its label all the same.
  mv "$pi/dev/gpiochip0" "$pi/dev/gpiochip4"; mv "$pi/sys/bus/gpio/devices/gpiochip0" "$pi/sys/bus/gpio/devices/gpiochip4"
  run run --board "$src/board/rpi5.yaml" --check --root "$pi"; expect_rc 0
  expect_out "pinctrl-rp1 -> /dev/gpiochip4 (54 lines"
  # A camera mode the calibration does not have: exit 2, the key named.
  sed 's/^    width: 640/    width: 752/' "$src/board/rpi5.yaml" >"$tmp/rpi5_752.yaml"
  run run --board "$tmp/rpi5_752.yaml" --check --root "$pi"; expect_rc 2
  expect_err "rpi5_752.yaml: cameras.left.width/height: 752x480 but"
  run run --board "$src/board/rpi5.yaml" --root "$pi"; expect_rc 2; one_err_line
  expect_err "--root: only with --check"
  printf 'board: {name: x}\nsource: replay\nreplay: {recording: r, sped: 2}\n' >"$tmp/bad.yaml"
  run run --board "$tmp/bad.yaml" --check; expect_rc 2; one_err_line
  expect_err "bad.yaml:3: unknown key 'replay.sped'"
  ;;
run_faults)
  # Faults injected into the replay: each degraded mode entered and left once, exit 0.
  run run --board "$src/board/sim.yaml" --out "$tmp/o" --fast --deterministic --no-view --json \
      --fault corrupt-frame@0.3 --fault camera-stall@1.0+0.5 --fault imu-unplug@1.6+0.25
  expect_rc 0
  [ "$(json "d['degraded']['camera_lost'], d['degraded']['camera_recovered'], d['degraded']['imu_lost'], d['degraded']['imu_recovered']")" = "1 1 1 1" ] || fail "transitions: $(cat "$tmp/out")"
  expect_err "camera lost"; expect_err "IMU back"
  run run --board "$src/board/sim.yaml" --out "$tmp/o" --fault melt@1+1; expect_rc 2; one_err_line
  expect_err "--fault 'melt@1+1': unknown fault"
  run run --board "$src/board/sim.yaml" --out "$tmp/o" --keys /dev/input/no-such-event; expect_rc 1
  expect_err "/dev/input/no-such-event"
  ;;
live)
  # `wallar run --live`: Foxglove's own client (@foxglove/ws-protocol, tools/node) gets
  # serverInfo, every channel and messages on each that parse under its schema, while the
  # appliance runs the sim board. Then the same run twice, a client that keeps up reading in
  # both, and in the second a client that subscribes to everything and never reads: the
  # stage latencies do not change (newest wins per channel; the stalled client loses messages,
  # counted), nor does a frame go untracked.
  command -v node >/dev/null && [ -d "$src/tools/node/node_modules/@foxglove/ws-protocol" ] ||
    fail "no Node.js or no tools/node/node_modules (run tools/setup)"
  client() { node "$src/tests/net/foxglove_ws_client.cjs" "$src/tools/node" "$@"; }
  secs=8
  [ -n "${WALLAR_EMULATOR:-}${WALLAR_SANITIZE:-}" ] && secs=12  # a slower start
  finish_live() {
    wait $pid; local rc=$?
    [ $rc = 0 ] || fail "run $1 exited $rc: $(cat "$tmp/run$1.err")"
  }
  start_live "$tmp/run1" "$secs" --json --out "$tmp/o1"
  client "$url" 1 /pose /tf /trajectory /map /walls /cam0 /cam1 /stats /log >"$tmp/first" ||
    fail "the reference client: $(cat "$tmp/first")"
  client "$url" 1 --hold $((secs / 2)) >"$tmp/keep1" || fail "client beside run 1: $(cat "$tmp/keep1")"
  finish_live 1
  python3 - "$tmp/first" "$tmp/run1.json" "$tmp/keep1" <<'PY' || fail "live channels: $(head -c 3000 "$tmp/first")"
import base64, json, sys
got = json.load(open(sys.argv[1]))
assert got['serverInfo']['name'] == 'wallar', got['serverInfo']
schemas = {c['topic']: c['schemaName'] for c in got['channels']}
assert schemas == {'/pose': 'foxglove.PoseInFrame', '/tf': 'foxglove.FrameTransforms',
                   '/trajectory': 'foxglove.PosesInFrame', '/map': 'foxglove.PointCloud',
                   '/walls': 'foxglove.SceneUpdate', '/cam0': 'foxglove.CompressedImage',
                   '/cam1': 'foxglove.CompressedImage', '/stats': 'wallar.Stats',
                   '/log': 'foxglove.Log'}, schemas
last = {t: m['message'] for t, m in got['last'].items()}
assert last['/pose']['frame_id'] == 'world' and 'orientation' in last['/pose']['pose']
tf = {(t['parent_frame_id'], t['child_frame_id']) for t in last['/tf']['transforms']}
assert {('world', 'body'), ('body', 'cam0'), ('body', 'cam1')} <= tf, tf
# Once the attitude filter has gravity, the frame "up" (z against gravity) holds the world.
later = json.load(open(sys.argv[3]))['last']['/tf']['message']['transforms']
up = [t for t in later if (t['parent_frame_id'], t['child_frame_id']) == ('up', 'world')]
assert len(up) == 1, later
# The map: x y z sigma r g b as float32 per point (the bytes' length only, as the client keeps it).
assert last['/map']['point_stride'] == 28 and last['/map']['data'] > 28 * 100, last['/map']
ents = last['/walls']['entities']
assert any(e['id'].startswith('surface-') and e['triangles'] for e in ents), ents
assert last['/walls']['deletions'][0]['type'] == 1
assert last['/cam0']['format'] == 'jpeg' and last['/cam0']['frame_id'] == 'cam0'
names = [t['name'] for t in last['/stats']['threads']]
assert 'tracking' in names and 'live' in names, names
assert 'board sim' in last['/log']['message'] or 'live server' in last['/log']['message'], last['/log']
run = json.load(open(sys.argv[2]))
live = run['live']
assert live['url'].startswith('ws://127.0.0.1:') and live['clients_total'] == 2, live
assert live['images'] > 0 and live['client_errors'] == 0, live
PY
  # Every network without a token: said at start. The board's token file: a client without the
  # token is refused before the upgrade, one with it is served.
  run run --board "$src/board/sim.yaml" --live 0.0.0.0:0 --duration 1 --no-view --out "$tmp/o0"
  expect_rc 0; expect_err "without a token: anyone on that network can watch"
  expect_err "live server on ws://$(hostname):"  # the host's name, not 0.0.0.0
  printf 's3cret-1\n' >"$tmp/live.token"
  sed 's|recording: \.\./|recording: '"$src"'/|' "$src/board/sim.yaml" >"$tmp/token.yaml"
  printf 'live:\n  port: 0\n  token_file: live.token\n' >>"$tmp/token.yaml"
  ${WALLAR_EMULATOR:-} "$bin" run --board "$tmp/token.yaml" --loop 0 --duration "$secs" --no-view \
    --out "$tmp/ot" >/dev/null 2>"$tmp/token.err" &
  pid=$!
  for _ in $(seq 1 300); do grep -q 'ws://' "$tmp/token.err" && break; sleep 0.1; done
  url=$(grep -o 'ws://127\.0\.0\.1:[0-9]*/' "$tmp/token.err" | head -1)
  [ -n "$url" ] || fail "no URL with the token file: $(cat "$tmp/token.err")"
  grep -q "without a token" "$tmp/token.err" && fail "a token warning on 127.0.0.1"
  client "$url" --refused >/dev/null || fail "served without the token"
  client "$url?token=s3cret-1" 1 /pose >/dev/null || fail "refused with the token"
  kill -INT $pid; wait $pid
  # The same run, the same reading client, and a client that never reads.
  ids=$(python3 -c "import json; print(' '.join(str(c['id']) for c in json.load(open('$tmp/first'))['channels']))")
  start_live "$tmp/run2" "$secs" --json --out "$tmp/o2"
  python3 - "$url" "$secs" $ids <<'PY' &
import socket, sys, time, json
host, port = sys.argv[1][5:].rstrip('/').split(':')
s = socket.socket()
s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
s.connect((host, int(port)))
s.sendall(b'GET / HTTP/1.1\r\nHost: x\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n'
          b'Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n'
          b'Sec-WebSocket-Protocol: foxglove.websocket.v1\r\n\r\n')
head = b''
while b'\r\n\r\n' not in head:  # the upgrade's answer, then nothing more is read
    head += s.recv(1)
assert head.startswith(b'HTTP/1.1 101'), head
subs = [{'id': i, 'channelId': int(c)} for i, c in enumerate(sys.argv[3:])]
text = json.dumps({'op': 'subscribe', 'subscriptions': subs}).encode()
frame = bytes([0x81, 0xfe]) + len(text).to_bytes(2, 'big') + bytes(4) + text  # masked, key 0
s.sendall(frame)
time.sleep(float(sys.argv[2]) + 5)  # never reads
PY
  stalled=$!
  client "$url" 1 --hold $((secs / 2)) >"$tmp/keep2" || fail "client beside the stalled one: $(cat "$tmp/keep2")"
  finish_live 2
  kill $stalled 2>/dev/null; wait $stalled 2>/dev/null
  python3 - "$tmp/run1.json" "$tmp/run2.json" "$tmp/keep2" <<'PY' || fail "a stalled client changed the run"
import json, sys
a, b = (json.load(open(p)) for p in sys.argv[1:3])
keep = json.load(open(sys.argv[3]))
assert b['live']['clients_total'] == 2 and b['live']['dropped'] > 0, b['live']
assert keep['counts']['/pose'] > 10 and keep['counts']['/cam0'] >= 2, keep['counts']
for run in (a, b):
    # A frame delivered as --duration stops the run may go untracked (seen once in 134 on a
    # loaded machine); none overwritten.
    f = run['frames']
    assert f['overwritten'] == 0 and f['tracked'] >= f['in'] - 1, f
st = lambda r: {s['name']: s for s in r['stages']}
sa, sb = st(a), st(b)
for name in ('capture -> tracking', 'tracking'):
    pa, pb = sa[name]['p50_ms'], sb[name]['p50_ms']
    print(f'{name}: p50 {pa:.2f} -> {pb:.2f} ms, p99 {sa[name]["p99_ms"]:.2f} -> {sb[name]["p99_ms"]:.2f} ms')
    # Loose for a loaded 2-core machine; a stage that waited on the network would take
    # hundreds of ms once the stalled client's buffers are full.
    assert pb <= 1.5 * pa + 3.0, (name, pa, pb)
    assert sb[name]['p99_ms'] <= 2.0 * sa[name]['p99_ms'] + 20.0, (name, sa[name], sb[name])
PY
  ;;
client)
  # The client API (issue 20): examples/print_planes (libwallar-client) against
  # `wallar run --board sim.yaml --client-socket`: the tracking state, the predicted pose, and
  # the floor and wall planes with their labels, whose polygons are walls.json's. Then the same
  # run with a frozen client, a client sending garbage, one of another protocol version and
  # one of another user beside it: each is counted or refused with its message, and the stage
  # latencies stay within a generous bound of the first run's.
  pp=${WALLAR_PRINT_PLANES:-}
  [ -x "$pp" ] || fail "no print_planes binary (WALLAR_PRINT_PLANES='$pp')"
  secs=6
  [ -n "${WALLAR_EMULATOR:-}${WALLAR_SANITIZE:-}" ] && secs=12
  chmod 711 "$tmp"
  mkdir -m 755 "$tmp/run"
  sock="$tmp/run/client.sock"
  start_client_run() {  # name
    ${WALLAR_EMULATOR:-} "$bin" run --board "$src/board/sim.yaml" --client-socket "$sock" \
      --loop 0 --duration "$secs" --no-view --json --out "$tmp/o$1" >"$tmp/run$1.json" \
      2>"$tmp/run$1.err" &
    pid=$!
  }
  finish_client_run() {
    wait $pid; local rc=$?
    [ $rc = 0 ] || fail "run $1 exited $rc: $(cat "$tmp/run$1.err")"
  }
  # Bad paths: one line naming the key, exit 2, before anything runs.
  run run --board "$src/board/sim.yaml" --client-socket "$tmp" --duration 1 --no-view --out "$tmp/ob"
  expect_rc 2; one_err_line; expect_err "client.socket $tmp: exists and is not a socket"
  run run --board "$src/board/sim.yaml" --client-socket "/$(printf 'x%.0s' $(seq 1 110))" --no-view
  expect_rc 2; one_err_line; expect_err "a UNIX socket's path is at most 107 bytes"
  start_client_run 1
  ${WALLAR_EMULATOR:-} "$pp" --socket "$sock" --rate 30 --ahead-ms 16 --wait 20 >"$tmp/pp1" 2>"$tmp/pp1.err" ||
    fail "print_planes: $(cat "$tmp/pp1.err")"
  finish_client_run 1
  grep -q "client API on $sock (mode 0660" "$tmp/run1.err" || fail "no client API line: $(cat "$tmp/run1.err")"
  python3 - "$tmp/pp1" "$tmp/o1/walls.json" "$tmp/run1.json" <<'PY' || fail "print_planes against walls.json: $(grep -v '^pose' "$tmp/pp1" | head -c 3000)"
import json, sys
lines = open(sys.argv[1]).read().splitlines()
walls = json.load(open(sys.argv[2]))
run = json.load(open(sys.argv[3]))
assert any(l.startswith('event tracking=2') for l in lines), 'no tracking event'
poses = [l for l in lines if l.startswith('pose ')]
assert len(poses) > 30 and sum('flags=15 tracking=2' in l for l in poses) > 20, poses[:5]
final = lines.index(next(l for l in lines if l.startswith('final ')))
planes = {}
for l in lines[final + 1:]:
    f = dict(kv.split('=', 1) for kv in l.split()[1:])
    planes[int(f['id'])] = (f['label'], f['orientation'],
                            [tuple(map(float, p.split(','))) for p in f['world'].split(';')])
labels = {p[0] for p in planes.values()}
assert {'floor', 'wall'} <= labels, planes
for s in walls['surfaces']:
    label, orientation, poly = planes[s['id']]
    assert label == s['kind'], (s['id'], label, s['kind'])
    assert orientation == {'floor': 'horizontal-upward', 'wall': 'vertical',
                           'ceiling': 'horizontal-downward'}[label], (label, orientation)
    ext = [tuple(c) for c in s['extent']]
    assert len(ext) == len(poly), (s['id'], len(ext), len(poly))
    # The same corners (the API's are counter-clockwise about the normal, from any start).
    for c in ext:
        assert min(max(abs(a - b) for a, b in zip(c, p)) for p in poly) < 2e-6, (s['id'], c)
assert len(planes) == len(walls['surfaces']), (sorted(planes), [s['id'] for s in walls['surfaces']])
c = run['client']
assert c['accepted'] == 1 and c['malformed'] == 0 and c['plane_models'] >= 1, c
# The view apps render from: the rectified left camera, at cam0's place in the body (EuRoC's
# T_BS translation; rectification only turns it), a unit quaternion.
view = [float(x) for x in next(l for l in lines if l.startswith('view in body:')).split()[4:]
        if x not in ('p', 'm')]
q, pos = view[:4], view[4:7]
assert abs(sum(x * x for x in q) - 1) < 1e-5, view
assert max(abs(a - b) for a, b in zip(pos, (-0.0216401, -0.0646770, 0.0098107))) < 1e-5, view
print('planes', {i: p[0] for i, p in planes.items()}, 'client', c)
PY
  # Run 2: the same, with hostile and frozen clients beside print_planes.
  start_client_run 2
  # The log line comes once the socket has its mode and group (it is bound with 0600 first).
  for _ in $(seq 1 300); do grep -q "client API on" "$tmp/run2.err" && break; sleep 0.05; done
  [ -S "$sock" ] || fail "no socket: $(cat "$tmp/run2.err")"
  [ "$(stat -c %a "$sock")" = 660 ] || fail "socket mode $(stat -c %a "$sock")"
  python3 - "$sock" "$secs" >"$tmp/hostile" 2>&1 <<'PY' &
import random, socket, struct, sys, time
path, secs = sys.argv[1], float(sys.argv[2])
def conn(rcvbuf=None):
    s = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    if rcvbuf: s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, rcvbuf)
    s.connect(path)
    return s
hello = lambda v: struct.pack('<IHHII', 8 + 6, 1, 0, 0x524c4157, v) + b'frozen'
frozen = conn(4096)
frozen.sendall(hello(1))  # then never reads
old = conn()
old.sendall(hello(99))
answer = old.recv(4096)
print('version 99:', answer[12:].decode())
rng = random.Random(20)
t_end = time.time() + secs - 2
garbage = 0
while time.time() < t_end:
    g = conn()
    try:
        g.sendall(bytes(rng.randrange(256) for _ in range(rng.randrange(8, 600))))
        g.sendall(struct.pack('<IHH', 1 << 30, 1, 0))  # an oversized message if still open
    except OSError:
        pass
    garbage += 1
    g.close()
    time.sleep(0.2)
print('garbage connections', garbage)
time.sleep(3)
PY
  hostile=$!
  # Another user: the socket's mode keeps them out (the kernel refuses connect()).
  other=
  if command -v setpriv >/dev/null && [ -x /usr/bin/python3 ] && [ "$(id -u)" = 0 ]; then
    other=$(setpriv --reuid=65534 --regid=65534 --clear-groups /usr/bin/python3 -c "
import socket
s = socket.socket(socket.AF_UNIX)
try:
    s.connect('$sock'); print('connected')
except PermissionError as e:
    print('refused', e)" 2>&1)
  fi
  ${WALLAR_EMULATOR:-} "$pp" --socket "$sock" --rate 30 --wait 20 >"$tmp/pp2" 2>"$tmp/pp2.err" ||
    fail "print_planes beside hostile clients: $(cat "$tmp/pp2.err")"
  finish_client_run 2
  wait $hostile
  grep -q "version 99: protocol version 99 is not served: this wallar speaks version 1" "$tmp/hostile" ||
    fail "no version message: $(cat "$tmp/hostile")"
  if [ -n "$other" ]; then
    case "$other" in refused*) ;; *) fail "uid 65534 was not refused: $other" ;; esac
  else
    echo "another user: not tested (needs root and setpriv)"
  fi
  grep -q '^final ' "$tmp/pp2" || fail "print_planes beside hostile clients got no final set"
  python3 - "$tmp/run1.json" "$tmp/run2.json" <<'PY' || fail "hostile clients changed the run"
import json, os, sys
a, b = (json.load(open(p)) for p in sys.argv[1:3])
c = b['client']
assert c['accepted'] == 2 and c['refused'] == 1 and c['malformed'] >= 5, c
# Under an emulator (qemu's TCG, beside other tests) tracking is slower than the camera with or
# without clients (1 and 15 of 160-194 frames skipped as stale in two aarch64 runs): the timing
# says nothing of the clients there, so only the native run compares it.
emulated = bool(os.environ.get('WALLAR_EMULATOR'))
for run in (a, b):
    # Every frame tracked or skipped as stale (counted); one delivered as --duration stops the
    # run may go untracked. Natively none is skipped.
    f = run['frames']
    assert f['tracked'] + f['overwritten'] >= f['in'] - 1, f
    assert emulated or f['overwritten'] == 0, f
st = lambda r: {s['name']: s for s in r['stages']}
sa, sb = st(a), st(b)
for name in ('imu -> filter', 'capture -> tracking', 'tracking'):
    pa, pb = sa[name]['p50_ms'], sb[name]['p50_ms']
    print(f'{name}: p50 {pa:.2f} -> {pb:.2f} ms, p99 {sa[name]["p99_ms"]:.2f} -> {sb[name]["p99_ms"]:.2f} ms')
    if emulated:
        continue
    assert pb <= 1.5 * pa + 3.0, (name, pa, pb)
    assert sb[name]['p99_ms'] <= 2.0 * sa[name]['p99_ms'] + 20.0, (name, sa[name], sb[name])
# The client API's writer on the tracking thread allocates nothing (the wallar binary counts).
rows = {t['name']: t for t in b['threads']}
assert 'client' in rows and 'accepted 2' in rows['client']['note'], rows.get('client')
a = rows['tracking']['allocations_after_start']
assert a is None or a == 0, ('tracking', a)
print('client', c)
PY
  # SO_PEERCRED: with the socket open to everyone (mode 0666), another user gets past the
  # kernel but is refused at its hello, with the firmware's message; the owner is served.
  if [ -n "$other" ]; then
    sed 's|recording: \.\./|recording: '"$src"'/|' "$src/board/sim.yaml" >"$tmp/open.yaml"
    printf 'client:\n  socket: %s\n  mode: 0666\n  group: no-such-group-here\n' "$sock" >>"$tmp/open.yaml"
    ${WALLAR_EMULATOR:-} "$bin" run --board "$tmp/open.yaml" --loop 0 --duration 4 --no-view \
      --json --out "$tmp/o3" >"$tmp/run3.json" 2>"$tmp/run3.err" &
    pid=$!
    for _ in $(seq 1 300); do grep -q "client API on" "$tmp/run3.err" && break; sleep 0.05; done
    [ "$(stat -c %a "$sock")" = 666 ] || fail "socket mode $(stat -c %a "$sock"), expected 666"
    grep -q "no group no-such-group-here on this system: the owner only" "$tmp/run3.err" ||
      fail "no word of the missing group: $(cat "$tmp/run3.err")"
    cred=$(setpriv --reuid=65534 --regid=65534 --clear-groups /usr/bin/python3 -c "
import socket, struct
s = socket.socket(socket.AF_UNIX)
s.connect('$sock')
s.sendall(struct.pack('<IHHII', 8, 1, 0, 0x524c4157, 1))
print(s.recv(4096)[12:].decode())" 2>&1)
    ${WALLAR_EMULATOR:-} "$pp" --socket "$sock" --wait 5 --duration 1 >"$tmp/pp3" 2>&1 ||
      fail "the owner was not served: $(cat "$tmp/pp3")"
    finish_client_run 3
    [ "$cred" = "uid 65534 may not use the client API (group none)" ] ||
      fail "uid 65534 past SO_PEERCRED: $cred"
    python3 -c "import json,sys; c=json.load(open('$tmp/run3.json'))['client']; sys.exit(0 if c['refused']==1 and c['accepted']==1 else 1)" ||
      fail "run 3 counters: $(python3 -c "import json; print(json.load(open('$tmp/run3.json'))['client'])")"
  fi
  ;;
client_draw)
  # The EGL example (issue 20): examples/draw_planes against `wallar run --board sim.yaml
  # --client-socket` (the bundled still recording, looped). A draws at 30 Hz for a while and
  # writes its last frame: its frames plus the refreshes it skipped are its rate times its
  # duration, each eye pose is the body pose times the view, and the frame shows the planes
  # it had in their labels' colours where they fall from its last eye pose. B draws until the
  # firmware stops (SIGTERM): one line on stderr, exit 1, its summary still printed, and the
  # last plane set it got (the model the firmware fits as it stops) is walls.json's: ids,
  # labels (floor and wall) and corners (tests/client/check_drawn_planes.py).
  dp=${WALLAR_DRAW_PLANES:-}
  [ -x "$dp" ] || fail "no draw_planes binary (WALLAR_DRAW_PLANES='$dp')"
  secs=6 strict=--strict
  [ -n "${WALLAR_EMULATOR:-}${WALLAR_SANITIZE:-}" ] && secs=12 strict=
  sock="$tmp/c.sock"
  ${WALLAR_EMULATOR:-} "$bin" run --board "$src/board/sim.yaml" --client-socket "$sock" --loop 0 \
    --no-view --json --out "$tmp/o" >"$tmp/run.json" 2>"$tmp/run.err" &
  pid=$!
  ${WALLAR_EMULATOR:-} "$dp" --socket "$sock" --rate 30 --duration $secs --size 320x240 \
    --fov-deg 80 --out "$tmp/last.ppm" --wait 30 >"$tmp/a" 2>"$tmp/a.err" &
  apid=$!
  ${WALLAR_EMULATOR:-} "$dp" --socket "$sock" --rate 10 --size 64x48 --wait 30 >"$tmp/b" \
    2>"$tmp/b.err" &
  bpid=$!
  wait $apid; arc=$?
  [ $arc = 0 ] || { kill $pid $bpid; fail "draw_planes exited $arc: $(cat "$tmp/a.err")"; }
  kill -TERM $pid
  wait $pid || fail "run exited $?: $(cat "$tmp/run.err")"
  wait $bpid; brc=$?
  [ $brc = 1 ] && [ "$(grep -c . "$tmp/b.err")" = 1 ] &&
    grep -q "^draw_planes: error: the firmware closed the connection after [0-9]* frames$" "$tmp/b.err" &&
    grep -q '^summary frames=' "$tmp/b" ||
    fail "draw_planes when the firmware stopped: exit $brc, stderr: $(cat "$tmp/b.err")"
  python3 "$src/tests/client/check_drawn_planes.py" "$tmp/a" "$tmp/last.ppm" "$tmp/b" \
    "$tmp/o/walls.json" --rate 30 --duration $secs --fov-deg 80 $strict ||
    fail "draw_planes: $(grep -v '^frame' "$tmp/a" | head -c 2000)"
  # Bad options: one line, exit 2, before connecting.
  out=$(${WALLAR_EMULATOR:-} "$dp" --size 10x10 2>&1); rc=$?
  [ $rc = 2 ] && [ "$(printf '%s\n' "$out" | wc -l)" = 1 ] || fail "--size 10x10: exit $rc: $out"
  ;;
client_prediction)
  # The client API's prediction on the pipeline: a synthetic 6 s of quick turns (300 deg/s
  # peaks) replayed in real time through `wallar run --client-socket`, print_planes asking for
  # the pose at now, now + 16 ms and now + 33 ms at 50 Hz; each pose against the ground truth
  # (tests/client/prediction_error.py), beside holding the pose it came from. Figures:
  # docs/results.md ("Client API: pose prediction").
  pp=${WALLAR_PRINT_PLANES:-}
  [ -x "$pp" ] || fail "no print_planes binary (WALLAR_PRINT_PLANES='$pp')"
  if [ -n "${WALLAR_EMULATOR:-}${WALLAR_SANITIZE:-}" ]; then
    echo "skipped: real-time replay under an emulator or a sanitizer"
    exit 77
  fi
  wallar eval synth-rig --out "$tmp/rec" --motion quick-turns --duration 6 --blur off \
    >"$tmp/gen" 2>&1 || fail "synth-rig: $(cat "$tmp/gen")"
  sed 's|recording: \.\./tests/data/euroc_v1_01_still|recording: '"$tmp/rec"'|' \
    "$src/board/sim.yaml" >"$tmp/board.yaml"
  wallar run --board "$tmp/board.yaml" --client-socket "$tmp/c.sock" --no-view --json \
    --out "$tmp/o" >"$tmp/run.json" 2>"$tmp/run.err" &
  pid=$!
  pps=()
  for a in 0 16 33; do
    "$pp" --socket "$tmp/c.sock" --rate 50 --ahead-ms $a --wait 20 >"$tmp/pp$a" 2>&1 &
    pps+=($!)
  done
  wait $pid || fail "run: $(cat "$tmp/run.err")"
  for p in "${pps[@]}"; do wait "$p" || fail "print_planes exited $?"; done
  for a in 0 16 33; do
    python3 "$src/tests/client/prediction_error.py" "$tmp/rec/mav0" "$tmp/o/trajectory.tum" \
      "$tmp/pp$a" --json >"$tmp/err$a" || fail "prediction_error.py on +$a ms"
    python3 - "$tmp/err$a" "$a" <<'PY' || fail "prediction at +$a ms: $(cat "$tmp/err$a")"
import json, sys
e = json.load(open(sys.argv[1]))
pr, held = e['predicted'], e['held']
print(f"+{sys.argv[2]} ms (median {e['ahead_ms']['median']:.0f} ms past the pose, {e['poses']} poses): "
      f"rotation p95 {pr['rot_deg_p95']:.3f} deg (held {held['rot_deg_p95']:.3f}), "
      f"position p95 {pr['pos_mm_p95']:.2f} mm (held {held['pos_mm_p95']:.2f})")
assert e['poses'] > 150, e
# The turns: the gyro since the pose must remove most of a held pose's error.
assert pr['rot_deg_p95'] < 0.5 * held['rot_deg_p95'], e
assert pr['pos_mm_p95'] < held['pos_mm_p95'], e
# Generous bounds (measured: 0.13, 0.09, 0.75 deg and 4.3, 6.9, 10.7 mm p95).
assert pr['rot_deg_p95'] < 2.0 and pr['pos_mm_p95'] < 25.0, e
PY
  done
  ;;
viewer)
  # The viewer page on the live server's port, in headless Chromium (Debian's chromium): it
  # draws the map, the walls, the head and both cameras from the running appliance, and the
  # screenshot holds each surface's colour where the page says the surface falls.
  command -v chromium >/dev/null || fail "no chromium (tools/setup installs it)"
  [ -d "$src/tools/node/node_modules/ws" ] || fail "no tools/node/node_modules (run tools/setup)"
  start_live "$tmp/run" 120 --out "$tmp/o"
  page="http${url#ws}"
  # The page and its scripts come from the binary; anything else is a 404.
  python3 - "$page" <<'PY' || { kill $pid; fail "the viewer's files"; }
import sys, urllib.request, urllib.error
base = sys.argv[1]
page = urllib.request.urlopen(base).read().decode()
assert 'viewer.js' in page and 'importmap' in page, page[:200]
for path, kind in (('viewer.js', 'javascript'), ('three.module.js', 'javascript'),
                   ('three.core.js', 'javascript'), ('addons/controls/OrbitControls.js', 'javascript')):
    r = urllib.request.urlopen(base + path)
    assert kind in r.headers['Content-Type'] and len(r.read()) > 1000, path
try:
    urllib.request.urlopen(base + 'etc/passwd')
    raise SystemExit('a path that is not the viewer was served')
except urllib.error.HTTPError as e:
    assert e.code == 404, e.code
PY
  node "$src/tests/net/viewer_check.cjs" "$src/tools/node" "$page" "$tmp/viewer.png" >"$tmp/check" ||
    { kill $pid; fail "the page: $(cat "$tmp/check")"; }
  kill -INT $pid; wait $pid
  python3 - "$tmp/check" <<'PY' || fail "viewer check: $(cat "$tmp/check")"
import json, sys
d = json.load(open(sys.argv[1]))
assert d['state']['map'] > 100 and d['state']['walls'] >= 1 and d['state']['images'] >= 2, d
assert d['samples'] >= 10 and d['matched'] >= 0.6 * d['samples'], d
PY
  [ -s "$tmp/viewer.png" ] || fail "no screenshot"
  [ -z "${WALLAR_VIEWER_SCREENSHOT:-}" ] || cp "$tmp/viewer.png" "$WALLAR_VIEWER_SCREENSHOT"
  ;;
run_record)
  # `wallar run --record FILE.mcap`: the sim board's sensor streams as the appliance received
  # them, then the run's outputs, in one file Foxglove's reader accepts; tracked offline, the
  # file gives the trajectory the bundled folder gives.
  command -v node >/dev/null && [ -d "$src/tools/node/node_modules/@mcap/core" ] ||
    fail "no Node.js or no tools/node/node_modules (run tools/setup)"
  run run --board "$src/board/sim.yaml" --record "$tmp/run.mcap" --no-view --json --out "$tmp/o"
  expect_rc 0
  read -r imu tracked dropped < <(json "d['imu']['samples'], d['frames']['tracked'], d['record']['imu_dropped'] + d['record']['frames_dropped'] + d['record']['write_errors']" | tr -d '(),')
  [ "$dropped" = 0 ] || fail "the recorder lost $dropped samples: $(cat "$tmp/out")"
  [ "$(json "d['record']['cam_rows']")" = "[40, 40]" ] || fail "cam rows: $(json "d['record']")"
  node "$src/tests/cli/mcap_reference.cjs" "$src/tools/node" "$tmp/run.mcap" /cam0=40 /cam1=40 \
    /imu0=$imu /pose=$tracked /tf=$tracked /map=1 /walls=1 >"$tmp/ref" ||
    fail "the reference reader refused the run's recording"
  run track "$tmp/run.mcap" --lockstep --out "$tmp/a.tum"; expect_rc 0
  run track "$rec" --lockstep --out "$tmp/b.tum"; expect_rc 0
  cmp "$tmp/a.tum" "$tmp/b.tum" || fail "the recorded run tracks differently from its recording"
  run run --board "$src/board/sim.yaml" --record "$tmp/run.mcap" --no-view --out "$tmp/o"
  expect_rc 2; one_err_line; expect_err "run.mcap"  # it exists: never overwritten
  run run --board "$src/board/sim.yaml" --record "$tmp/folder" --no-view --out "$tmp/o"
  expect_rc 2; one_err_line; expect_err "is not an .mcap file"
  # Rotating: 1 MiB segments under a 3 MiB cap; the outputs in the last segment kept.
  run run --board "$src/board/sim.yaml" --record "$tmp/segs" --record-segment-mb 1 \
    --record-max-mb 3 --no-view --json --out "$tmp/o"; expect_rc 0
  [ "$(json "d['record']['rotation']['segments_deleted'] >= 1")" = True ] || fail "rotation: $(json "d['record']")"
  last=$(ls "$tmp"/segs/*.mcap | tail -1)
  node "$src/tests/cli/mcap_reference.cjs" "$src/tools/node" "$last" /pose=$tracked /map=1 /walls=1 \
    >/dev/null || fail "the outputs are not in the last segment"
  ;;
run_signals)
  # SIGUSR1 prints the stats table while running; SIGINT stops cleanly with exit code 130.
  # Started directly (not through the wallar function) so $! is the process itself.
  ${WALLAR_EMULATOR:-} "$bin" run --board "$src/board/sim.yaml" --out "$tmp/o" --no-view --loop 0 \
    >"$tmp/out" 2>"$tmp/err" &
  pid=$!
  for _ in $(seq 1 100); do grep -q "board sim" "$tmp/err" && break; sleep 0.1; done
  sleep 1.5
  kill -USR1 $pid; sleep 1
  kill -INT $pid; wait $pid; echo $? >"$tmp/rc"
  expect_rc 130
  expect_err "thread       policy"; expect_err "tracking"
  expect_out "wall model"
  # SIGTERM is the service manager's stop: exit 0, and the board's replay.loop (0 here: until
  # stopped) kept it playing until then.
  sed 's/^  skip: 0$/  skip: 0\n  loop: 0/; s|recording: \.\./|recording: '"$src"'/|' \
    "$src/board/sim.yaml" >"$tmp/loop.yaml"
  grep -q '^  loop: 0$' "$tmp/loop.yaml" || fail "could not write the looping board"
  ${WALLAR_EMULATOR:-} "$bin" run --board "$tmp/loop.yaml" --out "$tmp/o2" --no-view \
    >"$tmp/out" 2>"$tmp/err" &
  pid=$!
  for _ in $(seq 1 100); do grep -q "board sim" "$tmp/err" && break; sleep 0.1; done
  sleep 3  # past the 2 s recording's end: a single play would have ended by now
  kill -0 $pid 2>/dev/null || fail "the looping board stopped by itself"
  kill -TERM $pid; wait $pid; echo $? >"$tmp/rc"
  expect_rc 0
  expect_out "wall model"
  # A stop while the tracking thread hangs (the test fault): the process does not wait for it
  # (a service manager would SIGKILL it after its stop timeout): exit 1 within seconds, saying
  # why.
  ${WALLAR_EMULATOR:-} "$bin" run --board "$tmp/loop.yaml" --out "$tmp/o3" --no-view \
    --fault tracking-hang@0.5+600 >"$tmp/out" 2>"$tmp/err" &
  pid=$!
  for _ in $(seq 1 600); do grep -q "tracking thread stalled" "$tmp/err" && break; sleep 0.1; done
  grep -q "tracking thread stalled" "$tmp/err" || fail "no stall reported: $(cat "$tmp/err")"
  t0_ms=$(date +%s%3N)
  kill -TERM $pid; wait $pid; echo $? >"$tmp/rc"
  stop_ms=$(($(date +%s%3N) - t0_ms))
  expect_rc 1
  expect_err "the tracking thread is hung (no heartbeat for 4 s) and did not stop"
  [ "$stop_ms" -lt 10000 ] || fail "the stop of a hung appliance took $stop_ms ms"
  ;;
walls)
  pcd="$src/tests/data/pcl/sac_plane_test.pcd"
  run walls "$pcd" --method msac --threshold 0.03 --max-walls 1 --json -; expect_rc 0
  [ "$(json "d['points']")" = 3283 ] || fail "points"
  [ "$(json "d['surfaces'][0]['inliers'] > 2000")" = True ] || fail "inliers"
  [ "$(json "abs(-d['surfaces'][0]['normal'][0] / d['surfaces'][0]['d'] + 0.8964) < 0.1")" = True ] || fail "coefficients"
  # A box room as CSV (y down, camera at the origin): 4 walls, floor and ceiling.
  python3 - "$tmp/room.csv" <<'PY'
import random, sys
random.seed(5)
with open(sys.argv[1], 'w') as f:
    f.write('x,y,z\n')
    u = random.uniform
    for _ in range(150):
        f.write(f'{u(-3,3)},{u(-1.2,1.6)},{2.5+u(-.01,.01)}\n'); f.write(f'{u(-3,3)},{u(-1.2,1.6)},{-2.5+u(-.01,.01)}\n')
        f.write(f'{3+u(-.01,.01)},{u(-1.2,1.6)},{u(-2.5,2.5)}\n'); f.write(f'{-3+u(-.01,.01)},{u(-1.2,1.6)},{u(-2.5,2.5)}\n')
        f.write(f'{u(-3,3)},{1.6+u(-.01,.01)},{u(-2.5,2.5)}\n'); f.write(f'{u(-3,3)},{-1.2+u(-.01,.01)},{u(-2.5,2.5)}\n')
    f.write('nan,0,1\n')
PY
  run walls "$tmp/room.csv" --gravity 0,9.81,0 --threshold 0.04 --manhattan --json "$tmp/room.json" --ply "$tmp/room.ply"
  expect_rc 0; expect_out "floor"; expect_out "ceiling"; expect_out "1 non-finite skipped"
  python3 - "$tmp/room.json" <<'PY' || fail "room json"
import json, sys
d = json.load(open(sys.argv[1]))
kinds = sorted(s['kind'] for s in d['surfaces'])
assert kinds == ['ceiling', 'floor', 'wall', 'wall', 'wall', 'wall'], kinds
assert sorted(s['id'] for s in d['surfaces']) == [1, 2, 3, 4, 5, 6]
for s in d['surfaces']:
    assert s['d'] < 0, s  # n toward the viewpoint at the origin: n.0 - d > 0
    assert len(s['extent']) >= 3
floor = [s for s in d['surfaces'] if s['kind'] == 'floor'][0]
assert floor['normal'][1] < -0.99, floor  # floor's front is up (-y)
# Where the time went: one search per surface found, each timed, then the one that ends it.
st = d['stages']
found = [x for x in st['searches'] if x['outcome'] in ('surface', 'merged')]
assert len(found) >= 6 and all(x['ms'] > 0 and x['rounds'] > 0 for x in found), st
assert st['searches'][-1]['outcome'] in ('too small', 'none', 'not a surface') or len(st['searches']) == 6, st
assert sum(x['ms'] + x.get('horizontal_ms', 0) for x in st['searches']) <= d['time_ms'], st
PY
  expect_out "time: search 1 "
  head -c 200 "$tmp/room.ply" | grep -q "element vertex 900" || fail "ply header"
  # Scattered points are not a surface: 1,400 uniform in a box, one 4 x 3 m wall of 120 behind
  # them. By the contrast score the wall is reported alone; by BSF (the default), slabs of the
  # scatter are reported as walls too, unless the band test (--surface-sigma 4) rejects them.
  python3 - "$tmp/scatter.csv" <<'PY'
import random, sys
random.seed(7)
u = random.uniform
with open(sys.argv[1], 'w') as f:
    for _ in range(120): f.write(f'{u(-2,2)},{u(-1.5,1.5)},{3+u(-.01,.01)}\n')
    for _ in range(1400): f.write(f'{u(-2,2)},{u(-1.5,1.5)},{u(0.5,2.95)}\n')
PY
  run walls "$tmp/scatter.csv" --method contrast --json -; expect_rc 0
  [ "$(json "len(d['surfaces']), round(d['surfaces'][0]['d'], 1), d['stages']['searches'][-1]['outcome']")" = "1 -3.0 too small" ] || fail "scatter: $(json "[(s['d'], s['inliers']) for s in d['surfaces']]")"
  run walls "$tmp/scatter.csv" --surface-sigma 4 --json -; expect_rc 0
  [ "$(json "len(d['surfaces']), d['stages']['searches'][-1]['outcome']")" = "1 not a surface" ] || fail "scatter by BSF with the band test: $(json "[(s['d'], s['inliers']) for s in d['surfaces']]")"
  run walls "$tmp/scatter.csv" --json -; expect_rc 0
  [ "$(json "len(d['surfaces']) > 2")" = True ] || fail "scatter by BSF without the band test: $(json "len(d['surfaces'])")"
  ;;
walls_bad_input)
  : >"$tmp/empty.ply"
  run walls "$tmp/empty.ply"; expect_rc 2; one_err_line; expect_err "empty.ply"
  printf 'x,y,z\n1,2,3\n4,5,6\n' >"$tmp/two.csv"
  run walls "$tmp/two.csv"; expect_rc 2; one_err_line; expect_err "needs at least 3 valid points, has 2"
  head -c 3000 "$src/tests/data/pcl/sac_plane_test.pcd" >"$tmp/cut.pcd"
  run walls "$tmp/cut.pcd"; expect_rc 2; one_err_line; expect_err "cut.pcd"
  run walls "$src/tests/data/pcl/sac_plane_test.pcd" --gravity 0,0,0; expect_rc 2; one_err_line
  expect_err "--gravity"
  run walls "$src/tests/data/pcl/sac_plane_test.pcd" --method magic; expect_rc 2
  printf 'ply\nformat ascii 1.0\nelement vertex 1\nproperty list uchar int x\nend_header\n' >"$tmp/list.ply"
  run walls "$tmp/list.ply"; expect_rc 2; one_err_line; expect_err "list.ply"
  ;;
eval_sweep)
  # The generator, read back by `wallar walls` (labels are an extra PLY property).
  run eval synth --out "$tmp/scene.ply" --rho-b 0.2 --seed 3 --json; expect_rc 0
  [ "$(json "d['labels']['wall'], d['labels']['front_plane'], d['labels']['backlier']")" = "100 150 25" ] \
    || fail "synth counts: $(cat "$tmp/out")"
  run walls "$tmp/scene.ply" --threshold 0.1; expect_rc 0
  head -2 "$tmp/out" | grep -qE "wall +id 1: n = \([+-]0\.0[0-9]+, [+-]0\.0[0-9]+, -1\.0000\), d = -(1\.99|2\.00)" || fail "wall not first: $(cat "$tmp/out")"
  run eval synth --out "$tmp/scene.csv" --rho-b 0.2; expect_rc 0
  [ "$(wc -l <"$tmp/scene.csv")" = 376 ] || fail "csv rows"   # header + 100 + 150 + 25 + 100
  # A small fig. 4.2 sweep: RANSAC-like beta 0 fails, 0.5 succeeds.
  run eval sweep bsf --out "$tmp/sw" --seeds 1-2 --beta 0,0.5 --rho-b 0.3 --no-plots --json
  expect_rc 0
  [ "$(json "d['trials']")" = 4 ] || fail "trials"
  grep -q '^0,0.3,0,2,0,' "$tmp/sw/bsf.csv" || fail "beta 0 should fail: $(cat "$tmp/sw/bsf.csv")"
  grep -q '^0.5,0.3,2,2,1,' "$tmp/sw/bsf.csv" || fail "beta 0.5 should succeed"
  for f in bsf.csv bsf.gp bsf.json; do [ -s "$tmp/sw/$f" ] || fail "no $f"; done
  if command -v gnuplot >/dev/null; then
    run eval sweep methods --out "$tmp/m" --seeds 1 --rho-b 0.2 --methods ransac,bsf; expect_rc 0
    head -c 8 "$tmp/m/methods.png" | od -c | grep -q 'P   N   G' || fail "methods.png is not a PNG"
  fi
  ;;
eval_bad_input)
  # Every bad argument is found before anything is written: no folder, no partial file.
  run eval sweep bsf --out "$tmp/a" --beta 1:0:0.1; expect_rc 2; one_err_line; expect_err "--beta: empty range"
  run eval sweep methods --out "$tmp/a" --methods ransac,magic; expect_rc 2; one_err_line
  expect_err "unknown method 'magic'"
  run eval sweep bsf --out "$tmp/a" --seeds 1,two; expect_rc 2; one_err_line
  expect_err "--seeds: 'two' is not an unsigned integer"
  run eval sweep bsf --out "$tmp/a" --threshold-m 0.1; expect_rc 2; one_err_line
  expect_err "does not apply to sweep 'bsf'"
  run eval sweep nosuch --out "$tmp/a"; expect_rc 2; one_err_line; expect_err "unknown sweep"
  [ -e "$tmp/a" ] && fail "a rejected sweep left $tmp/a behind"
  run eval synth --out "$tmp/scene.xyz"; expect_rc 2; one_err_line; expect_err "want .ply or .csv"
  [ -e "$tmp/scene.xyz" ] && fail "a rejected synth left a file"
  run eval all --recording "$tmp/none" --out "$tmp/a"; expect_rc 2
  [ -e "$tmp/a" ] && fail "a rejected eval all left $tmp/a behind"
  ;;
eval_real)
  # The room of the bundled EuRoC cut in the appliance's map (the default: lock step over the
  # whole recording), its figure, table and summary.
  run eval real --recording "$rec" --out "$tmp/ap" --json; expect_rc 0
  for f in real_overlay.png real_map.csv real_summary.json; do
    [ -s "$tmp/ap/$f" ] || fail "no $f (appliance map)"
  done
  python3 - "$tmp/ap" "$tmp/out" <<'PY' || fail "eval real outputs (appliance map)"
import json, sys
ev, out = sys.argv[1], sys.argv[2]
d = json.load(open(out))
assert d == json.load(open(f'{ev}/real_summary.json')), 'stdout and real_summary.json differ'
assert d['map_source'] == 'appliance' and d['pairs_requested'] is None, d
assert d['pairs_used'] == 40 and d['points'] > 150, (d['pairs_used'], d['points'])
floors = [s for s in d['surfaces'] if s['kind'] == 'floor']
assert len(floors) == 1, d['surfaces']
f = d['floor']
assert 0.5 < f['distance_below_camera_m'] < 1.5, f
assert f['free_fit_vs_ground_truth_gravity_deg'] < 2.0, f
rows = open(f'{ev}/real_map.csv').read().splitlines()
assert len(rows) == d['points'] + 1, (len(rows), d['points'])
PY
  # The study's own sparse map from ORB matches of 8 stereo pairs (--map-source orb).
  run eval real --recording "$rec" --out "$tmp/ev" --map-source orb --json; expect_rc 0
  for f in real_overlay.png real_map.csv real_summary.json; do
    [ -s "$tmp/ev/$f" ] || fail "no $f"
  done
  ls "$tmp/ev" | grep -q '\.part$' && fail "a .part file was left behind"
  python3 - "$tmp/ev" "$tmp/out" <<'PY' || fail "eval real outputs"
import json, struct, sys, zlib
ev, out = sys.argv[1], sys.argv[2]
d = json.load(open(out))
assert d == json.load(open(f'{ev}/real_summary.json')), 'stdout and real_summary.json differ'
assert d['map_source'] == 'orb', d['map_source']
assert d['ground_truth'] is True and d['pairs_used'] == 8, d
assert d['points'] > 2000, d['points']
floors = [s for s in d['surfaces'] if s['kind'] == 'floor']
assert len(floors) == 1, d['surfaces']
f = d['floor']
assert f is not None, 'no floor'
assert 0.5 < f['distance_below_camera_m'] < 1.5, f
assert f['free_fit_vs_ground_truth_gravity_deg'] < 2.0, f
assert f['free_fit_vs_imu_gravity_deg'] < 2.0, f
assert d['imu_gravity_vs_ground_truth_deg'] < 1.0, d['imu_gravity_vs_ground_truth_deg']
# The table: one row per map point, labelled with the summary's surface names.
rows = open(f'{ev}/real_map.csv').read().splitlines()
assert rows[0] == 'x,y,z,surface', rows[0]
labels = [r.split(',')[3] for r in rows[1:]]
assert len(labels) == d['points'], (len(labels), d['points'])
names = {s['name']: s['map_points'] for s in d['surfaces']}
assert set(labels) <= set(names) | {'none'}, set(labels)
for name, n in names.items():
    assert labels.count(name) == n, (name, labels.count(name), n)
# The figure: an RGB PNG the size of the camera image, with floor-coloured points drawn on it.
png = open(f'{ev}/real_overlay.png', 'rb').read()
assert png[:8] == b'\x89PNG\r\n\x1a\n', 'not a PNG'
w, h, depth, kind = struct.unpack('>IIBB', png[16:26])
assert (w, h, depth, kind) == (752, 480, 8, 2), (w, h, depth, kind)
pos, idat = 8, b''
while pos < len(png):
    n, tag = struct.unpack('>I4s', png[pos:pos + 8])
    if tag == b'IDAT': idat += png[pos + 8:pos + 8 + n]
    pos += 12 + n
raw, stride, prev, red = zlib.decompress(idat), 3 * w, bytearray(3 * w), 0
for y in range(h):
    ft, line = raw[y * (stride + 1)], bytearray(raw[y * (stride + 1) + 1:(y + 1) * (stride + 1)])
    for x in range(stride):
        a = line[x - 3] if x >= 3 else 0; b = prev[x]; c = prev[x - 3] if x >= 3 else 0
        if ft == 1: line[x] = (line[x] + a) & 255
        elif ft == 2: line[x] = (line[x] + b) & 255
        elif ft == 3: line[x] = (line[x] + (a + b) // 2) & 255
        elif ft == 4:
            p = a + b - c; pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
            line[x] = (line[x] + (a if pa <= pb and pa <= pc else b if pb <= pc else c)) & 255
    red += sum(1 for x in range(0, stride, 3) if tuple(line[x:x + 3]) == (230, 25, 75))
    prev = line
assert red > 2000, f'{red} floor-coloured pixels'
PY
  run eval real --recording "$rec" --out "$tmp/ev2" --map-source orb --pairs 2; expect_rc 0
  expect_out "from 2 of 40 stereo pairs"; expect_out "deg from ground-truth gravity"
  [ -s "$tmp/ev2/real_summary.json" ] || fail "no real_summary.json with --pairs 2"
  ;;
eval_real_bad_input)
  run eval real --recording "$tmp/nope" --out "$tmp/ev"; expect_rc 2; one_err_line
  expect_err "$tmp/nope: no such recording folder"
  [ -e "$tmp/ev/real_summary.json" ] && fail "real_summary.json left behind (missing recording)"
  run eval real --recording "$rec" --out "$tmp/ev" --map-source orb --pairs 41; expect_rc 2
  one_err_line; expect_err "cam0/data.csv: has 40 stereo pairs, the study asks for 41"
  [ -e "$tmp/ev/real_summary.json" ] && fail "real_summary.json left behind (too few pairs)"
  run eval real --recording "$rec" --out "$tmp/ev" --pairs 4; expect_rc 2; one_err_line
  expect_err "--pairs chooses the stereo pairs of --map-source orb"
  run eval real --recording "$rec" --out "$tmp/ev" --map-source tsdf; expect_rc 2
  run eval real --out "$tmp/ev"; expect_rc 2; expect_err "recording"
  mkdir -p "$tmp/r"; cp -r "$rec/mav0" "$tmp/r/"; chmod -R u+w "$tmp/r"
  first=$(sed -n 2p "$tmp/r/mav0/cam0/data.csv" | cut -d, -f2 | tr -d '\r')
  head -c 100 "$rec/mav0/cam0/data/$first" >"$tmp/r/mav0/cam0/data/$first"
  run eval real --recording "$tmp/r" --out "$tmp/ev"; expect_rc 2; one_err_line
  expect_err "cam0/data/$first"
  [ -e "$tmp/ev/real_summary.json" ] && fail "real_summary.json left behind (corrupt image)"
  ls "$tmp/ev" 2>/dev/null | grep -q . && fail "files left behind: $(ls "$tmp/ev")"
  # Without ground truth the study runs and says so.
  cp "$rec/mav0/cam0/data/$first" "$tmp/r/mav0/cam0/data/$first"
  rm -r "$tmp/r/mav0/state_groundtruth_estimate0"
  run eval real --recording "$tmp/r" --out "$tmp/ev" --map-source orb --pairs 2 --json; expect_rc 0
  [ "$(json "d['ground_truth']")" = False ] || fail "ground truth reported"
  [ "$(json "d['imu_gravity_vs_ground_truth_deg']")" = None ] || fail "IMU vs ground truth"
  [ "$(json "d['floor']['free_fit_vs_ground_truth_gravity_deg']")" = None ] || fail "floor vs truth"
  run eval real --recording "$tmp/r" --out "$tmp/ev" --map-source orb --pairs 2; expect_rc 0
  expect_out "no ground truth in this recording"
  ;;
eval_marker)
  # Render a marker view with the bundled calibration, find it again, check the distance.
  run eval marker --render --recording "$rec" --distance-m 1.2 --angle-deg 30 --out "$tmp/m.png" --seed 3
  if [ "$(rc)" = 1 ] && grep -qF "not in this build" "$tmp/err"; then
    one_err_line; expect_err "ArUco marker support is not in this build (OpenCV contrib is host-only)"
    run eval marker --image "$tmp/m.png" --recording "$rec"; expect_rc 1; one_err_line
    expect_err "not in this build"
    echo "ok [$case_name] (without ArUco)"; exit 0
  fi
  expect_rc 0; expect_out "rendered"; [ -s "$tmp/m.png" ] || fail "no rendered image"
  run eval marker --image "$tmp/m.png" --recording "$rec" --json; expect_rc 0
  [ "$(json "abs(d['distance_m'] - 1.2) < 0.01")" = True ] || fail "distance $(json "d['distance_m']")"
  [ "$(json "d['marker']['id']")" = 0 ] || fail "id"
  [ "$(json "d['plane']['d'] < 0 and abs(-d['plane']['d'] - 1.2 * 0.8660254) < 0.01")" = True ] || fail "plane"
  run eval marker --image "$tmp/m.png" --recording "$rec"; expect_rc 0
  expect_out "plane (camera frame"; expect_out "T_cam_marker"; expect_out "reprojection rms"
  # Another marker, and a real frame without a marker: exit 1, one line.
  run eval marker --image "$tmp/m.png" --recording "$rec" --id 4; expect_rc 1; one_err_line
  expect_err "no ArUco marker 4X4_50 id 4 found"
  run eval marker --image "$rec/mav0/cam0/data/1403715273262142976.png" --recording "$rec"
  expect_rc 1; one_err_line; expect_err "no ArUco marker"
  # Bad input: exit 2, one line.
  run eval marker --image "$tmp/m.png" --recording "$rec" --dictionary 9X9_7; expect_rc 2; one_err_line
  expect_err "unknown ArUco dictionary '9X9_7'"
  run eval marker --image "$tmp/missing.png" --recording "$rec"; expect_rc 2; one_err_line
  expect_err "missing.png"
  run eval marker --image "$tmp/m.png" --recording "$tmp/nowhere"; expect_rc 2; one_err_line
  run eval marker --recording "$rec"; expect_rc 2; one_err_line; expect_err "exactly one of"
  ;;
imu)
  # The bundled still cut: one attitude row per IMU sample, the exact header, ground truth.
  run imu "$rec" --out "$tmp/att.csv" --json; expect_rc 0
  [ "$(head -1 "$tmp/att.csv")" = "t_ns,qw,qx,qy,qz,gx,gy,gz,bgx,bgy,bgz" ] || fail "header"
  [ "$(tail -n +2 "$tmp/att.csv" | wc -l)" = 491 ] || fail "rows: $(wc -l <"$tmp/att.csv")"
  ls "$tmp" | grep -q '\.part$' && fail "a .part file was left behind"
  python3 - "$tmp/att.csv" "$tmp/out" <<'PY' || fail "imu outputs"
import csv, json, math, sys
rows = list(csv.DictReader(open(sys.argv[1])))
d = json.load(open(sys.argv[2]))
assert d['samples'] == 491 and d['valid_rows'] == 491, d
assert d['ground_truth']['tilt_rms_deg'] < 1.0, d['ground_truth']
assert d['ground_truth']['bias_error_final_rad_s'] < 3e-3, d['ground_truth']
last = rows[-1]
g = [float(last[k]) for k in ('gx', 'gy', 'gz')]
assert abs(math.sqrt(sum(x * x for x in g)) - 1) < 1e-6, g
assert g[0] < -0.9, g  # EuRoC's IMU x axis points up: gravity along -x
q = [float(last[k]) for k in ('qw', 'qx', 'qy', 'qz')]
assert abs(math.sqrt(sum(x * x for x in q)) - 1) < 1e-6, q
assert abs(float(last['bgz']) - 0.077) < 3e-3, last
gc = d['final_gravity_dir_cam0']
assert gc[1] > 0.5, gc  # the left camera looks ahead: gravity is image-down (+y)
PY
  run imu "$rec"; expect_rc 0; expect_out "491 samples"; expect_out "tilt RMS"
  run imu --help; expect_rc 0; expect_out "--out"; expect_out "--json"
  ;;
imu_only)
  # A recording with only mav0/imu0: the still cut's IMU alone, then the real 145 s flight.
  mkdir -p "$tmp/r/mav0"; cp -r "$rec/mav0/imu0" "$tmp/r/mav0/"
  run imu "$tmp/r" --out "$tmp/att.csv" --json; expect_rc 0
  [ "$(json "d['valid_rows']")" = 491 ] || fail "valid rows"
  [ "$(json "'ground_truth' in d")" = False ] || fail "ground truth without any"
  run imu "$src/tests/data/euroc_v1_01_imu" --json; expect_rc 0
  [ "$(json "d['samples']")" = 29120 ] || fail "samples"
  python3 -c "import json,sys; g=json.load(open('$tmp/out'))['ground_truth']; sys.exit(0 if g['tilt_rms_deg'] < 1.0 and g['bias_error_final_rad_s'] < 2e-3 else 1)" || fail "flight accuracy: $(cat "$tmp/out")"
  ;;
imu_bad_input)
  run imu "$tmp/nowhere" --out "$tmp/att.csv"; expect_rc 2; one_err_line
  expect_err "nowhere: no such recording folder"
  mkdir -p "$tmp/r/mav0"; cp -r "$rec/mav0/imu0" "$tmp/r/mav0/"; chmod -R u+w "$tmp/r"
  sed -i '9s/.*/1403715273462142976,0.1,0.2,0.3,0.4,bad,0.6/' "$tmp/r/mav0/imu0/data.csv"
  run imu "$tmp/r" --out "$tmp/att.csv"; expect_rc 2; one_err_line
  expect_err "imu0/data.csv:9: a_y (column 6) must be a finite number, got 'bad'"
  [ -e "$tmp/att.csv" ] && fail "a failed run left an output file"
  ls "$tmp" | grep -q '\.part$' && fail "a .part file was left behind"
  mkdir -p "$tmp/e/mav0/cam0"
  run imu "$tmp/e"; expect_rc 2; one_err_line; expect_err "imu0: missing folder"
  ;;
imu_live)
  # The live path on a machine without the board's hardware: the start-up check names each
  # missing IMU device with its board key, one line each (nothing of the cameras'), exit 1.
  run imu --board "$src/board/rpi5.yaml" --seconds 1 --out "$tmp/att.csv"; expect_rc 1
  expect_err "rpi5.yaml: imu.bus: /dev/i2c-1: no such device"
  expect_err "rpi5.yaml: imu.data_ready.chip: GPIO chip 'pinctrl-rp1'"
  expect_err "rpi5.yaml: imu.bus_recovery.sda.chip: GPIO chip 'pinctrl-rp1'"
  [ "$(wc -l <"$tmp/err")" = 4 ] || fail "not one line per missing device: $(cat "$tmp/err")"
  grep -q "cameras\|calibration" "$tmp/err" && fail "the IMU check named more: $(cat "$tmp/err")"
  [ -e "$tmp/att.csv" ] && fail "a failed live run left an output file"
  run imu --board "$src/board/sim.yaml"; expect_rc 2; one_err_line
  expect_err "the board names no IMU"
  run imu "$rec" --board "$src/board/rpi5.yaml"; expect_rc 2; one_err_line
  expect_err "give either a RECORDING or --board FILE"
  run imu --board "$src/board/rpi5.yaml" --seconds 0; expect_rc 2; one_err_line
  expect_err "--seconds: must be in (0, 86400]"
  ;;
record_live)
  # Live recording on a machine without the board's cameras: the device is named, exit 1, and
  # no recording folder is created.
  sed -e '/^calibration:/d' -e '/^  trigger:/,/^    line: 23/d' "$src/board/rpi5.yaml" \
    | sed -e '/^imu:/,/^display:/{/^display:/!d}' -e 's/^display:/imu:\n  driver: none\ndisplay:/' \
    > "$tmp/live.yaml"
  run record --board "$tmp/live.yaml" --out "$tmp/rec" --duration-s 1; expect_rc 1
  expect_err "live.yaml: cameras.left.device: /dev/v4l/by-path/platform-xhci-hcd.1-usb-0:1:1.0-video-index0: no such device"
  expect_err "live.yaml: cameras.right.device: /dev/v4l/by-path/platform-xhci-hcd.0-usb-0:1:1.0-video-index0: no such device"
  [ "$(wc -l <"$tmp/err")" = 2 ] || fail "not one line per missing camera: $(cat "$tmp/err")"
  [ -e "$tmp/rec" ] && fail "a failed live recording left a folder"
  # The Pi board's calibration file is the first thing missing here (bad input: exit 2).
  run record --board "$src/board/rpi5.yaml" --out "$tmp/rec" --duration-s 1; expect_rc 2
  tail -n 1 "$tmp/err" | grep -qF "calibration: /etc/wallar/calibration/rig.yaml: no such file" \
    || fail "the last line is not the calibration's: $(cat "$tmp/err")"
  [ -e "$tmp/rec" ] && fail "a failed live recording left a folder"
  # A stereo-only calibration on a board with an IMU: refused before any device opens, naming
  # the file and what is missing (it would put gravity in cam0's axes), exit 2; each other
  # problem (here every device of the Pi is missing) is one more line that names its key.
  cat >"$tmp/cal.yaml" <<'YAML'
cam0: {intrinsics: [450, 450, 320, 240], distortion_coeffs: [0, 0, 0, 0], resolution: [640, 480]}
cam1:
  intrinsics: [450, 450, 320, 240]
  distortion_coeffs: [0, 0, 0, 0]
  resolution: [640, 480]
  T_cn_cnm1: [[1, 0, 0, -0.11], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]
YAML
  sed -e "s#^calibration:.*#calibration: $tmp/cal.yaml#" "$src/board/rpi5.yaml" >"$tmp/cal_board.yaml"
  run run --board "$tmp/cal_board.yaml" --out "$tmp/o" --no-rt; expect_rc 2
  tail -n 1 "$tmp/err" | grep -qF "cal.yaml: no camera-IMU transform (cam0.T_cam_imu) for the board's icm20948" \
    || fail "the last line is not the calibration's: $(cat "$tmp/err")"
  expect_err "cal_board.yaml: cameras.left.device: /dev/v4l/by-path/platform-xhci-hcd.1-usb-0:1:1.0-video-index0: no such device"
  expect_err "cal_board.yaml: imu.data_ready.chip: GPIO chip 'pinctrl-rp1'"
  grep -vE "^wallar: (error: )?$tmp/cal_board.yaml: (cameras|imu|display|input|calibration)[.:]" "$tmp/err" \
    | grep -q . && fail "a line without its board key: $(cat "$tmp/err")"
  # Accepted once the file says the IMU is aligned with cam0: the first missing device, exit 1.
  sed -i '1i imu_aligned_with_cam0: true' "$tmp/cal.yaml"
  run run --board "$tmp/cal_board.yaml" --out "$tmp/o" --no-rt; expect_rc 1
  tail -n 1 "$tmp/err" | grep -qF "cameras.left.device: /dev/v4l/by-path/platform-xhci-hcd.1-usb-0:1:1.0-video-index0: no such device" \
    || fail "the last line is not the first missing device: $(cat "$tmp/err")"
  # --check finds the same without starting; a camera mode that is not the calibration's is the
  # board file's fault: exit 2, the key named.
  run run --board "$tmp/cal_board.yaml" --check; expect_rc 1; expect_out "cameras.left mode"
  expect_err "cameras.right.device: /dev/v4l/by-path/platform-xhci-hcd.0-usb-0:1:1.0-video-index0: no such device"
  sed -i 's/resolution: \[640, 480\]/resolution: [752, 480]/' "$tmp/cal.yaml"
  run run --board "$tmp/cal_board.yaml" --check; expect_rc 2
  expect_err "cal_board.yaml: cameras.left.width/height: 640x480 but $tmp/cal.yaml calibrates cam0 at 752x480"
  ;;
calibrate_stereo)
  # OpenCV's 13 real chessboard pairs: the issue's targets, and every output file readable.
  cal="$src/tests/data/opencv_stereo_calib"
  run calibrate stereo --left "$cal/left*.jpg" --right "$cal/right*.jpg" --board-size 9x6 \
    --square-m 0.025 --out "$tmp/stereo.yaml" --kalibr "$tmp/camchain.yaml" --json "$tmp/cal.json"
  expect_rc 0; expect_out "pairs used"
  cp "$tmp/cal.json" "$tmp/out"
  [ "$(json "sorted(k for k in ['rms_px','views_used','left','right','baseline_m'] if k in d)")" \
    = "['baseline_m', 'left', 'right', 'rms_px', 'views_used']" ] || fail "summary keys"
  [ "$(json "d['rms_px'] < 0.5")" = True ] || fail "rms $(json "d['rms_px']")"
  [ "$(json "all(abs(d[s][f] / 535.9 - 1) < 0.02 for s in ('left','right') for f in ('fx','fy'))")" \
    = True ] || fail "focal lengths"
  [ "$(json "len(d['left']['dist'])")" = 4 ] || fail "distortion"
  [ "$(json "d['views_used'] >= 11 and d['no_corners'] == []")" = True ] || fail "views"
  [ "$(json "abs(d['baseline_m'] - 0.083) < 0.01")" = True ] || fail "baseline"
  # The files it wrote calibrate a check, both formats (the check itself: rectify_check).
  printf '# one pair\n%s %s\n' "$cal/left05.jpg" "$cal/right05.jpg" > "$tmp/pairs.txt"
  run calibrate rectify-check --calibration "$tmp/stereo.yaml" --list "$tmp/pairs.txt" --json
  expect_rc 0; [ "$(json "d['pairs']")" = 1 ] || fail "pairs from the list"
  run calibrate rectify-check --calibration "$tmp/camchain.yaml" --list "$tmp/pairs.txt"
  expect_rc 0; expect_out "1 pairs"
  ;;
calibrate_stereo_bad_input)
  cal="$src/tests/data/opencv_stereo_calib"
  run calibrate stereo --left "$tmp/none*.jpg" --right "$cal/right*.jpg"; expect_rc 2
  one_err_line; expect_err "--left '$tmp/none*.jpg': no file matches"
  run calibrate stereo --left "$cal/left*.jpg" --right "$cal/right0*.jpg"; expect_rc 2
  one_err_line; expect_err "--left matches 13 files but --right 9"
  run calibrate stereo --left "$cal/left*.jpg" --right "$cal/right*.jpg" --board-size 9by6
  expect_rc 2; one_err_line; expect_err "--board-size '9by6': want the inner corners"
  # (two pairs: a failed chessboard search is the slow case, and this runs under qemu too)
  run calibrate stereo --left "$cal/left0[12].jpg" --right "$cal/right0[12].jpg" \
    --board-size 12x12 --out "$tmp/c.yaml" --json "$tmp/c.json"
  expect_rc 2; one_err_line; expect_err "was found in both images of only 0 of 2 pairs"
  [ -e "$tmp/c.yaml" ] || [ -e "$tmp/c.json" ] && fail "a failed calibration left a file"
  printf 'left01.jpg\n' > "$tmp/list.txt"
  run calibrate stereo --list "$tmp/list.txt"; expect_rc 2; one_err_line
  expect_err "list.txt:1: want two image paths, 'LEFT RIGHT'"
  printf 'not a jpeg at all' > "$tmp/bad.jpg"; cp "$tmp/bad.jpg" "$tmp/bad2.jpg"
  run calibrate stereo --left "$tmp/bad.jpg" --right "$tmp/bad2.jpg"; expect_rc 2; one_err_line
  expect_err "bad.jpg: corrupt JPEG"
  run calibrate rectify-check --calibration "$tmp/nope.yaml" --recording "$rec"; expect_rc 2
  one_err_line; expect_err "nope.yaml: no such calibration file or folder"
  run calibrate rectify-check --calibration "$cal/intrinsics.yml" --recording "$rec"; expect_rc 2
  one_err_line; expect_err "intrinsics.yml"
  ;;
rectify_check)
  # EuRoC's own calibration rectifies its pairs to well under half a pixel; a threshold turns
  # the check into a pass/fail for hardware-in-the-loop runs.
  run calibrate rectify-check --recording "$rec" --every 20 --max-mean-px 0.5 --json; expect_rc 0
  [ "$(json "d['pairs'] == 2 and d['matches'] > 500 and d['mean_px'] < 0.5 and d['pass']")" \
    = True ] || fail "$(cat "$tmp/out")"
  run calibrate rectify-check --recording "$rec" --every 40 --max-mean-px 0.01; expect_rc 1
  one_err_line
  expect_err "exceeds --max-mean-px 0.010"
  ;;
calibrate_accel_mag)
  # The headset held still in five tilts and turned round at each (synth-rig's calibration
  # motion), its accelerometer biased and its magnetometer with hard and soft iron drawn from
  # the seed: the bias within 5 mm/s^2 of the truth, the field's heading steady once corrected.
  run eval synth-rig --out "$tmp/cal" --motion calibration --duration 70 --imu-only \
    --magnetometer --seed 2; expect_rc 0
  [ -s "$tmp/cal/mav0/mag0/data.csv" ] || fail "no mag0/data.csv"
  run calibrate accel-mag "$tmp/cal" --out "$tmp/imu.yaml" --json; expect_rc 0
  [ "$(json "d['accelerometer']['bias_error_m_s2'] < 0.005")" = True ] || fail "bias: $(cat "$tmp/out")"
  [ "$(json "d['accelerometer']['tilt_error_deg'] < 0.1 < d['accelerometer']['tilt_error_raw_deg']")" = True ] || fail "tilt"
  [ "$(json "d['magnetometer']['solved'] and d['magnetometer']['heading_spread_deg'] < 2.0 < 20.0 < d['magnetometer']['heading_spread_raw_deg']")" = True ] \
    || fail "magnetometer: $(cat "$tmp/out")"
  python3 - "$tmp/imu.yaml" "$tmp/cal/mav0/state_groundtruth_estimate0/sensor.yaml" <<'PY' || fail "imu.yaml: $(cat "$tmp/imu.yaml")"
import sys
def value(path, key):
    for l in open(path):
        if l.startswith(key + ':'):
            return [float(v) for v in l.split('[')[1].split(']')[0].split(',')]
got, truth = value(sys.argv[1], 'magnetometer_hard_iron'), value(sys.argv[2], 'magnetometer_hard_iron_uT')
assert value(sys.argv[1], 'accelerometer_bias') and len(value(sys.argv[1], 'magnetometer_soft_iron')) == 9
sys.exit(0 if sum((a - b) ** 2 for a, b in zip(got, truth)) ** 0.5 < 0.5 else 1)
PY
  # The attitude filter with the file: the bias and iron applied. As read, the magnetometer's
  # hard iron would be taken for heading; its readings are refused instead (counted).
  run imu "$tmp/cal" --json; expect_rc 0
  raw_tilt=$(json "d['ground_truth']['tilt_rms_deg']")
  [ "$(json "d['mag_rejected'] > 1000 and d['ground_truth']['tilt_rms_deg'] < 1.0")" = True ] || fail "raw: $(cat "$tmp/out")"
  cp "$tmp/imu.yaml" "$tmp/cal/mav0/imu0/sensor.yaml"
  run imu "$tmp/cal" --json; expect_rc 0
  [ "$(json "d['mag_rejected'] == 0 and d['ground_truth']['tilt_rms_deg'] < 0.5 * $raw_tilt")" = True ] \
    || fail "calibrated: $(cat "$tmp/out") against $raw_tilt"
  # A recording that never tilts: said, and no file written.
  run eval synth-rig --out "$tmp/la" --motion look-around --duration 20 --imu-only; expect_rc 0
  run calibrate accel-mag "$tmp/la" --out "$tmp/la.yaml"; expect_rc 2; one_err_line
  expect_err "1 still poses found: hold the headset still (a second each) in at least four tilts"
  [ ! -e "$tmp/la.yaml" ] || fail "wrote a file from an unsolved fit"
  run calibrate accel-mag "$tmp/nowhere"; expect_rc 2; one_err_line
  ;;
calibrate_imu_noise)
  # Two minutes of a still IMU at 200 Hz generated with known densities (the simulator's
  # discrete forms): the Allan deviation reads them back; the bundled cut is too short.
  mkdir -p "$tmp/still/mav0/imu0"
  still_imu "$tmp/still/mav0/imu0/data.csv" 5 2e-4 2e-4 2e-3 3e-3
  run calibrate imu-noise "$tmp/still" --out "$tmp/imu.yaml" --json; expect_rc 0
  [ "$(json "abs(d['gyroscope_noise_density'] / 2e-4 - 1) < 0.1")" = True ] || fail "gyro density: $(cat "$tmp/out")"
  [ "$(json "abs(d['gyroscope_random_walk'] / 2e-4 - 1) < 0.35")" = True ] || fail "gyro walk: $(cat "$tmp/out")"
  [ "$(json "abs(d['accelerometer_noise_density'] / 2e-3 - 1) < 0.1")" = True ] || fail "accel density"
  grep -q "^gyroscope_noise_density: 0.0002" "$tmp/imu.yaml" || fail "sensor.yaml: $(cat "$tmp/imu.yaml")"
  run calibrate imu-noise "$rec"; expect_rc 2; one_err_line
  expect_err "s of IMU samples: the noise needs at least 60 s at rest"
  # A turn in the middle: refused, not read as noise.
  python3 - "$tmp/still/mav0/imu0/data.csv" <<'PY'
import sys
rows = open(sys.argv[1]).read().splitlines()
for i in range(12000, 12400):
    v = rows[i].split(',')
    v[4], v[6] = '4.0', '6.0'
    rows[i] = ','.join(v)
open(sys.argv[1], 'w').write('\n'.join(rows) + '\n')
PY
  run calibrate imu-noise "$tmp/still"; expect_rc 2; one_err_line; expect_err "the IMU moves"
  ;;
calibrate_flow)
  # The whole flow of docs/boot.md "Calibrating a new headset", each step fed the one before's
  # file: imu-noise (still) -> accel-mag --imu (tilts and turns) -> imu-cam --cameras --imu
  # (the calibration motion facing a room) -> the rig file a live board's calibration: key
  # names. synth-rig renders no chessboard, so the cameras come as `calibrate stereo --kalibr`
  # writes them: the clip's camchain without T_cam_imu (cli.calibrate_stereo covers that step
  # on OpenCV's real chessboards). Natively only, as cli.calibrate_imu_cam.
  [ -n "${WALLAR_EMULATOR:-}" ] && exit 0
  # 1. Two minutes at rest, with the synth-rig IMU's densities (its sensor.yaml).
  run eval synth-rig --out "$tmp/cal" --motion calibration --duration 70 --imu-only \
    --magnetometer --seed 2; expect_rc 0
  mkdir -p "$tmp/still/mav0/imu0"
  # shellcheck disable=SC2046  # the four densities, one word each
  still_imu "$tmp/still/mav0/imu0/data.csv" 3 $(python3 - "$tmp/cal/mav0/imu0/sensor.yaml" <<'PY'
import sys
d = {l.split(':')[0]: l.split(':')[1].split('#')[0].strip() for l in open(sys.argv[1]) if ':' in l}
print(' '.join(d[k] for k in ('gyroscope_noise_density', 'gyroscope_random_walk',
                              'accelerometer_noise_density', 'accelerometer_random_walk')))
PY
)
  run calibrate imu-noise "$tmp/still" --out "$tmp/imu.yaml" --json; expect_rc 0
  gyro_nd=$(json "d['gyroscope_noise_density']"); accel_nd=$(json "d['accelerometer_noise_density']")
  echo "flow: noise densities gyro $gyro_nd (generated 2.6e-4), accelerometer $accel_nd (2.3e-3)"
  [ "$(json "abs(d['gyroscope_noise_density'] / 2.6e-4 - 1) < 0.1 and abs(d['accelerometer_noise_density'] / 2.3e-3 - 1) < 0.1")" = True ] \
    || fail "noise: $(cat "$tmp/out")"
  # 2. Accelerometer bias and magnetometer iron, starting from step 1's file.
  run calibrate accel-mag "$tmp/cal" --imu "$tmp/imu.yaml" --out "$tmp/imu.yaml" --json
  expect_rc 0
  [ "$(json "d['accelerometer']['bias_error_m_s2'] < 0.005 and d['magnetometer']['solved']")" = True ] \
    || fail "accel-mag: $(cat "$tmp/out")"
  echo "flow: accelerometer bias error $(json "d['accelerometer']['bias_error_m_s2']") m/s^2," \
    "heading spread $(json "d['magnetometer']['heading_spread_deg']") deg"
  # 3. The camera-IMU transform and time offset (the IMU clock 8 ms behind), from the cameras
  # without T_cam_imu and step 2's file.
  run eval synth-rig --out "$tmp/la" --motion calibration --duration 20 --time-offset-ms -8 \
    --seed 2 --width 320 --height 240; expect_rc 0
  awk '/^  T_cam_imu:/ {skip = 4; next} skip > 0 {skip--; next} !/timeshift_cam_imu/' \
    "$tmp/la/mav0/camchain-imucam.yaml" >"$tmp/stereo.yaml"
  grep -q "T_cam_imu\|timeshift" "$tmp/stereo.yaml" && fail "stereo.yaml kept the IMU's parts"
  run calibrate imu-cam "$tmp/la" --cameras "$tmp/stereo.yaml" --imu "$tmp/imu.yaml" \
    --out "$tmp/rig.yaml" --json; expect_rc 0
  [ "$(json "d['vs_calibration_deg'] < 0.5 and abs(d['timeshift_cam_imu_ms'] + 8.0) < 1.0")" = True ] \
    || fail "imu-cam: $(cat "$tmp/out")"
  echo "flow: extrinsic $(json "d['vs_calibration_deg']") deg off, time offset" \
    "$(json "d['timeshift_cam_imu_ms']") ms (generated -8)"
  # The rig file holds every step's figures: step 1's noise, step 2's bias and iron (as its
  # file wrote them), T_cam_imu and the offset.
  python3 - "$tmp/rig.yaml" "$tmp/imu.yaml" "$gyro_nd" "$accel_nd" <<'PY' || fail "rig.yaml: $(cat "$tmp/rig.yaml")"
import sys
rig, imu = open(sys.argv[1]).read(), open(sys.argv[2]).read()
def values(text, key):
    for l in text.splitlines():
        if l.strip().startswith(key + ':'):
            v = l.split(':', 1)[1].split('#')[0].strip().strip('[]')
            return [float(x) for x in v.split(',')]
    sys.exit('no ' + key)
assert abs(values(rig, 'gyroscope_noise_density')[0] / float(sys.argv[3]) - 1) < 1e-6
assert abs(values(rig, 'accelerometer_noise_density')[0] / float(sys.argv[4]) - 1) < 1e-6
for key in ('accelerometer_bias', 'magnetometer_hard_iron', 'magnetometer_soft_iron'):
    got, want = values(rig, key), values(imu, key)
    assert len(got) == len(want) and max(abs(a - b) for a, b in zip(got, want)) < 1e-9, key
assert rig.count('T_cam_imu') == 2 and rig.count('timeshift_cam_imu') == 2
PY
  # 4. A live board whose calibration: key names the rig file: its calibration checks pass
  # (camera mode, rate, T_cam_imu), and only the absent devices are problems.
  sed -e "s#^calibration:.*#calibration: $tmp/rig.yaml#" -e 's/^    width: 640/    width: 320/' \
    -e 's/^    height: 480/    height: 240/' -e 's/^    fps: 30/    fps: 20/' \
    "$src/board/rpi5.yaml" >"$tmp/board.yaml"
  run run --board "$tmp/board.yaml" --check; expect_rc 1
  expect_out "calibration"
  grep -v ": no such device\|GPIO chip\|by-path" "$tmp/err" | grep -q . \
    && fail "problems beyond the absent devices: $(cat "$tmp/err")"
  # And as a board without T_cam_imu would be: refused, naming what is missing.
  sed -e "s#^calibration:.*#calibration: $tmp/stereo.yaml#" "$tmp/board.yaml" >"$tmp/board2.yaml"
  run run --board "$tmp/board2.yaml" --check; expect_rc 2
  expect_err "T_cam_imu"
  ;;
calibrate_imu_cam)
  # The bundled cut stands still: the rotation cannot be determined, and the command says why.
  run calibrate imu-cam "$rec"; expect_rc 2; one_err_line
  expect_err "only 0 frame pairs turn more than 1.0 deg"
  run calibrate imu-cam --help; expect_rc 0; expect_out "--min-rotation"
  run calibrate imu-cam "$tmp/nowhere"; expect_rc 2; one_err_line
  expect_err "no such recording folder"
  # The calibration motion (held in tilts, turned round in quarter turns with sharp starts and
  # stops) with its IMU clock 8 ms behind: the rotation within 0.5 deg of the truth and the
  # offset within 1 ms (docs/results.md has more seeds), written as the rig file a board's
  # calibration: key reads. Natively only: under qemu the clip, its tracking and the search
  # take minutes, and the arithmetic is the same.
  [ -n "${WALLAR_EMULATOR:-}" ] && exit 0
  run eval synth-rig --out "$tmp/la" --motion calibration --duration 20 --time-offset-ms -8 \
    --seed 2 --width 320 --height 240; expect_rc 0
  # The IMU's noise as `calibrate imu-noise --out` writes it (here: the clip's sensor.yaml with
  # other densities) goes into the rig file with the transform and the offset.
  sed 's/^gyroscope_noise_density:.*/gyroscope_noise_density: 1.5e-04/; s/^accelerometer_noise_density:.*/accelerometer_noise_density: 2.5e-03/' \
    "$tmp/la/mav0/imu0/sensor.yaml" >"$tmp/imu.yaml"
  grep -q '^gyroscope_noise_density: 1.5e-04' "$tmp/imu.yaml" || fail "could not write imu.yaml"
  run calibrate imu-cam "$tmp/la" --imu "$tmp/nowhere.yaml" --out "$tmp/rig.yaml"
  expect_rc 2; one_err_line; expect_err "nowhere.yaml"  # said before the tracking
  run calibrate imu-cam "$tmp/la" --imu "$tmp/imu.yaml" --out "$tmp/rig.yaml" --json; expect_rc 0
  [ "$(json "d['camera_rotations']")" = tracked ] || fail "rotations from the tracker"
  [ "$(json "d['vs_calibration_deg'] < 0.5")" = True ] || fail "extrinsic: $(cat "$tmp/out")"
  [ "$(json "abs(d['timeshift_cam_imu_ms'] + 8.0) < 1.0")" = True ] || fail "offset: $(cat "$tmp/out")"
  python3 - "$tmp/rig.yaml" <<'PY' || fail "rig file"
import sys
t = open(sys.argv[1]).read()
shift = [float(l.split(':')[1]) for l in t.splitlines() if l.strip().startswith('timeshift_cam_imu')]
def value(key):
    return [float(l.split(':')[1].split('#')[0]) for l in t.splitlines() if l.strip().startswith(key + ':')]
noise = value('gyroscope_noise_density') == [1.5e-4] and value('accelerometer_noise_density') == [2.5e-3]
sys.exit(0 if 'T_cam_imu' in t and len(shift) == 2 and abs(shift[0] + 0.008) < 0.001 and noise else 1)
PY
  # The cameras from `calibrate stereo`'s file (here: this rig file with cam0's principal point
  # moved by half a pixel) in place of the recording's: tracked with them, written with them.
  python3 - "$tmp/rig.yaml" "$tmp/cams.yaml" "$tmp/cams_vga.yaml" <<'PY' || fail "cams.yaml"
import sys
t = open(sys.argv[1]).read().split('\n')
i = next(k for k, l in enumerate(t) if l.strip().startswith('intrinsics:'))
fu, fv, pu, pv = (float(v) for v in t[i].split('[')[1].rstrip(']').split(','))
t[i] = f'  intrinsics: [{fu}, {fv}, {pu + 0.5}, {pv}]'
open(sys.argv[2], 'w').write('\n'.join(t))
open(sys.argv[3], 'w').write('\n'.join(t).replace('resolution: [320, 240]', 'resolution: [640, 480]'))
PY
  run calibrate imu-cam "$tmp/la" --cameras "$tmp/cams_vga.yaml" --out "$tmp/rig2.yaml"
  expect_rc 2; one_err_line; expect_err "--cameras: cam0 is 640x480 but the recording's images are 320x240"
  run calibrate imu-cam "$tmp/la" --cameras "$tmp/cams.yaml" --out "$tmp/rig2.yaml" --json
  expect_rc 0
  [ "$(json "d['vs_calibration_deg'] < 0.5")" = True ] || fail "extrinsic with --cameras: $(cat "$tmp/out")"
  grep -q 'intrinsics: \[225, 225, 160, 119.5\]' "$tmp/rig2.yaml" || fail "cameras not taken: $(head -12 "$tmp/rig2.yaml")"
  # (A live board's calibration: key reads this file; CalibrationFiles.* read it back.)
  run track "$tmp/la" --lockstep --json; expect_rc 0
  ;;
track)
  run track "$rec" --out "$tmp/traj.txt" --map "$tmp/map.ply" --walls "$tmp/walls.json" --eval \
      --gravity-aligned --json
  expect_rc 0
  [ "$(json "d['frames']")" = 40 ] || fail "frames"
  [ "$(json "d['tracking_frames']")" = 40 ] || fail "tracking frames"
  [ "$(json "d['imu'], d['mode'], d['mapping']")" = "True every frame thread" ] || fail "mode: $(cat "$tmp/out")"
  [ "$(json "d['events'], d['degraded']['camera_lost'] + d['degraded']['imu_lost']")" = "[] 0" ] || fail "degraded"
  python3 -c "import json,sys; d=json.load(open('$tmp/out')); s=d['stage_time']; sys.exit(0 if d['frame_time']['p50_ms'] > 0 and s['stage1_track']['p50_ms'] > 0 and s['rectify']['max_ms'] > 0 else 1)" || fail "stage times: $(cat "$tmp/out")"
  python3 -c "import json,sys; d=json.load(open('$tmp/out')); sys.exit(0 if d['drift_m'] < 0.01 and d['drift_deg'] < 0.5 and d['floor']['free_fit_vs_ground_truth_gravity_deg'] < 2.0 else 1)" || fail "accuracy: $(cat "$tmp/out")"
  # TUM: t x y z qx qy qz qw, one line per frame, the first pose the world's origin.
  [ "$(grep -vc '^#' "$tmp/traj.txt")" = 40 ] || fail "trajectory lines"
  awk '!/^#/ { if (NF != 8) exit 1 }' "$tmp/traj.txt" || fail "trajectory fields"
  # The map reads back, with its observation counts, and holds the floor 0.93 m down.
  run walls "$tmp/map.ply" --gravity 0,0,-1 --json -; expect_rc 0
  python3 -c "import json,sys; d=json.load(open('$tmp/out')); f=[w for w in d['surfaces'] if w['kind']=='floor']; sys.exit(0 if f and abs(f[0]['d'] + 0.93) < 0.1 else 1)" || fail "floor in the map: $(cat "$tmp/out")"
  # The reconstruction's final surfaces (the wallar walls schema, the same world): a floor
  # 0.93 m below the first body pose facing up, and they read back as a wall model.
  python3 - "$tmp/walls.json" <<'PY' || fail "walls.json: $(cat "$tmp/walls.json")"
import json, sys
d = json.load(open(sys.argv[1]))
assert d['mode'].startswith('2-D') and 'z is up' in d['frame'], (d['mode'], d['frame'])
floors = [s for s in d['surfaces'] if s['kind'] == 'floor']
assert len(floors) == 1, d['surfaces']
f = floors[0]
assert f['normal'][2] > 0.99 and abs(f['d'] + 0.93) < 0.1 and f['inliers'] > 100, f
for s in d['surfaces']:
    assert len(s['extent']) >= 3 and abs(sum(n * n for n in s['normal']) - 1) < 1e-9, s
PY
  run render "$rec" --out "$tmp/v" --walls "$tmp/walls.json" --every 40 --json; expect_rc 0
  # A recording of one stereo pair makes a map.
  cp -r "$rec" "$tmp/one"
  for c in cam0 cam1; do head -n 2 "$rec/mav0/$c/data.csv" >"$tmp/one/mav0/$c/data.csv"; done
  run track "$tmp/one" --lockstep --map "$tmp/one.ply" --json; expect_rc 0
  [ "$(json "d['frames']")" = 1 ] || fail "one pair: frames"
  python3 -c "import json,sys; sys.exit(0 if json.load(open('$tmp/out'))['map_points'] > 100 else 1)" || fail "one pair: map"
  ;;
track_run_same)
  # One pipeline: `wallar track --lockstep` and `wallar run --deterministic` (the sim board
  # replays the same recording) write the same trajectory, byte for byte, and the same walls.
  run track "$rec" --lockstep --out "$tmp/track.tum" --walls "$tmp/track_walls.json" --json
  expect_rc 0; [ "$(json "d['mode']")" = "lock step" ] || fail "mode"
  run run --board "$src/board/sim.yaml" --out "$tmp/o" --deterministic --fast --no-view --json
  expect_rc 0
  [ "$(grep -c . "$tmp/track.tum")" = 40 ] || fail "track.tum lines"
  cmp "$tmp/track.tum" "$tmp/o/trajectory.tum" || fail "trajectories differ: $(diff "$tmp/track.tum" "$tmp/o/trajectory.tum" | head -4)"
  python3 - "$tmp/track_walls.json" "$tmp/o/walls.json" <<'PY' || fail "walls differ"
import json, sys
a, b = (json.load(open(p)) for p in sys.argv[1:3])
key = lambda d: [(s['id'], s['kind'], s['normal'], s['d'], s['inliers']) for s in d['surfaces']]
assert key(a) == key(b) and len(a['surfaces']) >= 2, (key(a), key(b))
PY
  ;;
mcap)
  # MCAP: the bundled recording converted and read by Foxglove's reference reader (@mcap/core,
  # installed by tools/setup), tracked to the same trajectory as its EuRoC folder; a recording
  # of the sim board; 20 random cuts, each replayed up to its last complete chunk, as the
  # reference's own stream reader recovers it, and the loss said on stderr.
  ref() { node "$src/tests/cli/mcap_reference.cjs" "$src/tools/node" "$@"; }
  command -v node >/dev/null && [ -d "$src/tools/node/node_modules/@mcap/core" ] ||
    fail "no Node.js or no tools/node/node_modules (run tools/setup)"
  run convert "$rec" "$tmp/still.mcap" --json; expect_rc 0
  [ "$(json "d['frames']")" = "[40, 40]" ] || fail "converted frames"
  ref "$tmp/still.mcap" /cam0=40 /cam1=40 /imu0=491 /ground_truth=50 /cam0/calibration=40 \
    /cam1/calibration=40 >"$tmp/ref" || fail "the reference reader refused the converted file"
  # Each camera's calibration beside its images: the folder's sensor.yaml as Foxglove reads it.
  python3 - "$tmp/ref" "$rec" <<'PY' || fail "calibration channels: $(cat "$tmp/ref")"
import json, re, sys
got = json.load(open(sys.argv[1]))['calibrations']
for cam in ('cam0', 'cam1'):
    text = open(f'{sys.argv[2]}/mav0/{cam}/sensor.yaml').read()
    k = [float(v) for v in re.search(r'intrinsics: *\[([^\]]*)\]', text).group(1).split(',')]
    d = [float(v) for v in re.search(r'distortion_coefficients: *\[([^\]]*)\]', text).group(1).split(',')]
    res = [int(v) for v in re.search(r'resolution: *\[([^\]]*)\]', text).group(1).split(',')]
    c = got[f'/{cam}/calibration']
    assert [c['width'], c['height']] == res and c['fx'] == k[0] and c['D'] == d + [0.0], (cam, c)
PY
  # Under the cross emulator (10-20x slower) and a sanitizer (3-5x) the container's checks are
  # the same on fewer inputs: 5 cuts, no lz4 copy, no rectify-check (the unit tests run every
  # Mcap.* there too, and the fuzz stage the reader under ASan); the host build runs them all.
  reduced=${WALLAR_EMULATOR:+1}${WALLAR_SANITIZE:+1}
  if [ -z "$reduced" ]; then
    run convert "$rec" "$tmp/still.lz4.mcap" --compression lz4; expect_rc 0
    ref "$tmp/still.lz4.mcap" /cam0=40 /imu0=491 >/dev/null || fail "lz4 file refused"
  fi
  # The folder tracked once: its trajectory, and a run file for Foxglove (below).
  run track "$rec" --lockstep --out "$tmp/euroc.tum" --mcap "$tmp/run.mcap" --json; expect_rc 0
  mv "$tmp/out" "$tmp/run.json"
  run track "$tmp/still.mcap" --lockstep --out "$tmp/mcap.tum"; expect_rc 0
  [ ! -s "$tmp/err" ] || fail "stderr on a whole file: $(cat "$tmp/err")"
  cmp "$tmp/euroc.tum" "$tmp/mcap.tum" || fail "trajectories differ"
  # The calibration and frames inside the file: the folder's rectification figures exactly.
  if [ -z "$reduced" ]; then
    run calibrate rectify-check --recording "$rec" --every 40 --json; expect_rc 0
    mv "$tmp/out" "$tmp/check_euroc.json"
    run calibrate rectify-check --recording "$tmp/still.mcap" --every 40 --json; expect_rc 0
    python3 - "$tmp/check_euroc.json" "$tmp/out" <<'PY' || fail "rectify-check differs on the .mcap"
import json, sys
a, b = (json.load(open(p)) for p in sys.argv[1:3])
assert a['pairs'] == b['pairs'] == 1 and a['matches'] == b['matches'] > 200, (a, b)
assert a['mean_px'] == b['mean_px'], (a, b)
PY
  fi
  run convert "$tmp/still.mcap" "$tmp/back"; expect_rc 0
  cmp "$rec/mav0/imu0/data.csv" "$tmp/back/mav0/imu0/data.csv" || fail "imu0 differs after MCAP"
  diff -r "$rec/mav0/cam1/data" "$tmp/back/mav0/cam1/data" >/dev/null || fail "PNGs differ"
  run convert "$rec" "$tmp/still.mcap"; expect_rc 2; one_err_line; expect_err "already exists"
  run convert "$rec" "$tmp/x.bin"; expect_rc 2; one_err_line; expect_err "name it NAME.mcap"
  # A run for Foxglove: the streams plus /pose and /tf a frame, the final /map and /walls; the
  # reference reads the point cloud's points and the scene's surfaces that the run reports.
  cp "$tmp/run.json" "$tmp/out"
  frames=$(json "d['frames']"); points=$(json "d['map_points']"); surfaces=$(json "d['surfaces']")
  ref "$tmp/run.mcap" /cam0=40 /imu0=491 /pose=$frames /tf=$frames /map=1 /walls=1 >"$tmp/ref" ||
    fail "the reference reader refused the run's file"
  python3 - "$tmp/ref" "$points" "$surfaces" <<'PY' || fail "map or walls differ: $(cat "$tmp/ref")"
import json, sys
d = json.load(open(sys.argv[1]))
assert d['points']['/map'] == int(sys.argv[2]) > 100, d['points']
assert len(d['entities']['/walls']) == int(sys.argv[3]) >= 2, d['entities']
PY
  run replay "$tmp/run.mcap" --stats --fast --no-images; expect_rc 0  # outputs beside the streams
  expect_out "cam0      40 samples"
  # The sim board recorded to MCAP: counts equal the recorder's rows.
  run record --board "$src/board/sim.yaml" --out "$tmp/rec.mcap" --fast --json; expect_rc 0
  imu_rows=$(json "d['imu_rows']"); cam_rows=$(json "d['cam_rows'][0]")
  [ "$imu_rows" = 491 ] && [ "$cam_rows" = 40 ] || fail "recorded $imu_rows / $cam_rows"
  ref "$tmp/rec.mcap" /cam0=$cam_rows /cam1=40 /imu0=$imu_rows >/dev/null || fail "recording refused"
  # Rotating MCAP: 2 MiB segments under a 5 MiB cap, each a whole file Foxglove's reader
  # accepts; the last ends with the clip.
  run record --board "$src/board/sim.yaml" --out "$tmp/rot" --format mcap --fast --segment-mb 2 \
    --max-mb 5 --json; expect_rc 0
  [ "$(json "d['rotation']['segments_deleted'] >= 2")" = True ] || fail "mcap segments deleted: $(cat "$tmp/out")"
  [ "$(du -s --apparent-size -k "$tmp/rot" | cut -f1)" -le $((8 * 1024)) ] || fail "mcap over the cap"
  for seg in "$tmp"/rot/*.mcap; do
    ref --stream "$seg" >/dev/null || fail "segment $seg refused"
    run replay "$seg" --stats --fast --no-images; expect_rc 0; expect_out "unpaired left 0, right 0"
  done
  run replay "$(ls "$tmp"/rot/*.mcap | tail -1)" --stats --fast --no-images --json; expect_rc 0
  [ "$(json "d['replay']['last_t_ns']")" = "$(tail -1 "$rec/mav0/cam0/data.csv" | cut -d, -f1)" ] ||
    [ "$(json "d['replay']['last_t_ns'] >= $(tail -1 "$rec/mav0/cam0/data.csv" | cut -d, -f1)")" = True ] ||
    fail "the last segment ends early"
  run record --board "$src/board/sim.yaml" --out "$tmp/rec2.mcap" --segment-mb 5
  expect_rc 2; one_err_line; expect_err "give --out a folder"
  # Power loss: 20 cuts at seeded random bytes; the reference's stream reader says what each
  # holds (one node run for all), wallar replays each.
  size=$(stat -c %s "$tmp/still.mcap")
  ncuts=$([ -z "$reduced" ] && echo 20 || echo 5)
  cuts=$(python3 -c "import random; r = random.Random(21); print(*sorted(r.randrange(8, $size) for _ in range(20))[::20 // $ncuts])")
  for cut in $cuts; do head -c "$cut" "$tmp/still.mcap" >"$tmp/cut$cut.mcap"; done
  ref --stream $(for cut in $cuts; do echo "$tmp/cut$cut.mcap"; done) >"$tmp/want" ||
    fail "the reference's stream reader failed on a cut file"
  [ "$(grep -c . "$tmp/want")" = "$ncuts" ] || fail "reference read $(grep -c . "$tmp/want") cut files"
  for cut in $cuts; do
    run replay "$tmp/cut$cut.mcap" --stats --fast --no-images --json
    case "$(rc)" in
    0) expect_err "cut off or damaged: read"  # (and a frame whose partner was lost, when the cut split them)
       python3 - "$tmp/out" "$tmp/want" "$tmp/cut$cut.mcap" <<'PY' || fail "cut at $cut: $(cat "$tmp/err")"
import json, sys
got = json.load(open(sys.argv[1]))['streams']
want = next(w for w in map(json.loads, open(sys.argv[2])) if w['file'] == sys.argv[3])['counts']
for ours, topic in (('cam0', '/cam0'), ('cam1', '/cam1'), ('imu0', '/imu0')):
    assert got[ours]['count'] == want.get(topic, 0), (ours, got[ours]['count'], want)
PY
       ;;
    2) one_err_line; expect_err "$tmp/cut$cut.mcap" ;;  # cut before the calibration: said
    *) fail "cut at $cut: exit code $(rc): $(cat "$tmp/err")" ;;
    esac
  done
  ;;
track_no_imu)
  # Vision-only recordings: no imu0 folder at all, or an imu0/data.csv with its header only.
  # Accepted by track, run and render with nothing on stderr; no IMU is not a lost IMU.
  mkdir -p "$tmp/noimu/mav0"
  for d in cam0 cam1 state_groundtruth_estimate0; do cp -r "$rec/mav0/$d" "$tmp/noimu/mav0/"; done
  cp "$rec/mav0/body.yaml" "$tmp/noimu/mav0/" 2>/dev/null
  cp -r "$tmp/noimu" "$tmp/header"; cp -r "$rec/mav0/imu0" "$tmp/header/mav0/"; chmod -R u+w "$tmp/header"
  head -n 1 "$rec/mav0/imu0/data.csv" >"$tmp/header/mav0/imu0/data.csv"
  for r in noimu header; do
    run track "$tmp/$r" --lockstep --eval --walls "$tmp/$r.json" --json; expect_rc 0
    [ -s "$tmp/err" ] && fail "$r: stderr: $(cat "$tmp/err")"
    [ "$(json "d['imu'], d['frames'], d['tracking_frames'], d['events']")" = "False 40 40 []" ] || fail "$r: $(cat "$tmp/out")"
    [ "$(json "d['degraded']['imu_lost'], d['degraded']['camera_lost'], 'floor' in d")" = "0 0 False" ] || fail "$r: degraded"
    python3 -c "import json,sys; d=json.load(open('$tmp/out')); sys.exit(0 if d['drift_m'] < 0.01 else 1)" || fail "$r: drift"
    python3 -c "import json,sys; d=json.load(open('$tmp/$r.json')); sys.exit(0 if d['mode'].startswith('3-D') and d['surfaces'] else 1)" || fail "$r: walls"
  done
  run track "$tmp/noimu" --gravity-aligned; expect_rc 2; one_err_line; expect_err "--gravity-aligned needs an IMU"
  printf 'board: {name: vision}\nsource: replay\nreplay: {recording: %s, rate: 0}\n' "$tmp/noimu" >"$tmp/vision.yaml"
  run run --board "$tmp/vision.yaml" --out "$tmp/o" --deterministic --no-view --json; expect_rc 0
  [ "$(json "d['imu']['present'], d['imu']['samples'], d['degraded']['imu_lost'], d['events']")" = "False 0 0 []" ] || fail "run: $(cat "$tmp/out")"
  [ "$(json "d['walls']['mode']")" = "3-D (no gravity)" ] || fail "run: walls mode"
  grep -v "^wallar: board vision" "$tmp/err" | grep -q . && fail "run: stderr: $(cat "$tmp/err")"
  run render "$tmp/noimu" --out "$tmp/view" --every 40 --width 320 --height 120 --json; expect_rc 0
  [ -s "$tmp/err" ] && fail "render: stderr: $(cat "$tmp/err")"
  python3 -c "import json,sys; d=json.load(open('$tmp/view/walls.json')); sys.exit(0 if 'no IMU' in d['frame'] else 1)" || fail "render: frame"
  ;;
track_street)
  # The real moving clip of issue 17 (karlsruhe_0019_street: 253 pairs, 139 m of street, vision
  # only). Its licence forbids bundling it, so the test takes its path (WALLAR_STREET_CLIP, else
  # ../shared/data beside the checkout) and skips without it, and under an emulator (minutes).
  street="${WALLAR_STREET_CLIP:-$src/../shared/data/karlsruhe_0019_street}"
  [ -d "$street/mav0" ] || { echo "SKIP: no street clip at $street"; exit 77; }
  [ -n "${WALLAR_EMULATOR:-}" ] && { echo "SKIP: 253 frames at 1344x372 under an emulator"; exit 77; }
  run track "$street" --eval --walls "$tmp/street.json" --json; expect_rc 0
  [ -s "$tmp/err" ] && fail "stderr: $(cat "$tmp/err")"
  # Under a sanitizer (which found a read past the image's last row on this clip) the clean run
  # is what counts: the threaded mapper falls behind there, so the figures say nothing.
  [ -n "${WALLAR_SANITIZE:-}" ] && { echo "under $WALLAR_SANITIZE: ran clean, figures not checked"; exit 0; }
  [ "$(json "d['frames'], d['tracking_frames'], d['lost_frames'], d['mode']")" = "253 253 0 every frame" ] || fail "tracking: $(cat "$tmp/out")"
  # Its ground truth is a position track (identity orientations): no RPE or drift is claimed.
  [ "$(json "d['ground_truth'], 'drift_m' in d, 'rpe_rot_rmse_deg' in d")" = "positions only False False" ] || fail "eval fields: $(cat "$tmp/out")"
  # Positions only (the clip's ground-truth orientations are placeholders): under 1 % of the path.
  python3 -c "import json,sys; d=json.load(open('$tmp/out')); sys.exit(0 if d['ate_rmse_m'] < 0.01 * d['path_length_m'] and d['path_length_m'] > 130 else 1)" || fail "ATE: $(json "d['ate_rmse_m'], d['path_length_m']")"
  # The road as the floor and facades as walls, searched in 2-D with down from the path.
  python3 - "$tmp/street.json" <<'PY' || fail "walls: $(head -c 400 "$tmp/street.json")"
import json, sys
w = json.load(open(sys.argv[1]))
kinds = [s["kind"] for s in w["surfaces"]]
ok = w["mode"].startswith("2-D (down from the path") and kinds.count("floor") == 1 and kinds.count("wall") >= 2
sys.exit(0 if ok else 1)
PY
  ;;
track_bad_input)
  run track "$tmp/nowhere"; expect_rc 2; one_err_line
  run track "$rec" --board "$tmp/none.yaml"; expect_rc 2; one_err_line
  # --eval without ground truth.
  cp -r "$rec" "$tmp/nogt"; rm -r "$tmp/nogt/mav0/state_groundtruth_estimate0"
  run track "$tmp/nogt" --eval; expect_rc 2; one_err_line; expect_err "needs ground truth"
  # A calibration for another image size: named, with the image and the sizes.
  cp -r "$rec" "$tmp/size"
  sed -i 's/^resolution: \[752, 480\]/resolution: [640, 480]/' "$tmp/size/mav0/cam0/sensor.yaml" "$tmp/size/mav0/cam1/sensor.yaml"
  run track "$tmp/size" --out "$tmp/size.txt"; expect_rc 2; one_err_line
  expect_err "expected 640x480"
  [ ! -e "$tmp/size.txt" ] || fail "a trajectory was written for a failed run"
  ;;
render)
  run render "$rec" --out "$tmp/view" --every 13 --width 640 --height 240 --json; expect_rc 0
  [ "$(json "d['frames']")" = 40 ] || fail "frames"
  [ "$(json "d['written']")" = 4 ] || fail "written (0, 13, 26, 39)"
  for n in 000000 000013 000026 000039; do [ -s "$tmp/view/view_$n.png" ] || fail "view_$n.png"; done
  python3 -c "import struct,sys; b=open('$tmp/view/view_000039.png','rb').read(24); sys.exit(0 if struct.unpack('>II', b[16:24]) == (640, 240) else 1)" || fail "view size"
  python3 -c "import json,sys; d=json.load(open('$tmp/view/walls.json')); sys.exit(0 if any(s['kind']=='floor' for s in d['surfaces']) else 1)" || fail "no floor in walls.json"
  # Its walls.json renders again as given (--walls), the same number of surfaces.
  run render "$rec" --out "$tmp/again" --walls "$tmp/view/walls.json" --every 40 --json; expect_rc 0
  [ "$(json "d['walls']")" = "$(python3 -c "import json; print(len(json.load(open('$tmp/view/walls.json'))['surfaces']))")" ] || fail "walls given"
  [ "$(json "d['written']")" = 1 ] || fail "written with --walls"
  # Real time (4x here): the appliance with its render thread drawing the newest frame; every
  # delivered frame is tracked and posted or overwritten (counted), every posted frame drawn or
  # skipped, latencies are measured.
  run render "$rec" --out "$tmp/rt" --walls "$tmp/view/walls.json" --realtime --rate 4 --json
  expect_rc 0
  [ "$(json "d['frames_in'], d['posted'] + d['frames_overwritten'], d['walls_source']")" = "40 40 given" ] || fail "posted: $(cat "$tmp/out")"
  [ "$(json "d['drawn'] + d['skipped'] == d['posted'] > 0")" = True ] || fail "drawn + skipped"
  python3 -c "import json,sys; d=json.load(open('$tmp/out')); l=d['camera_to_display_latency']; sys.exit(0 if 0 < l['p50_ms'] <= l['max_ms'] and d['tracking_time']['p50_ms'] > 0 else 1)" || fail "latency: $(cat "$tmp/out")"
  # Without --walls the view draws the reconstruction's walls as they come.
  run render "$rec" --out "$tmp/rt2" --realtime --rate 4 --json; expect_rc 0
  [ "$(json "d['walls_source'], d['walls'] >= 1")" = "reconstruction True" ] || fail "live walls: $(cat "$tmp/out")"
  ;;
render_bad_input)
  run render "$tmp/nowhere" --out "$tmp/o"; expect_rc 2; one_err_line
  printf '{"surfaces": [{"id": 1, "normal": [0, 0, 2], "d": 1, "extent": [[0,0,0],[1,0,0],[1,1,0]]}]}' >"$tmp/w.json"
  run render "$rec" --out "$tmp/o" --walls "$tmp/w.json"; expect_rc 2; one_err_line
  expect_err "surface 0: normal is not a unit vector"
  printf '{"surfaces": [' >"$tmp/cut.json"
  run render "$rec" --out "$tmp/o" --walls "$tmp/cut.json"; expect_rc 2; one_err_line
  expect_err "cut.json: not JSON"
  run render "$rec" --out "$tmp/o" --lens 0.1; expect_rc 2; expect_err "lens"
  ;;
eval_synth_rig)
  # A short synthetic headset clip: written, read back by replay, tracked against its truth.
  run eval synth-rig --out "$tmp/rig" --motion look-around --duration 3 --time-offset-ms 4 --json
  expect_rc 0
  [ "$(json "d['frames']")" = 60 ] || fail "frames"
  imu_rows=$(json "d['imu_rows']")
  m="$tmp/rig/mav0"
  grep -q '^imu_clock_offset_ns: 4000000 ' "$m/state_groundtruth_estimate0/sensor.yaml" || fail "offset in the ground truth's sensor.yaml"
  grep -q 'timeshift_cam_imu: 0.004 ' "$m/camchain-imucam.yaml" || fail "timeshift_cam_imu"
  grep -q '^rate_hz: 200.0' "$m/imu0/sensor.yaml" || fail "imu rate"
  python3 -c "import sys; v={l.split(':')[0]: l.split(':')[1].split('#')[0] for l in open('$m/imu0/sensor.yaml') if ':' in l}; sys.exit(0 if float(v['gyroscope_noise_density']) == 2.6e-4 and float(v['accelerometer_random_walk']) == 3e-4 else 1)" || fail "densities"
  # The first IMU row is stamped 4 ms after the first ground-truth row (same true time).
  python3 - "$m" <<'PY' || fail "IMU vs ground-truth stamps"
import sys
rows = lambda f: [l.split(',')[0] for l in open(f) if not l.startswith('#')]
imu, gt = rows(sys.argv[1] + '/imu0/data.csv'), rows(sys.argv[1] + '/state_groundtruth_estimate0/data.csv')
sys.exit(0 if len(imu) == len(gt) and all(int(a) - int(b) == 4000000 for a, b in zip(imu, gt)) else 1)
PY
  run replay "$tmp/rig" --stats --fast --json; expect_rc 0
  [ "$(json "d['streams']['imu0']['count']")" = "$imu_rows" ] || fail "replayed IMU rows"
  [ "$(json "d['replay']['pairing']['pairs']")" = 60 ] || fail "stereo pairs"
  run track "$tmp/rig" --eval --lockstep --json; expect_rc 0
  python3 -c "import json,sys; d=json.load(open('$tmp/out')); sys.exit(0 if d['frames'] == 60 and d['tracking_frames'] >= 57 and d['ate_rmse_m'] < 0.03 else 1)" || fail "tracking: $(cat "$tmp/out")"
  # Same options, same bytes; the human-readable summary names what was written.
  run eval synth-rig --out "$tmp/a" --motion quick-turns --duration 1 --width 160 --height 120 --rolling-shutter 8 --gain-steps on --imu-rate 500
  expect_rc 0; expect_out "wrote $tmp/a (quick-turns, seed 1): 20 stereo frames 160x120"
  run eval synth-rig --out "$tmp/b" --motion quick-turns --duration 1 --width 160 --height 120 --rolling-shutter 8 --gain-steps on --imu-rate 500
  expect_rc 0
  diff -r "$tmp/a" "$tmp/b" >/dev/null || fail "two runs differ"
  ;;
eval_synth_rig_bad_input)
  for bad in "--imu-rate 100" "--imu-rate 2000" "--motion fly" "--blur maybe" "--blur 80" \
             "--gain-steps yes" "--duration 0" "--noise -1" "--width 8" "--time-offset-ms 5000" \
             "--motion walk --peak-turn-deg-s 200" "--ground-truth vicon" \
             "--imu-noise-from $tmp/none.yaml"; do
    # shellcheck disable=SC2086
    run eval synth-rig --out "$tmp/x" $bad; expect_rc 2; one_err_line
    expect_err "${bad%% *}"
    [ ! -e "$tmp/x" ] && [ ! -e "$tmp/x.part" ] || fail "$bad: something was written"
  done
  mkdir "$tmp/full"; echo mine >"$tmp/full/keep"
  run eval synth-rig --out "$tmp/full" --duration 0.1; expect_rc 2; one_err_line
  expect_err "already exists"
  [ "$(cat "$tmp/full/keep")" = mine ] || fail "an existing folder was touched"
  ;;
*)
  fail "unknown case" ;;
esac
echo "ok [$case_name]"

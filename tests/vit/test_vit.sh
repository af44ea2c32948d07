#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# libwallar_vit.so (issue 20): the same trajectory through the VIT interface as through
# `wallar track --lockstep` (deterministic) on one recording, and the exported symbols.
#   test_vit.sh WALLAR HARNESS LIBRARY SRC_DIR euroc|synth_rig|symbols
set -euo pipefail
wallar=$1 harness=$2 lib=$3 src=$4 case=$5
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
fail() { echo "FAILED: $*" >&2; exit 1; }

# Through the library and through `wallar track --lockstep` (deterministic): the same poses up
# to the VIT pose's float32 (issue 20 asks within 1 mm; held to 1 um RMS, same world, so that
# another path, e.g. without the gyro prior at 36 um, fails).
compare() {
  local rec=$1 reset=${2:-0}
  "$wallar" track "$rec" --lockstep --out "$tmp/track.tum" >"$tmp/track.out" 2>&1 ||
    fail "wallar track: $(cat "$tmp/track.out")"
  "$harness" --library "$lib" --recording "$rec" --reference "$tmp/track.tum" \
    --out "$tmp/vit.tum" --max-diff-m 1e-6 --check-reset "$reset" || fail "vit_harness on $rec"
}

case "$case" in
euroc)
  compare "$src/tests/data/euroc_v1_01_still"
  ;;
synth_rig)
  # A moving headset (quick turns), rendered with a fixed seed; a reset halfway through too.
  "$wallar" eval synth-rig --out "$tmp/rec" --motion quick-turns --duration 5 --seed 1 \
    >"$tmp/gen" 2>&1 || fail "synth-rig: $(cat "$tmp/gen")"
  compare "$tmp/rec" 1
  ;;
symbols)
  # Every function Monado's loader resolves is exported, and nothing but vit_* is.
  nm -D --defined-only "$lib" >"$tmp/nm" || fail "nm -D $lib"
  for f in api_get_version tracker_create tracker_destroy tracker_has_image_format \
    tracker_get_supported_extensions tracker_get_enabled_extensions tracker_enable_extension \
    tracker_start tracker_stop tracker_reset tracker_is_running tracker_push_imu_sample \
    tracker_push_img_sample tracker_add_imu_calibration tracker_add_camera_calibration \
    tracker_pop_pose tracker_get_timing_titles pose_destroy pose_get_data pose_get_timing \
    pose_get_features; do
    grep -qE " T vit_$f\$" "$tmp/nm" || fail "vit_$f not exported: $(cat "$tmp/nm")"
  done
  others=$(awk '$2 ~ /^[TDBRVW]$/ && $3 !~ /^vit_/ {print $3}' "$tmp/nm")
  [ -z "$others" ] || fail "exported beyond vit_*: $(echo "$others" | head -5)"
  echo "21 vit_* functions exported, nothing else"
  ;;
*) fail "unknown case $case" ;;
esac

#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# The layering rule of DEVELOPERS.md: dsp/ includes no drivers/ or firmware/ header; drivers/
# includes no dsp/ or firmware/ header (the header-only core vocabulary, wallar/core/, is shared).
set -u
root=$1
status=0
check() {  # folder, forbidden include pattern
  local hits
  hits=$(grep -rnE "#include [<\"]wallar/($2)/" "$root/$1" --include='*.hpp' --include='*.cpp' --include='*.h')
  if [ -n "$hits" ]; then
    echo "layering: $1/ must not include wallar/{$2}:" >&2
    echo "$hits" >&2
    status=1
  fi
}
check dsp 'drivers|firmware'
check drivers 'dsp|firmware'
# CMake: wallar_drivers must not link wallar::dsp, wallar_dsp must not link wallar::drivers.
grep -nE 'wallar(::|_)dsp' "$root/drivers/CMakeLists.txt" && { echo "drivers/CMakeLists.txt links dsp" >&2; status=1; }
grep -nE 'wallar(::|_)drivers' "$root/dsp/CMakeLists.txt" && { echo "dsp/CMakeLists.txt links drivers" >&2; status=1; }
[ $status = 0 ] && echo "layering ok"
exit $status

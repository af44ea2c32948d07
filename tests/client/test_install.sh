#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# libwallar-client as an application sees it once installed: the client's install rules into
# a temporary prefix, then the examples and a C++ use of the wrapper built with nothing but
# `pkg-config wallar-client` (draw_planes adds egl and glesv2), run against a socket that is not
# there (a one-line error, exit 1).
# The library exports only its C API and carries its soname.
#
# usage: test_install.sh BUILD_DIR SOURCE_DIR
set -uo pipefail
build=$1
src=$2
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
fail() { echo "FAIL [client_install]: $*" >&2; exit 1; }
command -v pkg-config >/dev/null || fail "no pkg-config"
cmake -DCMAKE_INSTALL_PREFIX="$tmp/prefix" -P "$build/firmware/client/cmake_install.cmake" >/dev/null ||
  fail "install rules"
pc=$(find "$tmp/prefix" -name wallar-client.pc)
[ -n "$pc" ] || fail "no wallar-client.pc installed"
export PKG_CONFIG_PATH=$(dirname "$pc")
flags=$(pkg-config --cflags --libs wallar-client) || fail "pkg-config: $flags"
libdir=$(pkg-config --variable=libdir wallar-client)
lib="$libdir/libwallar-client.so.0"
[ -e "$lib" ] || fail "no $lib"
objdump -p "$lib" | grep -q 'SONAME *libwallar-client.so.0$' || fail "soname: $(objdump -p "$lib" | grep SONAME)"
others=$(nm -D --defined-only "$lib" | awk '{print $3}' | grep -v '^wallar_client_\|^wallar_planes_')
[ -z "$others" ] || fail "exports beyond the C API: $others"
for f in connect disconnect fd now_ns locate poll_events tracking begin_planes; do
  nm -D --defined-only "$lib" | grep -q " wallar_client_$f\$" || fail "wallar_client_$f not exported"
done
cc -std=c11 -Wall -Wextra -Werror "$src/examples/print_planes.c" $flags -o "$tmp/print_planes" ||
  fail "print_planes.c does not build with pkg-config's flags"
gl_flags=$(pkg-config --cflags --libs egl glesv2) || fail "pkg-config egl glesv2: $gl_flags"
cc -std=c11 -Wall -Wextra -Werror "$src/examples/draw_planes.c" $flags $gl_flags -lm \
  -o "$tmp/draw_planes" || fail "draw_planes.c does not build with pkg-config's flags"
cat >"$tmp/use.cpp" <<'CPP'
#include <wallar_client.hpp>
#include <cstdio>
int main() {
  try {
    wallar::Client c("/nonexistent/wallar.sock", "t");
  } catch (const std::runtime_error& e) {
    std::printf("%s\n", e.what());
    return 1;
  }
  return 0;
}
CPP
c++ -std=c++17 -Wall -Wextra -Werror "$tmp/use.cpp" $flags -o "$tmp/use" ||
  fail "the C++ wrapper does not build (C++17) with pkg-config's flags"
for app in print_planes draw_planes; do
  out=$(LD_LIBRARY_PATH=$libdir "$tmp/$app" --socket /nonexistent/wallar.sock --wait 0 2>&1)
  rc=$?
  [ $rc = 1 ] || fail "$app exit $rc: $out"
  [ "$(printf '%s\n' "$out" | wc -l)" = 1 ] || fail "$app: not one line: $out"
  case "$out" in "$app: error: "*"/nonexistent/wallar.sock: cannot connect: No such file or directory"*) ;;
    *) fail "$app said: $out" ;; esac
done
out=$(LD_LIBRARY_PATH=$libdir "$tmp/use" 2>&1)
[ $? = 1 ] || fail "the C++ wrapper did not throw: $out"
case "$out" in *"cannot connect"*) ;; *) fail "the C++ wrapper said: $out" ;; esac
echo "ok [client_install]"

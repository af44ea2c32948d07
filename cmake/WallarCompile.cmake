# SPDX-License-Identifier: Apache-2.0
# Warnings, sanitizers and the SIMD baseline, applied to every target of the project through
# the interface target wallar_build_flags (not globally, so third-party code is untouched).

add_library(wallar_build_flags INTERFACE)
target_compile_options(wallar_build_flags INTERFACE -Wall -Wextra -Werror -Wshadow
                                                    -Wnon-virtual-dtor -Wformat=2)
# Same arithmetic on every target: GCC fuses a * b + c into an FMA wherever the ISA has one
# (always on aarch64, never on the x86-64-v2 baseline), so scalar geometry rounds differently
# and seeded RANSAC runs diverge between the board and the host. Fused multiply-adds stay
# where the code asks for them (the SIMD kernel's MulAdd).
target_compile_options(wallar_build_flags INTERFACE -ffp-contract=off)
# Libraries are position-independent (CMAKE_POSITION_INDEPENDENT_CODE, for libwallar_vit.so);
# nothing of ours is interposed, so calls stay direct and inlinable as without -fPIC.
target_compile_options(wallar_build_flags INTERFACE -fno-semantic-interposition)
# Unity builds (CI: CMAKE_UNITY_BUILD) include each .cpp into a combined file, where GCC sees a
# class of one .cpp holding a member of an anonymous-namespace type of the same .cpp as a type
# "defined in another file" and warns; in one-file-per-TU builds it is silent and harmless.
if(CMAKE_UNITY_BUILD AND CMAKE_CXX_COMPILER_ID STREQUAL "GNU")
  target_compile_options(wallar_build_flags INTERFACE -Wno-subobject-linkage)
endif()
# Debug builds catch uninitialised Eigen matrices (STYLE.md 13).
target_compile_definitions(wallar_build_flags INTERFACE
                           $<$<CONFIG:Debug>:EIGEN_INITIALIZE_MATRICES_BY_NAN>)

# SIMD baseline per target architecture; never -march=native (the binary must run on any board
# of the architecture). Highway dispatches wider units at run time on top of this baseline.
if(NOT DEFINED WALLAR_SIMD_FLAGS)
  if(CMAKE_SYSTEM_PROCESSOR MATCHES "^(aarch64|arm64)$")
    set(WALLAR_SIMD_FLAGS "-march=armv8-a")  # NEON (ASIMD) is part of ARMv8-A
  elseif(CMAKE_SYSTEM_PROCESSOR MATCHES "^(x86_64|AMD64)$")
    set(WALLAR_SIMD_FLAGS "-march=x86-64-v2")  # SSE4.2/POPCNT, any x86-64 of the last decade
  else()
    set(WALLAR_SIMD_FLAGS "")
  endif()
endif()
set(WALLAR_SIMD_FLAGS "${WALLAR_SIMD_FLAGS}" CACHE STRING "SIMD baseline flags for this target")
separate_arguments(_wallar_simd UNIX_COMMAND "${WALLAR_SIMD_FLAGS}")
target_compile_options(wallar_build_flags INTERFACE ${_wallar_simd})

# Hardening, as Debian's dpkg-buildflags gives its packages (lintian checks the binary for it):
# checked libc calls, stack protector, stack-clash probes, and a read-only GOT resolved at
# start-up (no lazy binding: the fixed-rate threads never stop in the dynamic linker either).
# Not in Debug (_FORTIFY_SOURCE needs the optimiser) nor under the sanitizers (their own checks).
if(NOT WALLAR_SANITIZE AND NOT WALLAR_BUILD_FUZZ)
  target_compile_options(wallar_build_flags INTERFACE -fstack-protector-strong
                                                      -fstack-clash-protection)
  target_compile_definitions(wallar_build_flags INTERFACE
                             $<$<NOT:$<CONFIG:Debug>>:_FORTIFY_SOURCE=2>)
  target_link_options(wallar_build_flags INTERFACE -Wl,-z,relro -Wl,-z,now)
endif()

if(WALLAR_SANITIZE)
  string(REPLACE ";" "," _wallar_san "${WALLAR_SANITIZE}")
  add_compile_options(-fsanitize=${_wallar_san} -fno-omit-frame-pointer
                      -fno-sanitize-recover=all)
  # UBSan's object-size check keeps clang 14 from inlining Eigen's small functions (a rendered
  # room's ray casts called each coefficient accessor out of line: the slowest tests ran at
  # half speed), and it finds nothing ASan does not: every access beyond an object is in
  # ASan's red zones.
  if(WALLAR_SANITIZE MATCHES "address" AND WALLAR_SANITIZE MATCHES "undefined")
    add_compile_options(-fno-sanitize=object-size)
  endif()
  add_link_options(-fsanitize=${_wallar_san})
  # One name for "a sanitizer build" with either compiler (GCC defines __SANITIZE_ADDRESS__,
  # clang only answers __has_feature): tests shorten their slowest cases, the allocation
  # counter leaves operator new to the sanitizer.
  add_compile_definitions(WALLAR_SANITIZED=1)
endif()

# libFuzzer (tests/fuzz): clang only. Our own code gets the coverage instrumentation libFuzzer
# steers by (fuzzer-no-link); the fuzz executables add -fsanitize=fuzzer for the driver.
if(WALLAR_BUILD_FUZZ)
  if(NOT CMAKE_CXX_COMPILER_ID MATCHES "Clang")
    message(FATAL_ERROR "WALLAR_BUILD_FUZZ needs clang (libFuzzer), not ${CMAKE_CXX_COMPILER_ID}; "
                        "use the 'fuzz' preset or -DCMAKE_CXX_COMPILER=clang++")
  endif()
  target_compile_options(wallar_build_flags INTERFACE -fsanitize=fuzzer-no-link)
  target_link_options(wallar_build_flags INTERFACE -fsanitize=fuzzer-no-link)
endif()

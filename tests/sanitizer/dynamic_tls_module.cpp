// SPDX-License-Identifier: Apache-2.0
/// @file dynamic_tls_module.cpp
/// @brief A shared module with a small thread-local block, which glibc allocates per thread on
/// first use (dynamic TLS, as in Mesa's and LLVM's dlopen'ed drivers). For
/// lsan_dynamic_tls.cpp only.
///
/// Threading: wallar_touch_dynamic_tls() may be called from any thread.

// 48 bytes: glibc mallocs the block; under ASan it lands 16 bytes into a page on each new
// thread, where LeakSanitizer's guess at the block's bounds (clang 14) reads ASan's chunk
// header instead. Exported, so that the compiler keeps it and every access goes through
// __tls_get_addr.
extern "C" __attribute__((visibility("default"))) thread_local char wallar_dynamic_tls_block[48];
thread_local char wallar_dynamic_tls_block[48];

extern "C" __attribute__((visibility("default"))) int wallar_touch_dynamic_tls(int value) {
  volatile char* block = wallar_dynamic_tls_block;
  block[0] = static_cast<char>(value);
  return block[0];
}

// SPDX-License-Identifier: Apache-2.0
/// @file lsan_dynamic_tls.cpp
/// @brief The ASan build's leak check must survive threads that hold dynamic TLS at exit.
///
/// CI's ASan stage once failed after a test had passed: "Tracer caught signal 11 ...
/// LeakSanitizer has encountered a fatal error" at the exit of the headset view's golden-image
/// test, whose llvmpipe threads hold Mesa's dynamic TLS. clang 14's LeakSanitizer records each
/// dynamic TLS block it sees through __tls_get_addr and guesses the block's bounds from the 16
/// bytes before it when the block starts 16 bytes into a page (a glibc 2.19 layout). glibc 2.36
/// mallocs the block, so under ASan those bytes are ASan's chunk header; the guessed range is
/// garbage and the leak check's scan of it faults. ASan's allocator starts each new thread's
/// allocations on fresh pages, so the block lands there often; which thread's does is timing.
/// The test presets set intercept_tls_get_addr=0: the blocks are then found as the heap chunks
/// they are, through glibc's own table (a pointer kept only in such a block is still no leak,
/// and a real leak is still reported; both checked by hand, docs/results.md).
///
/// This program makes the fault certain: 64 threads each touch a 48-byte thread-local block of
/// a dlopen'ed module, then wait while main returns, so the leak check runs with every block
/// live. With the option it exits 0; without it, LeakSanitizer dies and the test fails.
///
/// Threading: main starts the threads and never joins them (the process ends with them).
#include <dlfcn.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <thread>

namespace {
constexpr int kThreads = 64;
std::atomic<int> g_touched{0};
}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s MODULE.so\n", argv[0]);
    return 2;
  }
  void* module = dlopen(argv[1], RTLD_NOW);
  if (module == nullptr) {
    std::fprintf(stderr, "lsan_dynamic_tls: cannot load %s: %s\n", argv[1], dlerror());
    return 2;
  }
  using Touch = int (*)(int);
  const auto touch = reinterpret_cast<Touch>(dlsym(module, "wallar_touch_dynamic_tls"));
  if (touch == nullptr) {
    std::fprintf(stderr, "lsan_dynamic_tls: %s has no wallar_touch_dynamic_tls\n", argv[1]);
    return 2;
  }
  for (int i = 0; i < kThreads; ++i) {
    std::thread([touch, i] {
      if (touch(i) == i) g_touched.fetch_add(1);
      for (;;) pause();  // holds its block until the process ends
    }).detach();
  }
  while (g_touched.load() < kThreads) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  std::printf("%d threads hold dynamic TLS at exit\n", g_touched.load());
  return 0;
}

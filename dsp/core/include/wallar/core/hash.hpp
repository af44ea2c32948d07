// Portable 64-bit hashing for reproducible synthetic data and seeds.
//
// Threading: pure functions, safe from any thread.
#pragma once

#include <cstdint>

namespace wallar::core {

/// splitmix64's finaliser (Steele, Lea and Flood 2014): a well-mixed 64-bit hash whose output is
/// the same on every platform and standard library (unlike std::hash or the std::
/// distributions), so a fixed seed gives the same recording everywhere.
constexpr std::uint64_t mix64(std::uint64_t x) {
  x += 0x9E3779B97F4A7C15ULL;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ULL;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBULL;
  return x ^ (x >> 31);
}

/// splitmix64 as a generator: the next value of the sequence `state` is at, and `state` advanced
/// (mix64 of the state before the step, as in the reference implementation).
constexpr std::uint64_t splitmix64_next(std::uint64_t& state) {
  const std::uint64_t z = mix64(state);
  state += 0x9E3779B97F4A7C15ULL;
  return z;
}

}  // namespace wallar::core

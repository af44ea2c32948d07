// SPDX-License-Identifier: Apache-2.0
/// @file fuzz_yaml.cpp
/// @brief Fuzzes the YAML reader: parse, then walk the whole tree through every typed getter.
#include <string>

#include "fuzz_common.hpp"
#include "wallar/drivers/config/yaml.hpp"

namespace {

using wallar::config::YamlNode;
using wallar::fuzz::expect_only_input_errors;

void walk(const YamlNode& node, int depth) {
  if (depth > 64) __builtin_trap();  // the reader caps nesting well below this
  (void)node.path();
  (void)node.line();
  (void)node.file();
  expect_only_input_errors([&] { (void)node.scalar(); });
  expect_only_input_errors([&] { (void)node.as_double(); });
  expect_only_input_errors([&] { (void)node.as_int(); });
  expect_only_input_errors([&] { (void)node.as_bool(); });
  expect_only_input_errors([&] { (void)node.as_doubles(); });
  expect_only_input_errors([&] { (void)node.as_doubles(node.size()); });
  // Matrix shapes from the node itself (OpenCV maps, flat lists, lists of rows) and fixed ones.
  expect_only_input_errors([&] {
    const int n = static_cast<int>(node.size() % 17);
    (void)node.as_matrix(n, 1);
  });
  expect_only_input_errors([&] {
    if (node.is_sequence() && !node.items().empty()) {
      const int rows = static_cast<int>(node.size() % 9);
      const int cols = static_cast<int>(node.items().front().size() % 9);
      (void)node.as_matrix(rows, cols);
    }
  });
  expect_only_input_errors([&] { (void)node.as_matrix(4, 4); });
  expect_only_input_errors([&] { (void)node.as_matrix(3, 3); });
  expect_only_input_errors([&] { node.check_keys({"rows", "cols", "data", "dt"}); });
  expect_only_input_errors([&] { (void)node.at("data"); });
  expect_only_input_errors([&] { (void)node.get_double("rate_hz", 1.0); });
  expect_only_input_errors([&] { (void)node.get_int("rows", 0); });
  expect_only_input_errors([&] { (void)node.get_string("name", ""); });
  expect_only_input_errors([&] { (void)node.get_bool("enabled", false); });
  expect_only_input_errors([&] { node.fail("fuzz"); });

  if (node.is_map()) {
    for (const auto& [key, child] : node.entries()) {
      if (node.find(key) == nullptr) __builtin_trap();  // every entry is findable
      expect_only_input_errors([&, &k = key] { (void)node.at(k); });
      expect_only_input_errors([&, &k = key] { (void)node.get_double(k, 0.0); });
      expect_only_input_errors([&, &k = key] { (void)node.get_int(k, 0); });
      expect_only_input_errors([&, &k = key] { (void)node.get_string(k, ""); });
      expect_only_input_errors([&, &k = key] { (void)node.get_bool(k, false); });
      walk(child, depth + 1);
    }
  } else if (node.is_sequence()) {
    for (const YamlNode& item : node.items()) walk(item, depth + 1);
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  expect_only_input_errors([&] {
    const auto doc =
        wallar::config::YamlDocument::parse(wallar::fuzz::as_text(data, size), "fuzz.yaml");
    if (doc.name() != "fuzz.yaml") __builtin_trap();
    walk(doc.root(), 0);
  });
  return 0;
}

// SPDX-License-Identifier: Apache-2.0
/// @file viewer_files.hpp
/// @brief The live viewer's files (firmware/viewer: the page and its script; three.js from npm,
/// installed by tools/setup into tools/node), built into the binary at compile time, so the
/// page `wallar run --live` serves needs nothing on the headset's disk and nothing from the
/// network.
///
/// Threading: immutable data.
#pragma once

#include <string_view>
#include <vector>

namespace wallar::firmware {

struct ViewerFile {
  const char* path;          //!< as requested: "/", "/viewer.js", "/three.module.js", ...
  const char* content_type;  //!< "text/html; charset=utf-8", "text/javascript"
  std::string_view body;
};

/// Every file of the viewer (the page at "/").
const std::vector<ViewerFile>& viewer_files();

}  // namespace wallar::firmware

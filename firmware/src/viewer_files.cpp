// SPDX-License-Identifier: Apache-2.0
/// @file viewer_files.cpp
/// @brief The viewer's files in the binary's read-only data, each through the assembler's
/// .incbin (paths from CMake: WALLAR_VIEWER_DIR, WALLAR_THREE_DIR; the build depends on them).
#include "wallar/firmware/viewer_files.hpp"

// Defines NAME_begin and NAME_end around the file's bytes (ELF, any architecture's assembler).
#define WALLAR_EMBED(name, file)     \
  asm(".pushsection .rodata\n"       \
      ".balign 16\n"                 \
      ".global wallar_viewer_" #name \
      "_begin\n"                     \
      "wallar_viewer_" #name         \
      "_begin:\n"                    \
      ".incbin \"" file              \
      "\"\n"                         \
      ".global wallar_viewer_" #name \
      "_end\n"                       \
      "wallar_viewer_" #name         \
      "_end:\n"                      \
      ".popsection\n");              \
  extern "C" const char wallar_viewer_##name##_begin[], wallar_viewer_##name##_end[]

WALLAR_EMBED(index, WALLAR_VIEWER_DIR "/index.html");
WALLAR_EMBED(viewer, WALLAR_VIEWER_DIR "/viewer.js");
WALLAR_EMBED(three_module, WALLAR_THREE_DIR "/build/three.module.js");
WALLAR_EMBED(three_core, WALLAR_THREE_DIR "/build/three.core.js");
WALLAR_EMBED(orbit, WALLAR_THREE_DIR "/examples/jsm/controls/OrbitControls.js");
WALLAR_EMBED(three_license, WALLAR_THREE_DIR "/LICENSE");

namespace wallar::firmware {
namespace {

std::string_view bytes(const char* begin, const char* end) {
  return {begin, static_cast<std::size_t>(end - begin)};
}

}  // namespace

const std::vector<ViewerFile>& viewer_files() {
  static const std::vector<ViewerFile> files = {
      {"/", "text/html; charset=utf-8", bytes(wallar_viewer_index_begin, wallar_viewer_index_end)},
      {"/viewer.js", "text/javascript; charset=utf-8",
       bytes(wallar_viewer_viewer_begin, wallar_viewer_viewer_end)},
      {"/three.module.js", "text/javascript; charset=utf-8",
       bytes(wallar_viewer_three_module_begin, wallar_viewer_three_module_end)},
      {"/three.core.js", "text/javascript; charset=utf-8",
       bytes(wallar_viewer_three_core_begin, wallar_viewer_three_core_end)},
      {"/addons/controls/OrbitControls.js", "text/javascript; charset=utf-8",
       bytes(wallar_viewer_orbit_begin, wallar_viewer_orbit_end)},
      {"/three.js-LICENSE.txt", "text/plain; charset=utf-8",
       bytes(wallar_viewer_three_license_begin, wallar_viewer_three_license_end)},
  };
  return files;
}

}  // namespace wallar::firmware

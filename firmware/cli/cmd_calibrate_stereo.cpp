// SPDX-License-Identifier: Apache-2.0
/// @file cmd_calibrate_stereo.cpp
/// @brief `wallar calibrate stereo` (chessboard pairs -> OpenCV YAML, Kalibr camchain, JSON
/// summary) and `wallar calibrate rectify-check` (how well a calibration rectifies real pairs).
#include <glob.h>

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>
#include <optional>
#include <sstream>

#include "commands.hpp"
#include "wallar/core/error.hpp"
#include "wallar/drivers/recording/calibration_files.hpp"
#include "wallar/drivers/recording/euroc.hpp"
#include "wallar/drivers/recording/jpeg.hpp"
#include "wallar/dsp/stereo/stereo_calibration.hpp"
#include "wallar/eval/output.hpp"

namespace wallar::cli {
namespace {

namespace fs = std::filesystem;

struct ImagePairs {
  std::string left_glob, right_glob, list;
};

std::vector<std::string> expand(const std::string& pattern, const char* option) {
  glob_t g{};
  const int rc = ::glob(pattern.c_str(), 0, nullptr, &g);
  std::vector<std::string> out;
  if (rc == 0)
    for (std::size_t i = 0; i < g.gl_pathc; ++i) out.emplace_back(g.gl_pathv[i]);
  globfree(&g);
  if (out.empty())
    throw_input_error(std::string(option) + " '" + pattern + "'", 0, "no file matches");
  std::sort(out.begin(), out.end());
  return out;
}

// Left/right file pairs from two globs (matched by sorted order) or a list file.
std::vector<std::pair<std::string, std::string>> resolve(const ImagePairs& p) {
  std::vector<std::pair<std::string, std::string>> pairs;
  if (!p.list.empty()) {
    std::ifstream in(p.list);
    if (!in) throw_input_error(p.list, 0, "cannot open the list file");
    const fs::path base = fs::path(p.list).parent_path();
    std::string line;
    for (int n = 1; std::getline(in, line); ++n) {
      if (line.find_first_not_of(" \t\r") == std::string::npos || line[0] == '#') continue;
      std::istringstream words(line);
      std::string l, r, extra;
      if (!(words >> l >> r) || (words >> extra))
        throw_input_error(p.list, n, "want two image paths, 'LEFT RIGHT'");
      const auto resolve_path = [&](const std::string& f) {
        return fs::path(f).is_absolute() ? f : (base / f).string();
      };
      pairs.emplace_back(resolve_path(l), resolve_path(r));
    }
    if (pairs.empty()) throw_input_error(p.list, 0, "lists no image pairs");
    return pairs;
  }
  if (p.left_glob.empty() || p.right_glob.empty())
    throw InputError("give the image pairs as --left GLOB --right GLOB or --list FILE");
  const std::vector<std::string> l = expand(p.left_glob, "--left");
  const std::vector<std::string> r = expand(p.right_glob, "--right");
  if (l.size() != r.size())
    throw InputError("--left matches " + std::to_string(l.size()) + " files but --right " +
                     std::to_string(r.size()) + "; pairs are matched by sorted order");
  for (std::size_t i = 0; i < l.size(); ++i) pairs.emplace_back(l[i], r[i]);
  return pairs;
}

cv::Size parse_board_size(const std::string& text) {
  int w = 0, h = 0;
  char x = 0, rest = 0;
  if (std::sscanf(text.c_str(), "%d%c%d%c", &w, &x, &h, &rest) != 3 || (x != 'x' && x != 'X') ||
      w < 2 || h < 2 || w > 100 || h > 100)
    throw InputError("--board-size '" + text +
                     "': want the inner corners per row and column, e.g. 9x6");
  return {w, h};
}

Eigen::MatrixXd eigen_of(const cv::Mat& m) {
  Eigen::MatrixXd out(m.rows, m.cols);
  for (int r = 0; r < m.rows; ++r)
    for (int c = 0; c < m.cols; ++c) out(r, c) = m.at<double>(r, c);
  return out;
}

nlohmann::json camera_json(const CameraCalibration& c) {
  return {{"fx", c.fx}, {"fy", c.fy}, {"cx", c.cx}, {"cy", c.cy}, {"dist", c.distortion}};
}

struct StereoArgs {
  ImagePairs images;
  std::string board_size = "9x6";
  double square_m = 0.025;
  std::string out, kalibr, json;
};

int run_stereo(const StereoArgs& a) {
  const cv::Size inner = parse_board_size(a.board_size);
  const auto pairs = resolve(a.images);
  std::vector<Image> keep_alive;
  std::vector<std::vector<cv::Point2f>> cl, cr;
  std::vector<std::size_t> pair_of_view;
  std::vector<std::string> no_corners;
  cv::Size size;
  for (std::size_t i = 0; i < pairs.size(); ++i) {
    const Image l = recording::load_image_gray(pairs[i].first, size.width, size.height);
    size = {l.width(), l.height()};
    const Image r = recording::load_image_gray(pairs[i].second, size.width, size.height);
    auto found_l = dsp::find_chessboard(dsp::wrap_gray(l), inner);
    auto found_r = dsp::find_chessboard(dsp::wrap_gray(r), inner);
    if (!found_l) no_corners.push_back(pairs[i].first);
    if (!found_r) no_corners.push_back(pairs[i].second);
    if (!found_l || !found_r) continue;
    cl.push_back(std::move(*found_l));
    cr.push_back(std::move(*found_r));
    pair_of_view.push_back(i);
  }
  const dsp::StereoCalibrationParams params;
  if (cl.size() < params.min_views)
    throw InputError("the chessboard (" + a.board_size +
                     " inner corners) was found in both "
                     "images of only " +
                     std::to_string(cl.size()) + " of " + std::to_string(pairs.size()) +
                     " pairs; " + std::to_string(params.min_views) +
                     " are needed (check --board-size)");
  dsp::StereoCalibrationResult r;
  try {
    r = dsp::calibrate_stereo(cl, cr, size, {inner, a.square_m}, params);
  } catch (const std::invalid_argument& e) {
    throw InputError(std::string("calibration failed: ") + e.what());
  }
  const dsp::Rectifier rect(r.rig);
  dsp::VerticalDisparity rows;
  for (std::size_t v : r.views_used) rows.add(dsp::vertical_disparity(rect, cl[v], cr[v]));

  nlohmann::json views = nlohmann::json::array();
  for (std::size_t k = 0; k < r.views_used.size(); ++k) {
    const auto& p = pairs[pair_of_view[r.views_used[k]]];
    views.push_back({{"left", p.first}, {"right", p.second}, {"rms_px", r.view_rms_px[k]}});
  }
  nlohmann::json rejected = nlohmann::json::array();
  for (std::size_t v : r.views_rejected) {
    const auto& p = pairs[pair_of_view[v]];
    rejected.push_back({{"left", p.first}, {"right", p.second}});
  }
  const nlohmann::json summary = {
      {"rms_px", r.rms_px},
      {"views_used", r.views_used.size()},
      {"left", camera_json(r.rig.cams[0])},
      {"right", camera_json(r.rig.cams[1])},
      {"baseline_m", r.baseline_m},
      {"image_size", {size.width, size.height}},
      {"pairs", pairs.size()},
      {"mono_rms_px", {r.mono_rms_px[0], r.mono_rms_px[1]}},
      {"views", views},
      {"views_rejected", rejected},
      {"no_corners", no_corners},
      {"rectified_row_error_px", {{"mean", rows.mean_px}, {"max", rows.max_px}}}};

  // Every output is complete or absent: each is written under a temporary name and renamed.
  if (!a.out.empty()) {
    const recording::ExtraMatrices extra = {{"R1", eigen_of(cv::Mat(rect.R(0)))},
                                            {"R2", eigen_of(cv::Mat(rect.R(1)))},
                                            {"P1", eigen_of(cv::Mat(rect.P(0)))},
                                            {"P2", eigen_of(cv::Mat(rect.P(1)))},
                                            {"Q", eigen_of(cv::Mat(rect.Q()))}};
    eval::write_file_atomically(a.out, recording::format_opencv_stereo_yaml(r.rig, extra));
  }
  if (!a.kalibr.empty())
    eval::write_file_atomically(a.kalibr, recording::format_kalibr_camchain(r.rig));
  if (!a.json.empty()) {
    if (a.json == "-") {
      std::cout << summary.dump(2) << "\n";
      return kExitOk;
    }
    eval::write_file_atomically(a.json, summary.dump(2) + "\n");
  }
  std::printf(
      "wallar calibrate stereo: %zu of %zu pairs used (%zu rejected, %zu without corners)\n"
      "  rms %.3f px (left alone %.3f, right alone %.3f)\n"
      "  left  fx %.2f fy %.2f cx %.2f cy %.2f\n"
      "  right fx %.2f fy %.2f cx %.2f cy %.2f\n"
      "  baseline %.4f m; rectified corner rows differ by %.3f px on average (max %.3f)\n",
      r.views_used.size(), pairs.size(), r.views_rejected.size(), pairs.size() - cl.size(),
      r.rms_px, r.mono_rms_px[0], r.mono_rms_px[1], r.rig.cams[0].fx, r.rig.cams[0].fy,
      r.rig.cams[0].cx, r.rig.cams[0].cy, r.rig.cams[1].fx, r.rig.cams[1].fy, r.rig.cams[1].cx,
      r.rig.cams[1].cy, r.baseline_m, rows.mean_px, rows.max_px);
  for (const std::string& f : no_corners) std::printf("  no chessboard in %s\n", f.c_str());
  return kExitOk;
}

struct CheckArgs {
  std::string calibration, recording;
  ImagePairs images;
  int every = 8;
  double max_mean_px = 0.0;
  bool json = false;
};

int run_check(const CheckArgs& a) {
  std::vector<std::pair<std::string, std::string>> pairs;  // image files, or
  std::optional<recording::EurocRecording> rec;            // a recording's frames (MCAP too)
  std::vector<std::size_t> frames;
  std::string calibration = a.calibration;
  if (!a.recording.empty()) {
    rec.emplace(read_recording_reporting(a.recording));
    if (calibration.empty()) calibration = a.recording;
    const std::size_t n = std::min(rec->cams[0].frames.size(), rec->cams[1].frames.size());
    for (std::size_t i = 0; i < n; i += static_cast<std::size_t>(a.every)) frames.push_back(i);
  } else {
    pairs = resolve(a.images);
  }
  if (calibration.empty()) throw InputError("give --calibration FILE (or a --recording)");
  // An MCAP recording's calibration is inside it; a folder or file is read as before.
  const RigCalibration rig = rec && rec->store && calibration == a.recording
                                 ? rec->rig()
                                 : recording::read_rig_calibration(calibration);
  std::unique_ptr<dsp::Rectifier> rect;
  try {
    rect = std::make_unique<dsp::Rectifier>(rig);
  } catch (const std::invalid_argument& e) {
    throw_input_error(calibration, 0, e.what());
  }
  dsp::VerticalDisparity all;
  const std::size_t count = rec ? frames.size() : pairs.size();
  for (std::size_t k = 0; k < count; ++k) {
    Image l;
    Image r;
    if (rec) {
      l = recording::load_frame_gray(*rec, 0, rec->cams[0].frames[frames[k]]);
      r = recording::load_frame_gray(*rec, 1, rec->cams[1].frames[frames[k]]);
    } else {
      l = recording::load_image_gray(pairs[k].first, rig.cams[0].width_px, rig.cams[0].height_px);
      r = recording::load_image_gray(pairs[k].second, rig.cams[1].width_px, rig.cams[1].height_px);
    }
    all.add(dsp::vertical_disparity_of_features(*rect, dsp::wrap_gray(l), dsp::wrap_gray(r)));
  }
  const bool pass = a.max_mean_px <= 0.0 || (all.count > 0 && all.mean_px <= a.max_mean_px);
  if (a.json) {
    std::cout << nlohmann::json{{"calibration", calibration},
                                {"pairs", count},
                                {"matches", all.count},
                                {"mean_px", all.mean_px},
                                {"median_px", all.median_px},
                                {"max_px", all.max_px},
                                {"pass", pass}}
                     .dump(2)
              << "\n";
  } else {
    std::printf(
        "wallar calibrate rectify-check: %zu pairs, %zu matched features; rectified rows differ "
        "by %.3f px on average (median %.3f, max %.3f)\n",
        count, all.count, all.mean_px, all.median_px, all.max_px);
  }
  if (!pass) {
    std::fprintf(stderr, "wallar: error: mean row difference %.3f px exceeds --max-mean-px %.3f\n",
                 all.mean_px, a.max_mean_px);
    return kExitFailure;
  }
  return kExitOk;
}

void add_image_pair_options(CLI::App& cmd, ImagePairs& p) {
  auto* l = cmd.add_option("--left", p.left_glob, "Left images, a quoted glob ('left*.jpg')");
  auto* r = cmd.add_option("--right", p.right_glob,
                           "Right images, a quoted glob (sorted order pairs them)");
  auto* list = cmd.add_option("--list", p.list, "A file of 'LEFT RIGHT' lines instead of globs");
  l->needs(r);
  r->needs(l);
  list->excludes(l);
  list->excludes(r);
}

}  // namespace

void add_calibrate_stereo_commands(CLI::App& calibrate, std::function<int()>& run) {
  auto s = std::make_shared<StereoArgs>();
  CLI::App* cmd = calibrate.add_subcommand(
      "stereo", "Stereo calibration from chessboard image pairs (PNG or JPEG)");
  add_image_pair_options(*cmd, s->images);
  cmd->add_option("--board-size", s->board_size, "Inner corners per row x column")
      ->capture_default_str();
  cmd->add_option("--square-m", s->square_m, "Side of one square [m]")
      ->check(CLI::Range(1e-4, 10.0))
      ->capture_default_str();
  cmd->add_option("--out", s->out, "OpenCV stereo YAML to write (K1 D1 K2 D2 R T R1 R2 P1 P2 Q)");
  cmd->add_option("--kalibr", s->kalibr, "Kalibr camchain YAML to write");
  cmd->add_option("--json", s->json, "Summary as JSON to this file ('-': stdout)");
  cmd->callback([s, &run] { run = [s] { return run_stereo(*s); }; });

  auto c = std::make_shared<CheckArgs>();
  CLI::App* check = calibrate.add_subcommand(
      "rectify-check",
      "How far apart matched features land vertically after rectification (0 for a perfect "
      "calibration)");
  check->add_option("--calibration", c->calibration,
                    "EuRoC folder, Kalibr camchain or OpenCV stereo YAML (default: the "
                    "recording's own sensor.yaml)");
  auto* rec = check->add_option("--recording", c->recording,
                                "Recording (EuRoC folder or .mcap) to take pairs from");
  check->add_option("--every", c->every, "Use every Nth pair of the recording")
      ->check(CLI::Range(1, 100000))
      ->capture_default_str();
  add_image_pair_options(*check, c->images);
  rec->excludes(check->get_option("--left"));
  rec->excludes(check->get_option("--list"));
  check
      ->add_option("--max-mean-px", c->max_mean_px,
                   "Fail (exit 1) when the mean row difference is above this")
      ->check(CLI::NonNegativeNumber);
  check->add_flag("--json", c->json, "Print the result as JSON on stdout");
  check->callback([c, &run] { run = [c] { return run_check(*c); }; });
}

}  // namespace wallar::cli

// SPDX-License-Identifier: Apache-2.0
/// @file marker.cpp
/// @brief The parts of the marker ground truth that need no OpenCV contrib: dictionary names,
/// view poses, the wall plane of a pose, and the accuracy study (which renders and estimates
/// through marker_aruco.cpp or, without ArUco, fails at its first render).
#include "wallar/eval/marker.hpp"

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <random>
#include <sstream>

#include "wallar/core/error.hpp"
#include "wallar/dsp/eval/metrics.hpp"

namespace wallar::eval {
namespace {

struct DictionaryEntry {
  const char* name;
  int cv_id;    //!< cv::aruco::PREDEFINED_DICTIONARY_NAME
  int markers;  //!< ids 0 .. markers-1
};

// OpenCV 4.6's PREDEFINED_DICTIONARY_NAME, in its order.
constexpr std::array<DictionaryEntry, 21> kDictionaries{{
    {"4X4_50", 0, 50},
    {"4X4_100", 1, 100},
    {"4X4_250", 2, 250},
    {"4X4_1000", 3, 1000},
    {"5X5_50", 4, 50},
    {"5X5_100", 5, 100},
    {"5X5_250", 6, 250},
    {"5X5_1000", 7, 1000},
    {"6X6_50", 8, 50},
    {"6X6_100", 9, 100},
    {"6X6_250", 10, 250},
    {"6X6_1000", 11, 1000},
    {"7X7_50", 12, 50},
    {"7X7_100", 13, 100},
    {"7X7_250", 14, 250},
    {"7X7_1000", 15, 1000},
    {"ARUCO_ORIGINAL", 16, 1024},
    {"APRILTAG_16h5", 17, 30},
    {"APRILTAG_25h9", 18, 35},
    {"APRILTAG_36h10", 19, 2320},
    {"APRILTAG_36h11", 20, 587},
}};

std::string upper(std::string_view s) {
  std::string out(s);
  for (char& c : out) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  return out;
}

const DictionaryEntry& find_dictionary(const std::string& name) {
  std::string key = upper(name);
  if (key.rfind("DICT_", 0) == 0) key.erase(0, 5);
  for (const auto& entry : kDictionaries) {
    if (upper(entry.name) == key) return entry;
  }
  std::string known;
  for (const auto& entry : kDictionaries)
    known += (known.empty() ? "" : ", ") + std::string(entry.name);
  throw_input_error("--dictionary", 0,
                    "unknown ArUco dictionary '" + printable(name) + "' (known: " + known + ")");
}

double median(std::vector<double> v) {
  if (v.empty()) return std::nan("");
  std::sort(v.begin(), v.end());
  const std::size_t m = v.size() / 2;
  return v.size() % 2 == 1 ? v[m] : 0.5 * (v[m - 1] + v[m]);
}

/// A uniform double in [lo, hi) from the generator's raw bits (no std distributions: their
/// output differs between standard libraries).
double uniform(std::mt19937_64& rng, double lo, double hi) {
  const double u = static_cast<double>(rng() >> 11) * 0x1.0p-53;
  return lo + (hi - lo) * u;
}

/// JSON number, or null for NaN (no errors to summarise).
nlohmann::json number_or_null(double v) { return std::isfinite(v) ? nlohmann::json(v) : nullptr; }

struct StudyRow {
  double distance_m;
  double angle_deg;
  bool found;
  double normal_error_deg;
  double offset_error_m;
};

nlohmann::json summarise(const std::vector<StudyRow>& rows, double max_distance_m,
                         double max_angle_deg, double min_distance_m = 0.0,
                         double min_angle_deg = 0.0) {
  std::vector<double> normal, offset;
  std::size_t views = 0;
  for (const auto& r : rows) {
    if (r.distance_m > max_distance_m + 1e-9 || r.angle_deg > max_angle_deg + 1e-9 ||
        r.distance_m < min_distance_m - 1e-9 || r.angle_deg < min_angle_deg - 1e-9) {
      continue;
    }
    ++views;
    if (!r.found) continue;
    normal.push_back(r.normal_error_deg);
    offset.push_back(r.offset_error_m);
  }
  const auto max_of = [](const std::vector<double>& v) {
    return v.empty() ? std::nan("") : *std::max_element(v.begin(), v.end());
  };
  return nlohmann::json{{"views", views},
                        {"found", normal.size()},
                        {"median_normal_error_deg", number_or_null(median(normal))},
                        {"median_offset_error_m", number_or_null(median(offset))},
                        {"max_normal_error_deg", number_or_null(max_of(normal))},
                        {"max_offset_error_m", number_or_null(max_of(offset))}};
}

}  // namespace

const std::vector<std::string>& marker_dictionary_names() {
  static const std::vector<std::string> names = [] {
    std::vector<std::string> v;
    for (const auto& entry : kDictionaries) v.emplace_back(entry.name);
    return v;
  }();
  return names;
}

int marker_dictionary_id(const std::string& name) { return find_dictionary(name).cv_id; }

void check_marker_spec(const MarkerSpec& spec) {
  const DictionaryEntry& dict = find_dictionary(spec.dictionary);
  if (!(spec.size_m > 0.0) || !std::isfinite(spec.size_m)) {
    throw_input_error("--size-m", 0, "the marker size must be a positive number of metres");
  }
  if (spec.id < 0 || spec.id >= dict.markers) {
    throw_input_error("--id", 0,
                      "marker id " + std::to_string(spec.id) + " is not in " + dict.name +
                          " (ids 0.." + std::to_string(dict.markers - 1) + ")");
  }
}

Eigen::Isometry3d marker_view_pose(double distance_m, double angle_deg, double roll_deg,
                                   double yaw_deg, double pitch_deg) {
  constexpr double kRad = M_PI / 180.0;
  const Eigen::Matrix3d R_cam_dir = (Eigen::AngleAxisd(yaw_deg * kRad, Eigen::Vector3d::UnitY()) *
                                     Eigen::AngleAxisd(pitch_deg * kRad, Eigen::Vector3d::UnitX()))
                                        .toRotationMatrix();
  // Head-on: the marker's x along the camera's x, its y up (the camera's -y), its z toward the
  // camera; then turned about its own vertical axis and rolled about its normal.
  const Eigen::Matrix3d R_dir_facing = Eigen::Vector3d(1.0, -1.0, -1.0).asDiagonal();
  Eigen::Isometry3d T_cam_marker = Eigen::Isometry3d::Identity();
  T_cam_marker.linear() = R_cam_dir * R_dir_facing *
                          Eigen::AngleAxisd(angle_deg * kRad, Eigen::Vector3d::UnitY()) *
                          Eigen::AngleAxisd(roll_deg * kRad, Eigen::Vector3d::UnitZ());
  T_cam_marker.translation() = distance_m * (R_cam_dir * Eigen::Vector3d::UnitZ());
  return T_cam_marker;
}

Plane marker_plane(const Eigen::Isometry3d& T_cam_marker) {
  const Eigen::Vector3d n = T_cam_marker.linear().col(2);
  const Plane plane{n, n.dot(T_cam_marker.translation())};
  return plane.facing(Eigen::Vector3d::Zero());
}

nlohmann::json run_marker_study(const MarkerStudyOptions& options, const CameraCalibration& cam,
                                OutputDir& out) {
  check_marker_spec(options.spec);
  if (options.seeds < 1) throw std::invalid_argument("run_marker_study: seeds must be >= 1");
  const std::vector<double> distances_m{0.4, 0.6, 0.8, 1.0, 1.5, 2.0, 2.5, 3.0};
  const std::vector<double> angles_deg{0.0, 15.0, 30.0, 45.0, 60.0};

  CsvTable table({"distance_m", "angle_deg", "seed", "found", "normal_error_deg", "offset_error_m",
                  "reprojection_rms_px"});
  std::vector<StudyRow> rows;
  for (std::size_t di = 0; di < distances_m.size(); ++di) {
    for (std::size_t ai = 0; ai < angles_deg.size(); ++ai) {
      for (int s = 0; s < options.seeds; ++s) {
        const std::uint64_t seed = options.seed + static_cast<std::uint64_t>(s);
        // The view's roll and direction: from the seed and the grid cell, so each cell sees its
        // own poses and adding distances or angles changes no other cell's.
        std::mt19937_64 rng(seed * 0x9E3779B97F4A7C15ull + di * 1000u + ai);
        const double roll_deg = uniform(rng, -20.0, 20.0);
        const double yaw_deg = uniform(rng, -4.0, 4.0);
        const double pitch_deg = uniform(rng, -4.0, 4.0);
        const Eigen::Isometry3d T_cam_marker =
            marker_view_pose(distances_m[di], angles_deg[ai], roll_deg, yaw_deg, pitch_deg);
        const Image image =
            render_marker_view(cam, T_cam_marker, options.spec, options.noise_sigma, seed);
        const auto estimate = estimate_marker_plane(image, cam, options.spec);
        StudyRow row{distances_m[di], angles_deg[ai], estimate.has_value(), std::nan(""),
                     std::nan("")};
        table.add(distances_m[di]).add(angles_deg[ai]).add(static_cast<double>(seed));
        if (estimate) {
          const dsp::PlaneError e = dsp::plane_error(estimate->plane, marker_plane(T_cam_marker));
          row.normal_error_deg = e.angle_deg;
          row.offset_error_m = e.offset_m;
          table.add(1.0).add(e.angle_deg).add(e.offset_m).add(estimate->reprojection_rms_px);
        } else {
          table.add(0.0).add("").add("").add("");
        }
        table.end_row();
        rows.push_back(row);
      }
    }
  }
  out.write("marker_accuracy.csv", table.text());

  // Medians per distance, one column per viewing angle, for the figure (gnuplot draws one
  // unbroken curve per column).
  std::vector<std::string> columns{"distance_m"};
  for (const double a : angles_deg) {
    columns.push_back("median_normal_error_deg_at_" + std::to_string(static_cast<int>(a)) + "deg");
  }
  for (const double a : angles_deg) {
    columns.push_back("median_offset_error_mm_at_" + std::to_string(static_cast<int>(a)) + "deg");
  }
  CsvTable medians(columns);
  nlohmann::json cells = nlohmann::json::array();
  for (const double d : distances_m) {
    medians.add(d);
    std::vector<nlohmann::json> at_distance;
    for (const double a : angles_deg) at_distance.push_back(summarise(rows, d, a, d, a));
    for (const auto& c : at_distance) {
      const auto& v = c["median_normal_error_deg"];
      if (v.is_null())
        medians.add("NaN");
      else
        medians.add(v.get<double>());
    }
    for (const auto& c : at_distance) {
      const auto& v = c["median_offset_error_m"];
      if (v.is_null())
        medians.add("NaN");
      else
        medians.add(v.get<double>() * 1000.0);
    }
    medians.end_row();
    for (std::size_t ai = 0; ai < angles_deg.size(); ++ai) {
      nlohmann::json c = at_distance[ai];
      c["distance_m"] = d;
      c["angle_deg"] = angles_deg[ai];
      cells.push_back(std::move(c));
    }
  }
  out.write("marker_accuracy_medians.csv", medians.text());

  std::ostringstream gp;
  gp << "# Marker ground truth: plane error of the ArUco estimate against the rendered truth.\n"
     << "# Medians over " << options.seeds << " renders per point (marker_accuracy.csv has each).\n"
     << "set multiplot layout 1,2 title \"ArUco " << options.spec.dictionary << ", "
     << options.spec.size_m * 1000.0 << " mm marker, " << cam.name << " " << cam.width_px << "x"
     << cam.height_px << ", noise sigma " << options.noise_sigma << "\"\n"
     << "set key top left\nset grid\nset logscale y\nset xrange [0.3:3.1]\n"
     << "set xlabel \"distance [m]\"\n"
     << "set ylabel \"normal error [deg]\"\n"
     << "plot for [i=0:" << angles_deg.size() - 1
     << "] 'marker_accuracy_medians.csv' using 1:(column(2+i)) with linespoints title sprintf('%d "
        "deg', int(word('";
  for (std::size_t ai = 0; ai < angles_deg.size(); ++ai) {
    gp << (ai ? " " : "") << static_cast<int>(angles_deg[ai]);
  }
  gp << "', i+1))), 0.5 with lines dashtype 2 lc rgb 'black' title 'thesis ARToolKit (<=1 m, <=45 "
        "deg)'\n"
     << "set ylabel \"offset error [mm]\"\n"
     << "plot for [i=0:" << angles_deg.size() - 1
     << "] 'marker_accuracy_medians.csv' using 1:(column(" << 2 + angles_deg.size()
     << "+i)) with linespoints title sprintf('%d deg', int(word('";
  for (std::size_t ai = 0; ai < angles_deg.size(); ++ai) {
    gp << (ai ? " " : "") << static_cast<int>(angles_deg[ai]);
  }
  gp << "', i+1))), 3.0 with lines dashtype 2 lc rgb 'black' title 'thesis ARToolKit (<=1 m, <=45 "
        "deg)'\n"
     << "unset multiplot\n";
  out.plot("marker_accuracy", gp.str(), 1300, 560);

  std::size_t found = 0;
  for (const auto& r : rows) found += r.found ? 1 : 0;
  nlohmann::json summary{
      {"experiment", "marker_accuracy"},
      {"camera", cam.name},
      {"marker",
       {{"dictionary", options.spec.dictionary},
        {"id", options.spec.id},
        {"size_m", options.spec.size_m}}},
      {"noise_sigma", options.noise_sigma},
      {"seeds", options.seeds},
      {"first_seed", options.seed},
      {"views", rows.size()},
      {"found", found},
      {"error_measure",
       "normal: angle between the normals; offset: distance from the estimated "
       "plane to the true plane's point nearest the camera (dsp::plane_error)"},
      {"within_1m_45deg", summarise(rows, 1.0, 45.0)},
      {"at_3m_60deg", summarise(rows, 3.0, 60.0, 3.0, 60.0)},
      {"thesis_artoolkit_within_1m_45deg", {{"normal_error_deg", 0.5}, {"offset_error_m", 0.003}}},
      {"cells", cells}};
  out.write("marker_summary.json", summary.dump(2) + "\n");
  return summary;
}

}  // namespace wallar::eval

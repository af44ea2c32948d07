// SPDX-License-Identifier: Apache-2.0
/// @file marker.hpp
/// @brief Wall ground truth from a square ArUco marker on the wall (issue 4, item 5): find the
/// marker in a gray image, estimate its pose with the camera's calibration (lens distortion
/// included) and hand back the wall's plane in the camera frame. The thesis used a 177 mm
/// ARToolKit marker for the same job (about 3 mm and 0.5 degrees within 1 m and 45 degrees);
/// run_marker_study() measures what this one achieves on rendered views of known pose.
///
/// Marker frame (OpenCV's): origin at the marker's centre, x to its right, y up, z out of the
/// printed face toward whoever looks at it; size_m is the side of the black square.
///
/// ArUco lives in OpenCV contrib, which only the host has: builds without it (WALLAR_HAVE_ARUCO
/// undefined, e.g. the device build) keep this interface, aruco_available() is false and every
/// function that needs the marker throws std::runtime_error saying so.
///
/// Threading: the functions are reentrant (no shared state); call them from any thread.
/// OpenCV may use its own worker threads inside detection (OPENCV_FOR_THREADS_NUM caps them).
#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "wallar/core/calibration.hpp"
#include "wallar/core/image.hpp"
#include "wallar/core/plane.hpp"
#include "wallar/eval/output.hpp"

namespace wallar::eval {

/// True when this build has OpenCV contrib's ArUco module.
bool aruco_available();

/// Which marker to look for.
struct MarkerSpec {
  double size_m = 0.177;              //!< side of the black square [m]
  std::string dictionary = "4X4_50";  //!< OpenCV's predefined dictionary, without "DICT_"
  int id = 0;                         //!< the marker's id in the dictionary
};

/// The dictionary names accepted in MarkerSpec::dictionary (4X4_50 ... 7X7_1000,
/// ARUCO_ORIGINAL, APRILTAG_16h5 ... APRILTAG_36h11; case-insensitive, "DICT_" optional).
const std::vector<std::string>& marker_dictionary_names();

/// OpenCV's PREDEFINED_DICTIONARY_NAME value for `name`. Throws InputError
/// "--dictionary: unknown ArUco dictionary 'X' (known: ...)" for an unknown name.
int marker_dictionary_id(const std::string& name);

/// Checks spec (size > 0, known dictionary, id within the dictionary): InputError naming the
/// bad field otherwise. Needs ArUco for the id range (without it only the rest is checked).
void check_marker_spec(const MarkerSpec& spec);

/// The marker's pose for a view of it: its centre `distance_m` from the camera along the ray
/// through the camera's principal point turned by (yaw_deg, pitch_deg), its normal turned
/// `angle_deg` away from that ray about the marker's vertical axis, and rolled `roll_deg`
/// about its normal. angle_deg is the viewing angle the thesis quotes (0 = head-on).
Eigen::Isometry3d marker_view_pose(double distance_m, double angle_deg, double roll_deg = 0.0,
                                   double yaw_deg = 0.0, double pitch_deg = 0.0);

/// The marker's plane in the camera frame, n toward the camera (n.p - d = 0, d < 0).
Plane marker_plane(const Eigen::Isometry3d& T_cam_marker);

/// A gray image of cam's size: the marker (with a white quiet zone of one and a half cells) on a
/// softly textured wall that is the marker's plane, seen at T_cam_marker through cam's
/// projection including its lens distortion (radial-tangential or equidistant). Pixels on or
/// near the paper are the mean of 16x16 samples across them (edges land within 1/32 px), the
/// wall's smooth texture is taken at the pixel centre; then Gaussian noise of noise_sigma gray
/// levels from a mt19937_64 seeded with `seed` (the same arguments give the same image). No
/// blur, no lighting changes: an ideal camera whose calibration is exactly `cam`.
/// Throws InputError for a bad spec or an unsupported camera model.
Image render_marker_view(const CameraCalibration& cam, const Eigen::Isometry3d& T_cam_marker,
                         const MarkerSpec& spec, double noise_sigma, std::uint64_t seed);

struct MarkerEstimate {
  int id = 0;
  Eigen::Isometry3d T_cam_marker = Eigen::Isometry3d::Identity();
  Plane plane;                       //!< camera frame, n toward the camera
  double reprojection_rms_px = 0.0;  //!< the four corners, through the distortion model
};

/// Finds marker spec.id of spec.dictionary in `gray` (kGray8, cam's size; std::invalid_argument
/// otherwise) with cv::aruco::detectMarkers, refines its corners (cornerSubPix, then a straight
/// line fitted to each of its four edges after undistortion, the corners where they meet), and
/// estimates its pose: IPPE for squares on the corner rays, the better of its two solutions,
/// then Levenberg-Marquardt. Nothing when the marker is not in the image, or when no square
/// explains its corners (reprojection rms above 3 px).
std::optional<MarkerEstimate> estimate_marker_plane(const Image& gray, const CameraCalibration& cam,
                                                    const MarkerSpec& spec);

struct MarkerStudyOptions {
  MarkerSpec spec;
  std::uint64_t seed = 1;    //!< first seed; each view is rendered with seeds seed .. seed+seeds-1
  double noise_sigma = 2.0;  //!< [gray levels]
  int seeds = 5;             //!< renders per (distance, angle)
};

/// Renders the marker at distances 0.4 .. 3.0 m and viewing angles 0 .. 60 degrees (each seed
/// also draws a roll within +-20 degrees and a direction within +-4 degrees of the optical
/// axis), estimates its plane, and writes marker_accuracy.csv (distance_m, angle_deg, seed,
/// found, normal_error_deg, offset_error_m, reprojection_rms_px), marker_accuracy.png (with
/// its .gp) and marker_summary.json into `out`. Returns the summary: medians and maxima within
/// 1 m and 45 degrees (the thesis's range), at 3 m / 60 degrees, and per distance and angle.
nlohmann::json run_marker_study(const MarkerStudyOptions& options, const CameraCalibration& cam,
                                OutputDir& out);

}  // namespace wallar::eval

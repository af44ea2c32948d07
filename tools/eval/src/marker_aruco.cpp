// SPDX-License-Identifier: Apache-2.0
/// @file marker_aruco.cpp
/// @brief The marker ground truth with OpenCV contrib's ArUco module (host builds): rendering a
/// marker view through the lens model, and detecting the marker and estimating its pose.
///
/// The lens model is our own (both of EuRoC's: radial-tangential and equidistant), used the same
/// way by the renderer and the estimator: the renderer undistorts every pixel to its ray, the
/// estimator undistorts the detected corners and solves the pose on the pinhole rays.
#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <opencv2/aruco.hpp>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>
#include <random>
#include <stdexcept>

#include "wallar/core/error.hpp"
#include "wallar/eval/marker.hpp"

namespace wallar::eval {
namespace {

/// Pinhole projection with lens distortion, between normalized image coordinates (x/z, y/z)
/// and pixels.
class Lens {
 public:
  explicit Lens(const CameraCalibration& cam) : fx_(cam.fx), fy_(cam.fy), cx_(cam.cx), cy_(cam.cy) {
    if (!(fx_ > 0.0) || !(fy_ > 0.0)) {
      throw_input_error(cam.name, 0, "camera calibration has no focal length");
    }
    if (cam.distortion_model == "equidistant") {
      equidistant_ = true;
      if (cam.distortion.size() != 4) {
        throw_input_error(cam.name, 0, "equidistant distortion needs 4 coefficients");
      }
    } else if (cam.distortion_model == "radial-tangential" || cam.distortion_model == "none") {
      if (cam.distortion.size() > 5) {
        throw_input_error(cam.name, 0, "radial-tangential distortion has at most 5 coefficients");
      }
    } else {
      throw_input_error(cam.name, 0,
                        "distortion model '" + printable(cam.distortion_model) +
                            "' is not supported by the marker tools");
    }
    for (std::size_t i = 0; i < cam.distortion.size(); ++i) k_[i] = cam.distortion[i];
  }

  /// Undistorted normalized coordinates -> distorted normalized coordinates.
  [[nodiscard]] Eigen::Vector2d distort(const Eigen::Vector2d& x) const {
    const double r2 = x.squaredNorm();
    if (equidistant_) {
      const double r = std::sqrt(r2);
      if (r < 1e-12) return x;
      const double th = std::atan(r);
      const double th2 = th * th;
      const double thd = th * (1.0 + th2 * (k_[0] + th2 * (k_[1] + th2 * (k_[2] + th2 * k_[3]))));
      return x * (thd / r);
    }
    const double radial = 1.0 + r2 * (k_[0] + r2 * (k_[1] + r2 * k_[4]));
    const double xy = x.x() * x.y();
    return {x.x() * radial + 2.0 * k_[2] * xy + k_[3] * (r2 + 2.0 * x.x() * x.x()),
            x.y() * radial + k_[2] * (r2 + 2.0 * x.y() * x.y()) + 2.0 * k_[3] * xy};
  }

  /// d(distorted)/d(undistorted) by central differences.
  [[nodiscard]] Eigen::Matrix2d distort_jacobian(const Eigen::Vector2d& x) const {
    constexpr double h = 1e-7;
    Eigen::Matrix2d J;
    for (int i = 0; i < 2; ++i) {
      Eigen::Vector2d dx = Eigen::Vector2d::Zero();
      dx[i] = h;
      J.col(i) = (distort(x + dx) - distort(x - dx)) / (2.0 * h);
    }
    return J;
  }

  [[nodiscard]] Eigen::Vector2d to_pixel(const Eigen::Vector2d& distorted) const {
    return {fx_ * distorted.x() + cx_, fy_ * distorted.y() + cy_};
  }

  [[nodiscard]] Eigen::Vector2d project(const Eigen::Vector3d& p_cam) const {
    return to_pixel(distort(p_cam.head<2>() / p_cam.z()));
  }

  /// Pixel -> undistorted normalized coordinates by Newton's method from `x` (a guess on
  /// entry). False when it does not converge (outside the model's invertible range).
  bool unproject(const Eigen::Vector2d& px, Eigen::Vector2d& x) const {
    const Eigen::Vector2d target((px.x() - cx_) / fx_, (px.y() - cy_) / fy_);
    for (int iter = 0; iter < 50; ++iter) {
      const Eigen::Vector2d e = distort(x) - target;
      if (e.norm() < 1e-13) return true;
      const Eigen::Matrix2d J = distort_jacobian(x);
      if (std::abs(J.determinant()) < 1e-12) return false;
      x -= J.inverse() * e;
      if (!x.allFinite()) return false;
    }
    return (distort(x) - target).norm() < 1e-9;
  }

  /// d(pixel)/d(undistorted normalized) at x.
  [[nodiscard]] Eigen::Matrix2d pixel_jacobian(const Eigen::Vector2d& x) const {
    return Eigen::Vector2d(fx_, fy_).asDiagonal() * distort_jacobian(x);
  }

  [[nodiscard]] Eigen::Vector2d guess(const Eigen::Vector2d& px) const {
    return {(px.x() - cx_) / fx_, (px.y() - cy_) / fy_};
  }

 private:
  double fx_, fy_, cx_, cy_;
  bool equidistant_ = false;
  double k_[5] = {0.0, 0.0, 0.0, 0.0, 0.0};
};

cv::Ptr<cv::aruco::Dictionary> dictionary(const MarkerSpec& spec) {
  return cv::aruco::getPredefinedDictionary(marker_dictionary_id(spec.dictionary));
}

// Gray levels of the rendered scene: printed black and white under even light, a mid-gray wall.
constexpr double kBlack = 35.0;
constexpr double kWhite = 215.0;
constexpr double kBeyondWall = 90.0;  //!< rays that miss the wall plane

/// Above this the four corners are not the image of a square: not a usable estimate.
constexpr double kMaxReprojectionRmsPx = 3.0;

/// A standard normal deviate from raw generator bits (Box-Muller).
double normal(std::mt19937_64& rng) {
  const double u1 = (static_cast<double>(rng() >> 11) + 0.5) * 0x1.0p-53;
  const double u2 = static_cast<double>(rng() >> 11) * 0x1.0p-53;
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * M_PI * u2);
}

/// Bilinear interpolation of an 8-bit image at (x, y), pixel centres at integers; false outside.
bool sample(const cv::Mat& img, double x, double y, double& value) {
  const double fx = std::floor(x), fy = std::floor(y);
  const int x0 = static_cast<int>(fx), y0 = static_cast<int>(fy);
  if (x0 < 0 || y0 < 0 || x0 + 1 >= img.cols || y0 + 1 >= img.rows) return false;
  const double ax = x - fx, ay = y - fy;
  const std::uint8_t* r0 = img.ptr<std::uint8_t>(y0);
  const std::uint8_t* r1 = img.ptr<std::uint8_t>(y0 + 1);
  value = (1.0 - ay) * ((1.0 - ax) * r0[x0] + ax * r0[x0 + 1]) +
          ay * ((1.0 - ax) * r1[x0] + ax * r1[x0 + 1]);
  return true;
}

/// The marker's corners as rays (undistorted normalized coordinates) from its four edges: along
/// the middle of each side, where the black border meets the white paper, the edge's position
/// across it from the area under the normalized intensity profile (exact for an area-sampled
/// straight edge, whatever its sub-pixel phase); the edge points undistorted and a straight line
/// fitted to each side; adjacent lines intersected. False when a side yields too few points.
bool edge_corners(const cv::Mat& img, const Lens& lens,
                  const std::array<Eigen::Vector2d, 4>& corners_px,
                  std::array<Eigen::Vector2d, 4>& corner_rays) {
  const Eigen::Vector2d centre =
      0.25 * (corners_px[0] + corners_px[1] + corners_px[2] + corners_px[3]);
  double min_side_px = 1e9;
  for (std::size_t i = 0; i < 4; ++i) {
    min_side_px = std::min(min_side_px, (corners_px[(i + 1) % 4] - corners_px[i]).norm());
  }
  // Half-length of the profile: within the black border cell inside, the white paper outside.
  // (At least 1.5 px so that its ends are flat, at most 4 px.)
  constexpr int kCellsAcross = 6;  // the smallest marker (4x4 code) has 6 cells across
  const double half_px = std::clamp(0.45 * min_side_px / kCellsAcross, 1.5, 4.0);
  constexpr double kStepPx = 0.1;
  const int steps = static_cast<int>(std::lround(2.0 * half_px / kStepPx));
  std::array<Eigen::Vector3d, 4> lines;  // (a, b, c): a x + b y = c in normalized coordinates
  for (std::size_t i = 0; i < 4; ++i) {
    const Eigen::Vector2d a = corners_px[i], b = corners_px[(i + 1) % 4];
    const double length_px = (b - a).norm();
    if (length_px < 8.0) return false;
    const Eigen::Vector2d along = (b - a) / length_px;
    Eigen::Vector2d across(-along.y(), along.x());  // pointing out of the marker
    if (across.dot(0.5 * (a + b) - centre) < 0.0) across = -across;
    std::vector<Eigen::Vector2d> points;
    const int count = static_cast<int>(length_px * 0.7);
    for (int k = 0; k <= count; ++k) {
      const Eigen::Vector2d p = a + (b - a) * (0.15 + 0.7 * k / std::max(count, 1));
      std::vector<double> profile(static_cast<std::size_t>(steps) + 1);
      bool inside = true;
      for (int j = 0; j <= steps && inside; ++j) {
        const Eigen::Vector2d q = p + across * (-half_px + j * kStepPx);
        inside = sample(img, q.x(), q.y(), profile[static_cast<std::size_t>(j)]);
      }
      if (!inside) continue;
      // Dark and light levels: the profile's first and last quarter pixel.
      const int ends = std::max(1, static_cast<int>(std::lround(0.25 / kStepPx)));
      double dark = 0.0, light = 0.0;
      for (int j = 0; j < ends; ++j) {
        dark += profile[static_cast<std::size_t>(j)];
        light += profile[static_cast<std::size_t>(steps - j)];
      }
      dark /= ends;
      light /= ends;
      if (light - dark < 20.0) continue;  // no clear edge here
      double area = 0.0;                  // trapezoid rule over the normalized profile
      for (int j = 0; j < steps; ++j) {
        const double v0 = (profile[static_cast<std::size_t>(j)] - dark) / (light - dark);
        const double v1 = (profile[static_cast<std::size_t>(j + 1)] - dark) / (light - dark);
        area += 0.5 * (v0 + v1) * kStepPx;
      }
      const double edge = half_px - area;  // from p along `across`
      if (std::abs(edge) > 0.75 * half_px) continue;
      const Eigen::Vector2d e_px = p + across * edge;
      Eigen::Vector2d x = lens.guess(e_px);
      if (lens.unproject(e_px, x)) points.push_back(x);
    }
    if (points.size() < 5) return false;
    Eigen::Vector2d mean = Eigen::Vector2d::Zero();
    for (const auto& x : points) mean += x;
    mean /= static_cast<double>(points.size());
    Eigen::Matrix2d scatter = Eigen::Matrix2d::Zero();
    for (const auto& x : points) scatter += (x - mean) * (x - mean).transpose();
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(scatter);
    const Eigen::Vector2d normal = eig.eigenvectors().col(0);  // smallest eigenvalue
    lines[i] = {normal.x(), normal.y(), normal.dot(mean)};
  }
  for (std::size_t i = 0; i < 4; ++i) {
    const Eigen::Vector3d& l0 = lines[(i + 3) % 4];  // the side ending at corner i
    const Eigen::Vector3d& l1 = lines[i];            // the side starting there
    const Eigen::Matrix2d A = (Eigen::Matrix2d() << l0.x(), l0.y(), l1.x(), l1.y()).finished();
    if (std::abs(A.determinant()) < 1e-9) return false;
    corner_rays[i] = A.inverse() * Eigen::Vector2d(l0.z(), l1.z());
  }
  return true;
}

}  // namespace

bool aruco_available() { return true; }

Image render_marker_view(const CameraCalibration& cam, const Eigen::Isometry3d& T_cam_marker,
                         const MarkerSpec& spec, double noise_sigma, std::uint64_t seed) {
  check_marker_spec(spec);
  const Lens lens(cam);
  if (cam.width_px <= 0 || cam.height_px <= 0) {
    throw_input_error(cam.name, 0, "camera calibration has no image size");
  }
  if (!(noise_sigma >= 0.0) || !std::isfinite(noise_sigma)) {
    throw std::invalid_argument("render_marker_view: noise_sigma must be >= 0");
  }
  const cv::Ptr<cv::aruco::Dictionary> dict = dictionary(spec);
  const int cells = dict->markerSize + 2;  // the code and its black border, one cell each
  cv::Mat bits;
  cv::aruco::drawMarker(dict, spec.id, cells, bits, 1);  // one pixel per cell

  const double half_m = 0.5 * spec.size_m;
  const double cell_m = spec.size_m / cells;
  const double quiet_m = half_m + 1.5 * cell_m;  // the white paper around the black square
  const Eigen::Matrix3d R = T_cam_marker.linear();
  const Eigen::Vector3d t = T_cam_marker.translation();
  const Eigen::Vector3d n = R.col(2);
  const double d = n.dot(t);  // the wall: n.p = d in the camera frame
  const Eigen::Vector3d ex = R.col(0), ey = R.col(1);

  // The point of the wall (marker coordinates) seen along the ray (x, y, 1); false when the ray
  // does not reach the wall in front of the camera.
  const auto on_wall = [&](const Eigen::Vector2d& x, Eigen::Vector2d& q) {
    const Eigen::Vector3d ray(x.x(), x.y(), 1.0);
    const double denom = n.dot(ray);
    if (std::abs(denom) < 1e-12) return false;
    const double s = d / denom;
    if (!(s > 0.0)) return false;
    const Eigen::Vector3d p = s * ray - t;
    q = {ex.dot(p), ey.dot(p)};
    return true;
  };
  const auto paper = [&](const Eigen::Vector2d& q) {  // only inside the quiet zone
    if (std::abs(q.x()) < half_m && std::abs(q.y()) < half_m) {
      const int col =
          std::clamp(static_cast<int>(std::floor((q.x() + half_m) / cell_m)), 0, cells - 1);
      const int row =
          std::clamp(static_cast<int>(std::floor((half_m - q.y()) / cell_m)), 0, cells - 1);
      return bits.at<std::uint8_t>(row, col) > 127 ? kWhite : kBlack;
    }
    return kWhite;
  };
  // The wall: soft blotches of about half a metre, no corners or edges to detect, coarse
  // enough not to alias where the wall recedes at 60 degrees.
  const auto wall = [&](const Eigen::Vector2d& q) {
    return 140.0 + 20.0 * std::sin(q.x() * 2.0 * M_PI / 0.47 + 0.3) *
                       std::sin(q.y() * 2.0 * M_PI / 0.61 + 1.1);
  };
  const auto in_quiet = [&](const Eigen::Vector2d& q) {
    return std::abs(q.x()) < quiet_m && std::abs(q.y()) < quiet_m;
  };

  constexpr int kSub = 16;  // samples per pixel and axis near the paper
  Image image = Image::allocate(cam.width_px, cam.height_px, PixelFormat::kGray8);
  std::mt19937_64 rng(seed);
  Eigen::Vector2d row_start_x = lens.guess({0.0, 0.0});
  for (int v = 0; v < cam.height_px; ++v) {
    std::uint8_t* out = image.mutable_data() + std::ptrdiff_t{v} * image.stride_bytes();
    Eigen::Vector2d x = row_start_x;
    for (int u = 0; u < cam.width_px; ++u) {
      const Eigen::Vector2d px(u, v);
      if (!lens.unproject(px, x)) x = lens.guess(px);
      if (u == 0) row_start_x = x;
      // Across one pixel the undistortion is affine to well below 1e-4 px.
      const Eigen::Matrix2d J_x_px = lens.pixel_jacobian(x).inverse();
      double value = kBeyondWall;
      Eigen::Vector2d q;
      if (on_wall(x, q)) {
        // Whole pixel outside the paper: the wall's smooth texture at its centre. Otherwise the
        // mean of kSub x kSub samples.
        bool near_paper = false;
        for (const double cu : {-0.5, 0.5}) {
          for (const double cv_ : {-0.5, 0.5}) {
            Eigen::Vector2d qc;
            if (!on_wall(x + J_x_px * Eigen::Vector2d(cu, cv_), qc) ||
                std::max(std::abs(qc.x()), std::abs(qc.y())) < quiet_m + cell_m) {
              near_paper = true;
            }
          }
        }
        if (!near_paper && !in_quiet(q)) {
          value = wall(q);
        } else {
          const double wall_here = wall(q);
          double sum = 0.0;
          for (int i = 0; i < kSub; ++i) {
            for (int j = 0; j < kSub; ++j) {
              const Eigen::Vector2d offset((j + 0.5) / kSub - 0.5, (i + 0.5) / kSub - 0.5);
              Eigen::Vector2d qs;
              if (!on_wall(x + J_x_px * offset, qs)) {
                sum += kBeyondWall;
              } else {
                sum += in_quiet(qs) ? paper(qs) : wall_here;
              }
            }
          }
          value = sum / (kSub * kSub);
        }
      }
      if (noise_sigma > 0.0) value += noise_sigma * normal(rng);
      out[u] = static_cast<std::uint8_t>(std::clamp(std::lround(value), 0L, 255L));
    }
  }
  return image;
}

std::optional<MarkerEstimate> estimate_marker_plane(const Image& gray, const CameraCalibration& cam,
                                                    const MarkerSpec& spec) {
  check_marker_spec(spec);
  const Lens lens(cam);
  if (gray.empty() || gray.format() != PixelFormat::kGray8) {
    throw std::invalid_argument("estimate_marker_plane: needs an 8-bit gray image");
  }
  if (gray.width() != cam.width_px || gray.height() != cam.height_px) {
    throw std::invalid_argument("estimate_marker_plane: image is " + std::to_string(gray.width()) +
                                "x" + std::to_string(gray.height()) + ", calibration " + cam.name +
                                " is for " + std::to_string(cam.width_px) + "x" +
                                std::to_string(cam.height_px));
  }
  const cv::Mat img(gray.height(), gray.width(), CV_8UC1, const_cast<std::uint8_t*>(gray.data()),
                    static_cast<std::size_t>(gray.stride_bytes()));
  const cv::Ptr<cv::aruco::Dictionary> dict = dictionary(spec);
  const cv::Ptr<cv::aruco::DetectorParameters> params = cv::aruco::DetectorParameters::create();
  // Corners are refined below, with a window fitted to the marker's size in the image.
  params->cornerRefinementMethod = cv::aruco::CORNER_REFINE_NONE;
  std::vector<std::vector<cv::Point2f>> corners;
  std::vector<int> ids;
  cv::aruco::detectMarkers(img, dict, corners, ids, params);

  // The wanted id; if it is seen more than once, the largest.
  int best = -1;
  double best_perimeter_px = 0.0;
  for (std::size_t i = 0; i < ids.size(); ++i) {
    if (ids[i] != spec.id) continue;
    const double perimeter_px = cv::arcLength(corners[i], true);
    if (perimeter_px > best_perimeter_px) {
      best = static_cast<int>(i);
      best_perimeter_px = perimeter_px;
    }
  }
  if (best < 0) return std::nullopt;
  std::vector<cv::Point2f>& found = corners[static_cast<std::size_t>(best)];
  // What CORNER_REFINE_SUBPIX does (cv::cornerSubPix on each corner), with the window's half size
  // at most half a cell so that it stays within the black border on small markers.
  const double cell_px = best_perimeter_px / 4.0 / (dict->markerSize + 2);
  const int half_window_px = std::clamp(static_cast<int>(std::lround(0.5 * cell_px)), 2, 5);
  cv::cornerSubPix(img, found, cv::Size(half_window_px, half_window_px), cv::Size(-1, -1),
                   cv::TermCriteria(cv::TermCriteria::COUNT + cv::TermCriteria::EPS, 100, 0.001));
  std::array<Eigen::Vector2d, 4> corners_px;
  for (std::size_t i = 0; i < 4; ++i) corners_px[i] = {found[i].x, found[i].y};

  // Corners in OpenCV's order (top-left, top-right, bottom-right, bottom-left of the marker as
  // printed), in the marker frame and as rays: from the four edges where that works (cornerSubPix
  // is biased toward the inside of an L-shaped corner by about 0.1 px), else from cornerSubPix.
  std::array<Eigen::Vector2d, 4> corner_rays;
  if (!edge_corners(img, lens, corners_px, corner_rays)) {
    for (std::size_t i = 0; i < 4; ++i) {
      corner_rays[i] = lens.guess(corners_px[i]);
      if (!lens.unproject(corners_px[i], corner_rays[i])) return std::nullopt;
    }
  }
  // The pose is solved for the marker frame turned half a turn about its x axis (z away from the
  // camera): a marker seen head-on is then near the identity rotation, not at the half turn where
  // the rotation vector is singular (OpenCV's IPPE returns garbage there). IPPE_SQUARE wants the
  // corners at (-h, h), (h, h), (h, -h), (-h, -h) in that frame: the marker's BL, BR, TR, TL.
  const double h = 0.5 * spec.size_m;
  const std::vector<cv::Point3d> object{{-h, h, 0.0}, {h, h, 0.0}, {h, -h, 0.0}, {-h, -h, 0.0}};
  constexpr std::array<std::size_t, 4> kCornerOf{3, 2, 1, 0};
  std::vector<cv::Point2d> rays;
  for (const std::size_t c : kCornerOf) rays.emplace_back(corner_rays[c].x(), corner_rays[c].y());
  const cv::Mat K = cv::Mat::eye(3, 3, CV_64F);
  std::vector<cv::Mat> rvecs, tvecs;
  cv::Mat errors;
  const int solutions =
      cv::solvePnPGeneric(object, rays, K, cv::noArray(), rvecs, tvecs, false,
                          cv::SOLVEPNP_IPPE_SQUARE, cv::noArray(), cv::noArray(), errors);
  if (solutions < 1) return std::nullopt;
  int pick = 0;
  for (int i = 1; i < solutions; ++i) {
    if (errors.at<double>(i) < errors.at<double>(pick)) pick = i;
  }
  cv::Mat rvec = rvecs[static_cast<std::size_t>(pick)].clone();
  cv::Mat tvec = tvecs[static_cast<std::size_t>(pick)].clone();
  cv::solvePnPRefineLM(
      object, rays, K, cv::noArray(), rvec, tvec,
      cv::TermCriteria(cv::TermCriteria::COUNT + cv::TermCriteria::EPS, 50, 1e-12));
  cv::Mat R_cv;
  cv::Rodrigues(rvec, R_cv);
  Eigen::Matrix3d R_cam_turned;
  Eigen::Vector3d t_cam;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) R_cam_turned(r, c) = R_cv.at<double>(r, c);
    t_cam[r] = tvec.at<double>(r);
  }
  MarkerEstimate est;
  est.id = spec.id;
  est.T_cam_marker.linear() = R_cam_turned * Eigen::Vector3d(1.0, -1.0, -1.0).asDiagonal();
  est.T_cam_marker.translation() = t_cam;
  if (!(est.T_cam_marker.translation().z() > 0.0)) return std::nullopt;
  est.plane = marker_plane(est.T_cam_marker);
  const std::array<Eigen::Vector3d, 4> corners_marker{
      Eigen::Vector3d(-h, h, 0.0), Eigen::Vector3d(h, h, 0.0), Eigen::Vector3d(h, -h, 0.0),
      Eigen::Vector3d(-h, -h, 0.0)};
  double sum_sq = 0.0;
  for (std::size_t i = 0; i < 4; ++i) {
    sum_sq += (lens.project(est.T_cam_marker * corners_marker[i]) -
               lens.to_pixel(lens.distort(corner_rays[i])))
                  .squaredNorm();
  }
  est.reprojection_rms_px = std::sqrt(sum_sq / 4.0);
  // Four corners that no square explains (a mis-detection): no estimate.
  if (!(est.reprojection_rms_px < kMaxReprojectionRmsPx)) return std::nullopt;
  return est;
}

}  // namespace wallar::eval

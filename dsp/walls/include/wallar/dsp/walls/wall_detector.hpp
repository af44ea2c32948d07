// SPDX-License-Identifier: Apache-2.0
/// @file wall_detector.hpp
/// @brief Backlier-aware RANSAC for walls (thesis §3.3, Algorithm 4), in 3-D and, with a
/// gravity direction, in 2-D on the ground plane; plus horizontal surfaces (floor, ceiling).
///
/// Scores (higher is better):
///  - kRansac:   N_in
///  - kMsac:     sum over inliers of (1 - s^2 / t^2)        (truncated quadratic loss)
///  - kBsf:      N_in - beta * N_back                        (BSF-RANSAC, eq. 3.1, beta >= 0)
///  - kBinomial: N_in * Binomial(N_back; N_in + N_back, rho_b), in log space (B-RANSAC, eq. 3.4)
///  - kContrast: N_inner - w * N_outer - beta * N_back          (N_inner: inliers within t / 2,
///               N_outer the others, w = outer_weight: BSF that a slab through scattered
///               points, as full in its outer half as in its inner one, does not win)
/// A backlier is a point behind the candidate wall seen from the viewpoints (s < -t with the
/// normal turned toward them). A candidate is skipped when a viewpoint lies within
/// min_viewpoint_distance_m of it or viewpoints lie on both sides, and, in 3-D, when its front
/// does not face the viewing direction within +-90 degrees ("goes behind the camera").
///
/// Rounds adapt to the best candidate's inlier ratio (eq. 2.7) for the configured confidence,
/// up to max_rounds. Guided sampling draws the 2nd (and 3rd) point of a sample from the first
/// one's neighbourhood (the 3^dim grid cells around it, NAPSAC-like) in 3 of 4 rounds; the stopping
/// rule then uses the all-inlier probability of that mixed sampler, with the neighbours' inlier
/// fraction measured on the best candidate. Walls are surfaces, clutter fills a volume: a wall
/// point's neighbours are far more often wall points than a random point is. A new best candidate
/// is refined by local optimisation (least-squares refit on its inliers, re-scored, a few times:
/// LO-RANSAC).
///
/// Memory: every buffer is sized in the constructor (max_points); set_points() and the detect
/// calls allocate nothing on the heap.
///
/// Threading: one WallDetector per thread; it is not shared.
#pragma once

#include <Eigen/Geometry>
#include <cmath>
#include <cstdint>
#include <optional>
#include <span>
#include <vector>

#include "wallar/core/hash.hpp"
#include "wallar/core/plane.hpp"
#include "wallar/core/point_cloud.hpp"
#include "wallar/dsp/walls/plane_kernel.hpp"

namespace wallar::dsp {

/// Viewpoints a WallDetector holds (set_viewpoints() refuses more).
inline constexpr std::size_t kMaxViewpoints = 64;
/// Points in the bail-out test's subset (DetectorConfig::bail_out); a multiple of kPointPadding.
inline constexpr std::size_t kBailOutPoints = 256;

enum class ScoreMethod : std::uint8_t { kRansac, kMsac, kBsf, kBinomial, kContrast };
enum class Sampling : std::uint8_t { kUniform, kGuided };

struct DetectorConfig {
  ScoreMethod method = ScoreMethod::kBsf;
  double threshold_m = 0.05;  //!< inlier band half-width t [m]
  double beta = 0.5;          //!< BSF backlier weight (>= 0)
  double rho_b = -1.0;        //!< B-RANSAC backlier probability; < 0: estimate from data
  double confidence = 0.99;   //!< eq. 2.7's p
  std::uint32_t max_rounds = 200'000;
  std::uint32_t min_rounds = 200;  //!< cheap insurance against an early lucky stop
  /// The smallest score a result is of use with (a surface's minimum size): the rounds need not
  /// make finding weaker planes likely (0: every plane that beats the best so far counts).
  std::uint32_t min_score = 0;
  /// kContrast scores N_inner - outer_weight N_outer - beta N_back (N_inner: inliers within
  /// t / 2, N_outer: the other inliers). A slab through scattered points has N_inner = N_outer:
  /// with 1 it scores nothing, with 0.5 a quarter of its inliers. 0.5 tolerates surfaces whose
  /// points spread over more of the band: with kContrast in the appliance (threshold 1.5 x the
  /// map's median sigma), the EuRoC still cut's wall is kept at 0.5 and lost at 1, and the
  /// generated family's slabs still fall under their floor (docs/perf.md). A tracker's far
  /// points scatter far beyond the band: on the street clip's map no weight keeps the facades.
  double outer_weight = 0.5;
  /// Bail-out (Capel 2005): a candidate is first counted on a random subset of the points
  /// (kBailOutPoints) and dropped there when even three standard deviations above what it
  /// scores on it would not reach the score it needs (the best so far, at least min_score).
  /// Not for kBinomial (its log score does not scale with the points counted).
  bool bail_out = true;
  std::uint64_t seed = 1;
  Sampling sampling = Sampling::kGuided;
  int local_optimisation_iterations = 3;  //!< 0 disables LO
  double min_viewpoint_distance_m = 0.1;  //!< candidates closer to a viewpoint are skipped
  bool facing_check = true;               //!< 3-D: skip planes not facing view_dir (+-90 deg)
  Eigen::Vector3d view_dir = Eigen::Vector3d::UnitZ();  //!< camera's optical axis (3-D mode)
  std::uint32_t neighbours = 16;    //!< guided sampling: ~2x this many points per neighbourhood
  double neighbour_radius_m = 0.0;  //!< grid cell size [m]; 0: derived from the cloud
};

struct Detection {
  bool found = false;
  Plane plane;  //!< in the input frame, n toward the viewpoints
  std::uint32_t inliers = 0;
  std::uint32_t backliers = 0;
  double score = 0.0;   //!< in the method's units (log score for kBinomial)
  double rmse_m = 0.0;  //!< RMS distance of the inliers to the plane
  double rho_b = 0.0;   //!< backlier probability used (kBinomial) or observed (others)
  std::uint32_t rounds = 0;
  std::uint32_t rounds_needed = 0;       //!< eq. 2.7 for the final estimate (capped)
  std::uint32_t candidates_skipped = 0;  //!< degenerate or behind-the-camera samples
  std::uint32_t candidates_bailed = 0;   //!< dropped after the partial count (bail_out)
};

/// log(N_in * Binomial(k; n, rho)) with n = N_in + N_back, k = N_back (B-RANSAC, eq. 3.4).
double binomial_log_score(std::uint32_t inliers, std::uint32_t backliers, double rho_b);

/// The fewest inliers with which a B-RANSAC candidate can still score above log_score.
double binomial_min_inliers(double log_score, double rho_b, std::size_t n_points);

/// Rounds for an all-inlier sample with probability `confidence` when one sample is all
/// inliers with probability p_good (eq. 2.7 with p_good = rho_i^m), capped at max_rounds.
std::uint32_t rounds_needed(double p_good, double confidence, std::uint32_t max_rounds);

/// Least-squares plane through points (smallest eigenvector of their covariance).
std::optional<Plane> fit_plane_least_squares(std::span<const Eigen::Vector3d> points);

class WallDetector {
 public:
  WallDetector(std::size_t max_points, DetectorConfig config);

  [[nodiscard]] const DetectorConfig& config() const { return config_; }
  DetectorConfig& mutable_config() { return config_; }

  /// Viewpoints (camera centres) in the input frame; at least one. Default: the origin.
  void set_viewpoints(std::span<const Eigen::Vector3d> viewpoints);

  /// Loads the points to search (non-finite ones skipped and counted) and re-seeds the random
  /// generator from config().seed, so a search depends only on the seed and the input. With a
  /// gravity vector (pointing down, in the input frame), the cloud is rotated so that "up" is +z,
  /// and the 2-D and horizontal detectors become available. Throws std::length_error beyond
  /// max_points.
  void set_points(const PointCloud& cloud, std::optional<Eigen::Vector3d> gravity = std::nullopt);

  [[nodiscard]] std::size_t size() const { return n_; }
  [[nodiscard]] std::size_t skipped_non_finite() const { return skipped_; }
  [[nodiscard]] bool has_gravity() const { return has_gravity_; }

  /// Best wall in 3-D (3-point samples). `warm_start`: planes tried first (e.g. last model's).
  Detection detect_3d(std::span<const Plane> warm_start = {});
  /// Best vertical wall (2-point line samples on the ground plane); needs gravity.
  Detection detect_vertical(std::span<const Plane> warm_start = {});
  /// Best horizontal surface (1-point height samples); needs gravity.
  Detection detect_horizontal(std::span<const Plane> warm_start = {});

  /// Removes the inliers of `plane` from the points still searched; returns how many. With
  /// `removed`, also hands them back (input frame; the vector is cleared first and allocates
  /// only if it must grow).
  std::size_t remove_inliers(const Plane& plane, std::vector<Eigen::Vector3d>* removed = nullptr);

  /// For Manhattan constraints: only vertical candidates whose normal is within tol of a
  /// multiple of 90 degrees from `axis` (a horizontal direction, input frame) are accepted.
  void set_manhattan(std::optional<Eigen::Vector3d> axis, double tolerance_rad);

 private:
  enum class Mode : std::uint8_t { k3d, kVertical, kHorizontal };
  struct Candidate {
    Eigen::Vector3f n;
    float d;
  };
  Detection detect(Mode mode, std::span<const Plane> warm_start);
  bool orient_and_check(Mode mode, Eigen::Vector3f& n, float& d) const;
  double score_of(const PlaneCounts& c) const;
  PlaneCounts evaluate(const Eigen::Vector3f& n, float d) const;
  /// evaluate(), unless the bail-out test on the first kBailOutPoints says the candidate cannot
  /// score `needed` (then false).
  bool evaluate_unless_hopeless(const Eigen::Vector3f& n, float d, double needed,
                                PlaneCounts& counts) const;
  bool sample(Mode mode, bool guided, Eigen::Vector3f& n, float& d);
  void build_grid(Mode mode);
  [[nodiscard]] std::uint32_t find_cell(int ix, int iy, int iz) const;
  [[nodiscard]] std::uint32_t probe(std::uint32_t key) const;
  /// |n.p_i - d| < t for point i of the working frame.
  [[nodiscard]] bool near_plane(std::size_t i, const Eigen::Vector3f& n, float d, float t) const {
    return std::abs(n.x() * x_[i] + n.y() * y_[i] + n.z() * z_[i] - d) < t;
  }
  double guided_inlier_fraction(const Eigen::Vector3f& n, float d) const;
  bool refit(Mode mode, Eigen::Vector3f& n, float& d) const;
  double rho_for_binomial() const;
  void pad();
  [[nodiscard]] std::size_t padded() const {
    return (n_ + kPointPadding - 1) / kPointPadding * kPointPadding;
  }
  std::uint32_t draw(std::size_t n) {
    return static_cast<std::uint32_t>(((core::splitmix64_next(rng_state_) >> 32) * n) >> 32);
  }

  DetectorConfig config_;
  std::size_t capacity_;
  std::size_t n_ = 0;
  std::size_t skipped_ = 0;
  bool has_gravity_ = false;
  Eigen::Matrix3d R_work_input_ = Eigen::Matrix3d::Identity();  //!< input -> working frame
  // Working-frame points, SoA, padded with NaN to kPointPadding.
  std::vector<float> x_, y_, z_;
  std::vector<Eigen::Vector3f> viewpoints_;  //!< working frame
  // Guided sampling: the points bucketed in a uniform grid (3-D, or the ground plane).
  std::vector<std::uint32_t> grid_key_, grid_order_;  //!< scratch for the neighbour grid
  static constexpr std::uint32_t kEmptyCell = 0xFFFFFFFFu;
  static constexpr std::uint32_t kNoCell = 0xFFFFFFFFu;
  std::vector<std::uint32_t> cell_key_, cell_start_, cell_count_;  //!< cell hash table
  int cell_table_bits_ = 0;
  bool grid_planar_ = false;
  mutable std::vector<Eigen::Vector3d> scratch_points_;
  Mode grid_mode_ = Mode::k3d;
  bool grid_valid_ = false;
  std::uint64_t rng_state_ = 0;  //!< splitmix64: a round draws several numbers (cheap ones)
  Eigen::Vector3f view_work_ = Eigen::Vector3f::UnitZ();  //!< config_.view_dir, working frame
  std::optional<Eigen::Vector3f> manhattan_axis_;
  double manhattan_tol_rad_ = 0.0;
  mutable double rho_estimate_ = -1.0;
};

}  // namespace wallar::dsp

// SPDX-License-Identifier: Apache-2.0
/// @file wall_detector.cpp
/// @brief Backlier-aware RANSAC: sampling, candidate checks, scoring, adaptive rounds, LO.
#include "wallar/dsp/walls/wall_detector.hpp"

#include <math.h>  // lgamma_r

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace wallar::dsp {
namespace {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
constexpr double kMinusInf = -std::numeric_limits<double>::infinity();
// Share of guided rounds (the rest draw uniformly, a safety net for planes whose points are
// spread too thinly for neighbourhood sampling).
constexpr double kGuidedShare = 0.75;

int sample_size(int mode) { return mode == 0 ? 3 : mode == 1 ? 2 : 1; }

}  // namespace

double binomial_log_score(std::uint32_t inliers, std::uint32_t backliers, double rho_b) {
  if (inliers == 0) return kMinusInf;
  const double n = static_cast<double>(inliers) + backliers;
  const double k = backliers;
  const double rho = std::clamp(rho_b, 1e-9, 1.0 - 1e-9);
  // lgamma_r: plain lgamma writes the global signgam, a data race between detector threads.
  int sign = 0;
  const double log_choose =
      ::lgamma_r(n + 1.0, &sign) - ::lgamma_r(k + 1.0, &sign) - ::lgamma_r(n - k + 1.0, &sign);
  return std::log(static_cast<double>(inliers)) + log_choose + k * std::log(rho) +
         (n - k) * std::log1p(-rho);
}

double binomial_min_inliers(double log_score, double rho_b, std::size_t n_points) {
  // The best score N inliers can reach is at the most likely backlier count k* (the mode of
  // the binomial); that bound grows with N, so the smallest N above log_score is found by
  // bisection.
  const double rho = std::clamp(rho_b, 1e-9, 1.0 - 1e-9);
  const auto best_with = [rho](std::uint32_t n_in) {
    const auto mode = static_cast<std::uint32_t>(std::floor(rho / (1.0 - rho) * n_in));
    return std::max(binomial_log_score(n_in, mode, rho), binomial_log_score(n_in, mode + 1, rho));
  };
  std::uint32_t lo = 1, hi = static_cast<std::uint32_t>(std::max<std::size_t>(n_points, 1));
  if (best_with(hi) <= log_score) return hi;
  while (lo < hi) {
    const std::uint32_t mid = lo + (hi - lo) / 2;
    if (best_with(mid) > log_score)
      hi = mid;
    else
      lo = mid + 1;
  }
  return lo;
}

std::uint32_t rounds_needed(double p_good, double confidence, std::uint32_t max_rounds) {
  if (!(p_good > 0.0)) return max_rounds;
  if (p_good >= 1.0) return 1;
  const double n = std::log1p(-confidence) / std::log1p(-p_good);
  if (!(n < static_cast<double>(max_rounds))) return max_rounds;
  return std::max<std::uint32_t>(1, static_cast<std::uint32_t>(std::ceil(n)));
}

std::optional<Plane> fit_plane_least_squares(std::span<const Eigen::Vector3d> points) {
  if (points.size() < 3) return std::nullopt;
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const auto& p : points) mean += p;
  mean /= static_cast<double>(points.size());
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (const auto& p : points) cov += (p - mean) * (p - mean).transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);
  if (eig.info() != Eigen::Success) return std::nullopt;
  // Degenerate (collinear) when the two largest spreads are not both clearly non-zero.
  if (!(eig.eigenvalues()(1) > 1e-12 * std::max(1.0, eig.eigenvalues()(2)))) return std::nullopt;
  Plane plane;
  plane.n = eig.eigenvectors().col(0).normalized();
  plane.d = plane.n.dot(mean);
  return plane;
}

WallDetector::WallDetector(std::size_t max_points, DetectorConfig config)
    : config_(config), capacity_(max_points), rng_state_(config.seed) {
  const std::size_t cap =
      (max_points + kPointPadding - 1) / kPointPadding * kPointPadding + kPointPadding;
  x_.assign(cap, kNaN);
  y_.assign(cap, kNaN);
  z_.assign(cap, kNaN);
  grid_key_.assign(cap, 0);
  grid_order_.assign(cap, 0);
  std::size_t table = 16;  // the cell table: a power of two, at least twice the points
  while (table < 2 * cap) table *= 2;
  cell_key_.assign(table, kEmptyCell);
  while ((std::size_t{1} << cell_table_bits_) < table) ++cell_table_bits_;
  cell_start_.assign(table, 0);
  cell_count_.assign(table, 0);
  scratch_points_.reserve(cap);
  viewpoints_.reserve(kMaxViewpoints);
  viewpoints_.emplace_back(Eigen::Vector3f::Zero());
}

void WallDetector::set_viewpoints(std::span<const Eigen::Vector3d> viewpoints) {
  if (viewpoints.empty()) throw std::invalid_argument("at least one viewpoint is needed");
  if (viewpoints.size() > kMaxViewpoints) {
    throw std::length_error(std::to_string(viewpoints.size()) +
                            " viewpoints: more than the detector holds (64)");
  }
  viewpoints_.reserve(kMaxViewpoints);  // a copied detector's vector has only its size
  viewpoints_.clear();
  for (const auto& v : viewpoints) viewpoints_.push_back((R_work_input_ * v).cast<float>());
}

void WallDetector::pad() {
  for (std::size_t i = n_; i < padded(); ++i) x_[i] = y_[i] = z_[i] = kNaN;
}

void WallDetector::set_points(const PointCloud& cloud, std::optional<Eigen::Vector3d> gravity) {
  if (cloud.size() > capacity_) {
    throw std::length_error("cloud has more points than the detector was sized for");
  }
  // Viewpoints are kept in the working frame: take them back to the input frame first.
  std::array<Eigen::Vector3d, 64> vp_input;
  const std::size_t n_vp = viewpoints_.size();
  for (std::size_t i = 0; i < n_vp; ++i) {
    vp_input[i] = R_work_input_.transpose() * viewpoints_[i].cast<double>();
  }
  has_gravity_ = gravity.has_value();
  R_work_input_ = Eigen::Matrix3d::Identity();
  if (gravity) {
    if (!(gravity->norm() > 1e-9)) throw std::invalid_argument("gravity vector is zero");
    R_work_input_ =
        Eigen::Quaterniond::FromTwoVectors(-gravity->normalized(), Eigen::Vector3d::UnitZ())
            .toRotationMatrix();
  }
  viewpoints_.clear();
  for (std::size_t i = 0; i < n_vp; ++i) {
    viewpoints_.push_back((R_work_input_ * vp_input[i]).cast<float>());
  }
  const Eigen::Matrix3f R = R_work_input_.cast<float>();
  // A new problem starts the random stream afresh: results depend on the seed and the input
  // only, not on what the detector searched before.
  rng_state_ = config_.seed;
  n_ = 0;
  skipped_ = 0;
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    const Eigen::Vector3f p(cloud.x[i], cloud.y[i], cloud.z[i]);
    if (!p.allFinite()) {
      ++skipped_;
      continue;
    }
    const Eigen::Vector3f q = R * p;
    x_[n_] = q.x();
    y_[n_] = q.y();
    z_[n_] = q.z();
    ++n_;
  }
  // Random order (Fisher-Yates), so that any first k points are a random sample of them: the
  // bail-out test counts a candidate on the first kBailOutPoints.
  for (std::size_t i = n_; i > 1; --i) {
    const std::uint32_t j = draw(i);
    std::swap(x_[i - 1], x_[j]);
    std::swap(y_[i - 1], y_[j]);
    std::swap(z_[i - 1], z_[j]);
  }
  pad();
  grid_valid_ = false;
}

void WallDetector::set_manhattan(std::optional<Eigen::Vector3d> axis, double tolerance_rad) {
  manhattan_axis_.reset();
  manhattan_tol_rad_ = tolerance_rad;
  if (!axis) return;
  Eigen::Vector3f a = (R_work_input_ * *axis).cast<float>();
  a.z() = 0.0f;
  if (a.norm() > 1e-6f) manhattan_axis_ = a.normalized();
}

bool WallDetector::evaluate_unless_hopeless(const Eigen::Vector3f& n, float d, double needed,
                                            PlaneCounts& counts) const {
  const std::size_t all = padded();
  if (!config_.bail_out || config_.method == ScoreMethod::kBinomial || all < 4 * kBailOutPoints ||
      !(needed > 0.0)) {
    counts = evaluate(n, d);
    return true;
  }
  const auto t = static_cast<float>(config_.threshold_m);
  const bool backliers_count =
      config_.method == ScoreMethod::kBsf || config_.method == ScoreMethod::kContrast;
  const double b2 = backliers_count ? config_.beta * config_.beta : 0.0;
  // The points are in random order (set_points shuffles them), so the first k are a random
  // sample: a candidate that scores `needed` on all points scores about needed * k / n on them,
  // give or take the spread of its own counts there (each point adds 0, +-1 or -beta). More
  // steps (64, 256, 1024 points) bailed more often on the best plane itself and took more
  // rounds: one.
  constexpr std::size_t k = kBailOutPoints;
  counts = score_plane(x_.data(), y_.data(), z_.data(), k, n.x(), n.y(), n.z(), d, t);
  const double variance = static_cast<double>(counts.inliers) + b2 * counts.backliers + 1.0;
  const double expected = needed * static_cast<double>(k) / static_cast<double>(n_);
  const double short_by = expected - score_of(counts);
  if (short_by > 0.0 && short_by * short_by > 9.0 * variance) return false;  // 3 sd short
  const PlaneCounts rest =
      score_plane(x_.data() + k, y_.data() + k, z_.data() + k, all - k, n.x(), n.y(), n.z(), d, t);
  counts.inliers += rest.inliers;
  counts.backliers += rest.backliers;
  counts.inlier_sq_sum += rest.inlier_sq_sum;
  counts.inner += rest.inner;
  return true;
}

PlaneCounts WallDetector::evaluate(const Eigen::Vector3f& n, float d) const {
  return score_plane(x_.data(), y_.data(), z_.data(), padded(), n.x(), n.y(), n.z(), d,
                     static_cast<float>(config_.threshold_m));
}

double WallDetector::rho_for_binomial() const {
  return config_.rho_b >= 0.0 ? config_.rho_b : std::max(rho_estimate_, 1e-3);
}

double WallDetector::score_of(const PlaneCounts& c) const {
  switch (config_.method) {
    case ScoreMethod::kRansac:
      return c.inliers;
    case ScoreMethod::kMsac: {
      const double t2 = config_.threshold_m * config_.threshold_m;
      return static_cast<double>(c.inliers) - static_cast<double>(c.inlier_sq_sum) / t2;
    }
    case ScoreMethod::kBsf:
      return static_cast<double>(c.inliers) - config_.beta * c.backliers;
    case ScoreMethod::kBinomial:
      return binomial_log_score(c.inliers, c.backliers, rho_for_binomial());
    case ScoreMethod::kContrast:
      // The inner half of the band less its outer half, less beta per backlier.
      return static_cast<double>(c.inner) -
             config_.outer_weight * static_cast<double>(c.inliers - c.inner) -
             config_.beta * c.backliers;
  }
  return c.inliers;
}

bool WallDetector::orient_and_check(Mode mode, Eigen::Vector3f& n, float& d) const {
  // Every viewpoint must see the same side, not too close: else it is no wall of this room.
  int side = 0;
  const auto min_dist = static_cast<float>(config_.min_viewpoint_distance_m);
  for (const Eigen::Vector3f& v : viewpoints_) {
    const float s = n.dot(v) - d;
    if (!(std::abs(s) >= min_dist)) return false;
    const int this_side = s > 0.0f ? 1 : -1;
    if (side != 0 && this_side != side) return false;
    side = this_side;
  }
  if (side < 0) {
    n = -n;
    d = -d;
  }
  if (mode == Mode::k3d && config_.facing_check) {
    // The wall's front must face the camera: it looks along view_dir into the wall.
    if (!(n.dot(view_work_) < 0.0f)) return false;
  }
  if (mode == Mode::kVertical && manhattan_axis_) {
    const float c = std::abs(n.x() * manhattan_axis_->x() + n.y() * manhattan_axis_->y());
    const float s = std::abs(n.x() * manhattan_axis_->y() - n.y() * manhattan_axis_->x());
    // |angle| mod 90 degrees: close to parallel (s ~ 0) or perpendicular (c ~ 0).
    if (std::min(s, c) > std::sin(static_cast<float>(manhattan_tol_rad_))) return false;
  }
  return true;
}

bool WallDetector::sample(Mode mode, bool guided, Eigen::Vector3f& n, float& d) {
  const auto point = [this](std::uint32_t i) { return Eigen::Vector3f(x_[i], y_[i], z_[i]); };
  const std::uint32_t i0 = draw(n_);
  const bool use_cells = guided && mode != Mode::kHorizontal;
  auto other = [&]() -> std::uint32_t {
    if (use_cells) {
      // NAPSAC-like: a random one of the 3^dim cells around the first point, then a random
      // point in it; a few retries past empty cells, then a uniform draw.
      const std::uint32_t k0 = grid_key_[i0];
      const int ix = static_cast<int>(k0 >> 20), iy = static_cast<int>((k0 >> 10) & 1023u);
      const int iz = static_cast<int>(k0 & 1023u);
      const std::uint32_t offsets = grid_planar_ ? 9 : 27;
      for (int attempt = 0; attempt < 4; ++attempt) {
        const std::uint32_t o = draw(offsets);
        const int jx = ix + static_cast<int>(o % 3) - 1,
                  jy = iy + static_cast<int>((o / 3) % 3) - 1;
        const int jz = iz + (grid_planar_ ? 0 : static_cast<int>(o / 9) - 1);
        const std::uint32_t slot = find_cell(jx, jy, jz);
        if (slot == kNoCell) continue;
        const std::uint32_t j = grid_order_[cell_start_[slot] + draw(cell_count_[slot])];
        if (j != i0) return j;
      }
    }
    return draw(n_);
  };
  switch (mode) {
    case Mode::kHorizontal:
      n = Eigen::Vector3f::UnitZ();
      d = z_[i0];
      return true;
    case Mode::kVertical: {
      const std::uint32_t i1 = other();
      if (i1 == i0) return false;
      const Eigen::Vector2f a(x_[i0], y_[i0]);
      const Eigen::Vector2f v = Eigen::Vector2f(x_[i1], y_[i1]) - a;
      const float len = v.norm();
      if (!(len > 1e-6f)) return false;  // coincident on the ground plane
      n = Eigen::Vector3f(-v.y() / len, v.x() / len, 0.0f);
      d = n.x() * a.x() + n.y() * a.y();
      return true;
    }
    case Mode::k3d: {
      const std::uint32_t i1 = other();
      const std::uint32_t i2 = other();
      if (i1 == i0 || i2 == i0 || i1 == i2) return false;
      const Eigen::Vector3f a = point(i0);
      const Eigen::Vector3f ab = point(i1) - a;
      const Eigen::Vector3f ac = point(i2) - a;
      const Eigen::Vector3f c = ab.cross(ac);
      const float norm2 = c.squaredNorm();
      // Collinear or coincident: the cross product is tiny relative to the edge lengths.
      if (!(norm2 > 1e-8f * ab.squaredNorm() * ac.squaredNorm()) || !(norm2 > 1e-24f)) {
        return false;
      }
      n = c * (1.0f / std::sqrt(norm2));
      d = n.dot(a);
      return true;
    }
  }
  return false;
}

std::uint32_t WallDetector::probe(std::uint32_t key) const {
  // Knuth's multiplicative hash: the product's HIGH bits mix every bit of the key. Linear
  // probing ends at the key's slot or at the empty slot where it would go.
  std::uint32_t slot = (key * 2654435761u) >> (32 - cell_table_bits_);
  const auto mask = static_cast<std::uint32_t>(cell_key_.size() - 1);
  while (cell_key_[slot] != kEmptyCell && cell_key_[slot] != key) slot = (slot + 1) & mask;
  return slot;
}

std::uint32_t WallDetector::find_cell(int ix, int iy, int iz) const {
  if (ix < 0 || iy < 0 || iz < 0 || ix > 1023 || iy > 1023 || iz > 1023) return kNoCell;
  const std::uint32_t slot = probe(static_cast<std::uint32_t>((ix << 20) | (iy << 10) | iz));
  return cell_key_[slot] == kEmptyCell ? kNoCell : slot;
}

void WallDetector::build_grid(Mode mode) {
  grid_mode_ = mode;
  grid_valid_ = true;
  grid_planar_ = mode == Mode::kVertical;
  std::fill(cell_key_.begin(), cell_key_.end(), kEmptyCell);
  if (n_ < 2) return;
  const bool planar = grid_planar_;
  Eigen::Vector3f lo = Eigen::Vector3f::Constant(std::numeric_limits<float>::max());
  Eigen::Vector3f hi = -lo;
  for (std::size_t i = 0; i < n_; ++i) {
    const Eigen::Vector3f p(x_[i], y_[i], planar ? 0.0f : z_[i]);
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  // Cell size: about 2 * `neighbours` points expected in the 3^dim cells around a point.
  const Eigen::Vector3f ext = (hi - lo).cwiseMax(1e-3f);
  const double dims = planar ? 2.0 : 3.0;
  const double volume = planar ? double{ext.x()} * ext.y() : double{ext.x()} * ext.y() * ext.z();
  double h = config_.neighbour_radius_m > 0.0
                 ? config_.neighbour_radius_m
                 : std::pow(volume * 2.0 * config_.neighbours /
                                (std::pow(3.0, dims) * static_cast<double>(n_)),
                            1.0 / dims);
  h = std::max(h, 1e-3);
  const auto cell = [&](float v, float l) {
    return static_cast<std::uint32_t>(std::min(1023.0, std::floor((v - l) / h)));
  };
  // Bucket the points by cell (a counting sort through the open-addressing cell table).
  for (std::size_t i = 0; i < n_; ++i) {
    const std::uint32_t k = (cell(x_[i], lo.x()) << 20) | (cell(y_[i], lo.y()) << 10) |
                            (planar ? 0u : cell(z_[i], lo.z()));
    grid_key_[i] = k;
    const std::uint32_t slot = probe(k);
    if (cell_key_[slot] == kEmptyCell) {
      cell_key_[slot] = k;
      cell_count_[slot] = 0;
    }
    ++cell_count_[slot];
  }
  std::uint32_t next = 0;
  for (std::size_t slot = 0; slot < cell_key_.size(); ++slot) {
    if (cell_key_[slot] == kEmptyCell) continue;
    cell_start_[slot] = next;
    next += cell_count_[slot];
    cell_count_[slot] = 0;  // refilled below
  }
  for (std::size_t i = 0; i < n_; ++i) {
    const std::uint32_t slot = probe(grid_key_[i]);
    grid_order_[cell_start_[slot] + cell_count_[slot]++] = static_cast<std::uint32_t>(i);
  }
}

double WallDetector::guided_inlier_fraction(const Eigen::Vector3f& n, float d) const {
  // The chance that the guided draw from an inlier's neighbourhood is an inlier too: over the
  // non-empty cells around each inlier (drawn with equal chance), the share of inliers.
  const auto t = static_cast<float>(config_.threshold_m);
  const auto inlier = [&](std::uint32_t i) { return near_plane(i, n, d, t); };
  const int zr = grid_planar_ ? 0 : 1;
  double sum = 0.0;
  std::size_t count = 0;
  for (std::uint32_t i = 0; i < n_; ++i) {
    if (!inlier(i)) continue;
    const std::uint32_t k0 = grid_key_[i];
    const int ix = static_cast<int>(k0 >> 20), iy = static_cast<int>((k0 >> 10) & 1023u);
    const int iz = static_cast<int>(k0 & 1023u);
    double cell_sum = 0.0;
    int cells = 0;
    for (int dx = -1; dx <= 1; ++dx) {
      for (int dy = -1; dy <= 1; ++dy) {
        for (int dz = -zr; dz <= zr; ++dz) {
          const std::uint32_t slot = find_cell(ix + dx, iy + dy, iz + dz);
          if (slot == kNoCell) continue;
          std::uint32_t hits = 0, others = 0;
          for (std::uint32_t m = 0; m < cell_count_[slot]; ++m) {
            const std::uint32_t j = grid_order_[cell_start_[slot] + m];
            if (j == i) continue;
            ++others;
            hits += inlier(j) ? 1 : 0;
          }
          if (others == 0) continue;
          cell_sum += static_cast<double>(hits) / others;
          ++cells;
        }
      }
    }
    if (cells == 0) continue;
    sum += cell_sum / cells;
    ++count;
  }
  return count ? sum / static_cast<double>(count) : 0.0;
}

bool WallDetector::refit(Mode mode, Eigen::Vector3f& n, float& d) const {
  const auto t = static_cast<float>(config_.threshold_m);
  scratch_points_.clear();
  for (std::size_t i = 0; i < n_; ++i) {
    if (near_plane(i, n, d, t)) {
      scratch_points_.emplace_back(x_[i], y_[i], z_[i]);
    }
  }
  const std::size_t m = scratch_points_.size();
  if (m < static_cast<std::size_t>(sample_size(static_cast<int>(mode)))) return false;
  Eigen::Vector3f n_new;
  float d_new = 0.0f;
  if (mode == Mode::kHorizontal) {
    double zsum = 0.0;
    for (const auto& p : scratch_points_) zsum += p.z();
    n_new = Eigen::Vector3f::UnitZ();
    d_new = static_cast<float>(zsum / static_cast<double>(m));
  } else if (mode == Mode::kVertical) {
    Eigen::Vector2d mean = Eigen::Vector2d::Zero();
    for (const auto& p : scratch_points_) mean += p.head<2>();
    mean /= static_cast<double>(m);
    Eigen::Matrix2d cov = Eigen::Matrix2d::Zero();
    for (const auto& p : scratch_points_)
      cov += (p.head<2>() - mean) * (p.head<2>() - mean).transpose();
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(cov);
    if (eig.info() != Eigen::Success || !(eig.eigenvalues()(1) > 1e-12)) return false;
    const Eigen::Vector2d nn = eig.eigenvectors().col(0).normalized();
    n_new = Eigen::Vector3f(static_cast<float>(nn.x()), static_cast<float>(nn.y()), 0.0f);
    d_new = static_cast<float>(nn.dot(mean));
  } else {
    const auto plane = fit_plane_least_squares(scratch_points_);
    if (!plane) return false;
    n_new = plane->n.cast<float>();
    d_new = static_cast<float>(plane->d);
  }
  if (n_new.dot(n) < 0.0f) {
    n_new = -n_new;
    d_new = -d_new;
  }
  n = n_new;
  d = d_new;
  return true;
}

Detection WallDetector::detect(Mode mode, std::span<const Plane> warm_start) {
  Detection best;
  if (n_ < static_cast<std::size_t>(sample_size(static_cast<int>(mode)))) return best;
  if (mode != Mode::k3d && !has_gravity_) {
    throw std::logic_error("2-D and horizontal detection need a gravity direction");
  }
  // B-RANSAC without a given rho_b: estimate it from the wall a BSF pass finds (beta 0.5
  // works up to rho_b > 0.5 on the thesis's scenes), then search again with it.
  if (config_.method == ScoreMethod::kBinomial && config_.rho_b < 0.0) {
    const DetectorConfig saved = config_;
    config_.method = ScoreMethod::kBsf;
    config_.beta = 0.5;
    const Detection first = detect(mode, warm_start);
    config_ = saved;
    const double total = static_cast<double>(first.inliers) + first.backliers;
    rho_estimate_ = total > 0.0 ? std::clamp(first.backliers / total, 1e-3, 0.9) : 0.05;
  }

  view_work_ = (R_work_input_ * config_.view_dir).cast<float>();
  const bool guided = config_.sampling == Sampling::kGuided && mode != Mode::kHorizontal;
  if (guided && (!grid_valid_ || grid_mode_ != mode)) build_grid(mode);
  const int m = sample_size(static_cast<int>(mode));
  double best_score = kMinusInf;
  Eigen::Vector3f best_n = Eigen::Vector3f::UnitZ();
  float best_d = 0.0f;
  PlaneCounts best_counts;
  std::uint32_t target = config_.max_rounds;
  // Stopping rule state (see update_target).
  double p_uniform = 0.0;       // an all-inlier uniform sample of the weakest possible winner
  double p_guided_model = 0.0;  // the same for a guided sample, from its neighbourhoods
  double guided_scale = 1.0;    // from the best plane to the weakest possible winner
  double model_w = 0.0, model_sparser = 1.0;  // for p_guided_model, when it is next refreshed
  bool model_stale = false;
  std::uint32_t guided_rounds = 0, guided_hits = 0;
  const auto t_m = static_cast<float>(config_.threshold_m);
  const float cos_close = std::cos(5.0f * static_cast<float>(M_PI) / 180.0f);
  const auto close_to_best = [&](const Eigen::Vector3f& n, float d) {
    const float c = n.dot(best_n);
    return std::abs(c) > cos_close && std::abs((c > 0.0f ? d : -d) - best_d) < t_m;
  };

  // Eq. 2.7 with the probability that one round draws a sample of a plane that could still
  // win. Uniform rounds: w^m. Guided rounds: the neighbourhood model w * q^(m-1), but never
  // more than the rate at which guided rounds have actually produced candidates close to the
  // best plane (scaled to the weakest winner): a local sample can be all inliers and still
  // tilt away when the noise is large next to the neighbours' spacing.
  const auto update_target = [&] {
    double p_good = p_uniform;
    if (guided) {
      const double measured = (guided_hits + 0.5) / (guided_rounds + 1.0) * guided_scale;
      p_good = (1.0 - kGuidedShare) * p_uniform + kGuidedShare * std::min(p_guided_model, measured);
    }
    target = rounds_needed(p_good, config_.confidence, config_.max_rounds);
  };

  const auto consider = [&](Eigen::Vector3f n, float d) {
    if (!orient_and_check(mode, n, d)) {
      ++best.candidates_skipped;
      return;
    }
    PlaneCounts c;
    if (!evaluate_unless_hopeless(
            n, d, std::max(best_score, static_cast<double>(config_.min_score)), c)) {
      ++best.candidates_bailed;
      return;
    }
    double s = score_of(c);
    if (!(s > best_score)) return;
    // Local optimisation: refit on the inliers while that improves the score.
    for (int it = 0; it < config_.local_optimisation_iterations; ++it) {
      Eigen::Vector3f n2 = n;
      float d2 = d;
      if (!refit(mode, n2, d2) || !orient_and_check(mode, n2, d2)) break;
      const PlaneCounts c2 = evaluate(n2, d2);
      const double s2 = score_of(c2);
      if (!(s2 > s)) break;
      n = n2;
      d = d2;
      c = c2;
      s = s2;
    }
    // Evidence about guided rounds counts for the best plane only while it stays the same.
    if (best_score == kMinusInf || !close_to_best(n, d)) guided_rounds = guided_hits = 0;
    best_score = s;
    best_n = n;
    best_d = d;
    best_counts = c;
    // The weakest plane that could still beat this score: every score here is at most N_in
    // (B-RANSAC: see binomial_min_inliers). With plain RANSAC that is the best's own ratio;
    // with backlier-aware scores it is lower, so a decoy found first (a table in front of the
    // wall) does not end the search.
    const double w_best = static_cast<double>(c.inliers) / static_cast<double>(n_);
    const double n_min = config_.method == ScoreMethod::kBinomial
                             ? binomial_min_inliers(s, rho_for_binomial(), n_)
                             : s;
    // Planes scoring under min_score are of no use: the rounds need only make finding one of
    // that size likely, even while the best so far is smaller.
    const double w =
        std::max(std::clamp(n_min / static_cast<double>(n_), 1.0 / static_cast<double>(n_), w_best),
                 static_cast<double>(config_.min_score) / static_cast<double>(n_));
    const double sparser = std::min(1.0, w / w_best);
    p_uniform = std::pow(w, m);
    if (guided) {
      // q (below, once the rounds reach min_rounds: a search finds many bests early on, and
      // q costs a pass over the best's inliers' neighbourhoods) is scaled down with the inlier
      // count. What guided rounds showed on the best plane says little about a much sparser
      // one (its neighbourhoods hold fewer of its own points): the credit falls off steeply.
      model_w = w;
      model_sparser = sparser;
      model_stale = true;
      guided_scale = std::pow(sparser, 2 * m);
    }
    update_target();
  };
  // q: the fraction of an inlier's neighbours that are inliers, measured on the best plane.
  const auto refresh_guided_model = [&] {
    const double q = guided_inlier_fraction(best_n, best_d) * model_sparser;
    p_guided_model = model_w * std::pow(q, m - 1);
    model_stale = false;
    update_target();
  };

  for (const Plane& p : warm_start) {
    const Eigen::Vector3d nw = R_work_input_ * p.n;
    if (mode == Mode::kVertical && std::abs(nw.z()) > 0.2) continue;
    if (mode == Mode::kHorizontal && std::abs(nw.z()) < 0.8) continue;
    consider(nw.cast<float>(), static_cast<float>(p.d));
  }
  std::uint32_t round = 0;
  for (; round < config_.max_rounds; ++round) {
    if (round >= config_.min_rounds) {
      if (model_stale) refresh_guided_model();
      if (round >= target) break;
    }
    const bool guided_round = guided && (round & 3u) != 0;  // 3 of 4 rounds: kGuidedShare
    Eigen::Vector3f n;
    float d = 0.0f;
    if (!sample(mode, guided_round, n, d)) {
      ++best.candidates_skipped;
      continue;
    }
    if (guided_round && best_score != kMinusInf) {
      ++guided_rounds;
      guided_hits += close_to_best(n, d) ? 1 : 0;
      if ((guided_rounds & 15u) == 0) update_target();
    }
    consider(n, d);
  }
  best.rounds = round;
  if (model_stale) refresh_guided_model();  // for rounds_needed
  if (best_score == kMinusInf || best_counts.inliers == 0) return best;
  // Algorithm 4, line 15: the wall is the least-squares plane of the best candidate's
  // inliers. Count-based scores have flat optima (any tilt that keeps the band full scores
  // the same); the refit takes the plane to the middle of its inliers. Counts are re-taken.
  {
    Eigen::Vector3f n = best_n;
    float d = best_d;
    if (refit(mode, n, d) && orient_and_check(mode, n, d)) {
      const PlaneCounts c = evaluate(n, d);
      if (c.inliers > 0) {
        best_n = n;
        best_d = d;
        best_counts = c;
        best_score = score_of(c);
      }
    }
  }
  best.found = true;
  best.plane.n = R_work_input_.transpose() * best_n.cast<double>().normalized();
  best.plane.d = best_d;
  best.inliers = best_counts.inliers;
  best.backliers = best_counts.backliers;
  best.score = best_score;
  best.rmse_m = std::sqrt(static_cast<double>(best_counts.inlier_sq_sum) / best_counts.inliers);
  const double total = static_cast<double>(best.inliers) + best.backliers;
  best.rho_b =
      config_.method == ScoreMethod::kBinomial ? rho_for_binomial() : best.backliers / total;
  best.rounds_needed = target;
  return best;
}

Detection WallDetector::detect_3d(std::span<const Plane> warm_start) {
  return detect(Mode::k3d, warm_start);
}
Detection WallDetector::detect_vertical(std::span<const Plane> warm_start) {
  return detect(Mode::kVertical, warm_start);
}
Detection WallDetector::detect_horizontal(std::span<const Plane> warm_start) {
  return detect(Mode::kHorizontal, warm_start);
}

std::size_t WallDetector::remove_inliers(const Plane& plane,
                                         std::vector<Eigen::Vector3d>* removed) {
  const Eigen::Vector3f n = (R_work_input_ * plane.n).cast<float>();
  const auto d = static_cast<float>(plane.d);
  const auto t = static_cast<float>(config_.threshold_m);
  const Eigen::Matrix3d R_input_work = R_work_input_.transpose();
  if (removed != nullptr) removed->clear();
  std::size_t kept = 0;
  for (std::size_t i = 0; i < n_; ++i) {
    if (near_plane(i, n, d, t)) {
      if (removed != nullptr)
        removed->push_back(R_input_work * Eigen::Vector3d(x_[i], y_[i], z_[i]));
      continue;
    }
    x_[kept] = x_[i];
    y_[kept] = y_[i];
    z_[kept] = z_[i];
    ++kept;
  }
  const std::size_t count = n_ - kept;
  n_ = kept;
  pad();
  grid_valid_ = false;
  return count;
}

}  // namespace wallar::dsp

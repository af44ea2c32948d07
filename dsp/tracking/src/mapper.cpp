// SPDX-License-Identifier: Apache-2.0
/// @file mapper.cpp
/// @brief Key-frame store, bounded local/global bundle adjustment windows, point and key-frame
/// culling, point generations, map segments, snapshots.
#include "wallar/dsp/tracking/mapper.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <unordered_map>

#include "wallar/dsp/tracking/bundle_adjustment.hpp"

namespace wallar::dsp {
namespace {

struct Observation {
  int keyframe = 0;  // index into keyframes
  float u_px = 0.0f, v_px = 0.0f, u_right_px = NAN;
};
struct PointRecord {
  std::int32_t id = -1;
  std::uint32_t generation = 0;
  Eigen::Vector3d p_world = Eigen::Vector3d::Zero();
  float sigma_m = 0.0f;
  float sigma0_m = 0.0f;  // from the creating stereo pair
  bool alive = true;
  int first_keyframe = 0;  // index of the key-frame that made it
  std::vector<Observation> observations;
};
struct PointSlot {
  std::int32_t index = -1;  // into points
  std::uint32_t generation = 0;
};
struct MapperKeyframe {
  std::int32_t id = -1;
  TimeNs t_ns = 0;
  SE3d T_world_cam = SE3d::Identity();
  std::int32_t segment = 0;
  bool segment_start = false;
  bool alive = true;
  float observation_sigma_px = 1.0f;
  bool gyro_aided = false;        // its rotation was tracked with the gyro's
  double travelled_m = 0.0;       // from the key-frame before it (of its segment)
  std::vector<PointSlot> points;  // what it saw (a slot whose generation moved on is gone)
};

}  // namespace

struct Mapper::Impl {
  StereoIntrinsics K;
  MapperConfig config;
  std::vector<MapperKeyframe> keyframes;  // in order of arrival; dropped ones stay as tombstones
  std::vector<PointRecord> points;
  std::unordered_map<std::int32_t, std::int32_t> point_index;  // tracker id -> index
  std::uint64_t version = 0;
  std::uint64_t culled_keyframes = 0;
  std::uint64_t stale = 0;
  int alive_keyframes = 0;

  bool sees(const PointSlot& slot) const {
    const PointRecord& p = points[static_cast<std::size_t>(slot.index)];
    return p.alive && p.generation == slot.generation;
  }
  /// The newest `count` alive key-frames (indices, oldest first).
  std::vector<int> newest_alive(int count) const;
  MapperStats adjust(const std::vector<int>& window, int iterations, int max_fixed,
                     MapCorrection& out);
  void cull_redundant(const std::vector<int>& window, MapCorrection& out, MapperStats& stats);
  void cull_unconfirmed(MapCorrection& out, MapperStats& stats);
  void kill_point(PointRecord& p, MapCorrection& out, MapperStats& stats);
};

Mapper::Mapper(const StereoIntrinsics& K, const MapperConfig& config)
    : impl_(std::make_unique<Impl>()) {
  impl_->K = K;
  impl_->config = config;
}
Mapper::~Mapper() = default;

int Mapper::keyframe_count() const { return impl_->alive_keyframes; }
int Mapper::points_count() const {
  int n = 0;
  for (const PointRecord& p : impl_->points) n += p.alive ? 1 : 0;
  return n;
}
std::uint64_t Mapper::culled_keyframes() const { return impl_->culled_keyframes; }
std::uint64_t Mapper::stale_messages() const { return impl_->stale; }

void Mapper::add_keyframe(const KeyframeMessage& message) {
  Impl& m = *impl_;
  const int k = static_cast<int>(m.keyframes.size());
  MapperKeyframe record;
  record.id = message.id;
  record.t_ns = message.t_ns;
  record.T_world_cam = message.T_world_cam;
  record.segment = message.segment;
  record.segment_start = message.segment_start;
  record.observation_sigma_px = std::max(1.0f, message.observation_sigma_px);
  record.gyro_aided = message.gyro_aided;
  for (auto it = m.keyframes.rbegin(); it != m.keyframes.rend(); ++it) {
    if (it->segment != record.segment) continue;
    record.travelled_m = (it->T_world_cam.translation() - record.T_world_cam.translation()).norm();
    break;
  }
  for (const PointRef& ref : message.culled) {
    const auto it = m.point_index.find(ref.id);
    if (it == m.point_index.end()) continue;
    PointRecord& p = m.points[static_cast<std::size_t>(it->second)];
    if (p.generation != ref.generation) {
      ++m.stale;  // about an older point in that slot
      continue;
    }
    p.alive = false;
  }
  for (const NewMapPoint& np : message.new_points) {
    auto [it, fresh] =
        m.point_index.try_emplace(np.point, static_cast<std::int32_t>(m.points.size()));
    PointRecord record_point{np.point,   np.generation, np.p_world, np.sigma_m,
                             np.sigma_m, true,          k,          {}};
    if (fresh) {
      m.points.push_back(std::move(record_point));
    } else {
      // The tracker reused the id of a culled point: a new point in the old slot.
      m.points[static_cast<std::size_t>(it->second)] = std::move(record_point);
    }
  }
  for (const KeyframeObservation& o : message.observations) {
    const auto it = m.point_index.find(o.point);
    if (it == m.point_index.end()) continue;
    PointRecord& p = m.points[static_cast<std::size_t>(it->second)];
    if (p.generation != o.generation) {
      ++m.stale;
      continue;
    }
    if (!p.alive) continue;
    p.observations.push_back(Observation{k, o.u_px, o.v_px, o.u_right_px});
    record.points.push_back(PointSlot{it->second, p.generation});
  }
  m.keyframes.push_back(std::move(record));
  ++m.alive_keyframes;
  ++m.version;
}

std::vector<int> Mapper::Impl::newest_alive(int count) const {
  std::vector<int> out;
  for (int k = static_cast<int>(keyframes.size()) - 1;
       k >= 0 && static_cast<int>(out.size()) < count; --k) {
    if (keyframes[static_cast<std::size_t>(k)].alive) out.push_back(k);
  }
  std::reverse(out.begin(), out.end());
  return out;
}

void Mapper::Impl::kill_point(PointRecord& p, MapCorrection& out, MapperStats& stats) {
  p.alive = false;
  out.culled.push_back(PointRef{p.id, p.generation});
  ++stats.culled;
}

MapperStats Mapper::Impl::adjust(const std::vector<int>& window, int iterations, int max_fixed,
                                 MapCorrection& out) {
  out.clear();
  MapperStats stats;
  stats.keyframes = alive_keyframes;
  for (const PointRecord& p : points) stats.points += p.alive ? 1 : 0;
  if (alive_keyframes < config.min_keyframes_for_ba || window.empty()) return stats;
  // The points seen by the window.
  std::vector<std::int32_t> ba_point_of(points.size(), -1);
  std::vector<BaPoint> ba_points;
  std::vector<std::int32_t> point_of_ba;
  std::vector<char> in_window(keyframes.size(), 0);
  for (int k : window) in_window[static_cast<std::size_t>(k)] = 1;
  for (int k : window) {
    for (const PointSlot& slot : keyframes[static_cast<std::size_t>(k)].points) {
      if (!sees(slot) || ba_point_of[static_cast<std::size_t>(slot.index)] >= 0) continue;
      ba_point_of[static_cast<std::size_t>(slot.index)] =
          static_cast<std::int32_t>(ba_points.size());
      ba_points.push_back(BaPoint{points[static_cast<std::size_t>(slot.index)].p_world, false});
      point_of_ba.push_back(slot.index);
    }
  }
  // Key-frames outside the window that see those points hold still: the ones sharing the most.
  std::unordered_map<int, int> shared;
  for (std::int32_t pi : point_of_ba) {
    for (const Observation& o : points[static_cast<std::size_t>(pi)].observations) {
      if (!in_window[static_cast<std::size_t>(o.keyframe)]) ++shared[o.keyframe];
    }
  }
  std::vector<std::pair<int, int>> outside(shared.begin(), shared.end());  // (key-frame, shared)
  std::sort(outside.begin(), outside.end(), [](const auto& a, const auto& b) {
    return a.second != b.second ? a.second > b.second : a.first > b.first;
  });
  if (static_cast<int>(outside.size()) > max_fixed)
    outside.resize(static_cast<std::size_t>(max_fixed));
  std::vector<std::int32_t> ba_keyframe_of(keyframes.size(), -1);
  std::vector<BaKeyframe> ba_keyframes;
  std::vector<std::int32_t> keyframe_of_ba;
  const auto add = [&](int k, bool fixed) {
    ba_keyframe_of[static_cast<std::size_t>(k)] = static_cast<std::int32_t>(ba_keyframes.size());
    BaKeyframe b{keyframes[static_cast<std::size_t>(k)].T_world_cam.inverse(), fixed};
    const MapperKeyframe& kf = keyframes[static_cast<std::size_t>(k)];
    const double travelled = kf.travelled_m;
    b.prior_sigma_m = config.keyframe_prior_m + config.keyframe_prior_m_per_m * travelled;
    const double prior_deg =
        kf.gyro_aided
            ? config.keyframe_prior_deg_gyro + config.keyframe_prior_deg_per_m_gyro * travelled
            : config.keyframe_prior_deg + config.keyframe_prior_deg_per_m * travelled;
    b.prior_sigma_rad = prior_deg * M_PI / 180.0;
    ba_keyframes.push_back(b);
    keyframe_of_ba.push_back(k);
  };
  // Each segment's first key-frame holds its gauge.
  for (int k : window) add(k, keyframes[static_cast<std::size_t>(k)].segment_start);
  std::sort(outside.begin(), outside.end());  // in key-frame order (repeatable)
  for (const auto& [k, n] : outside) add(k, true);
  (void)shared;
  // Gauge: at least one key-frame of each segment in the adjustment holds still.
  {
    std::unordered_map<std::int32_t, bool> segment_fixed;
    for (std::size_t b = 0; b < ba_keyframes.size(); ++b) {
      const std::int32_t seg = keyframes[static_cast<std::size_t>(keyframe_of_ba[b])].segment;
      segment_fixed[seg] = segment_fixed[seg] || ba_keyframes[b].fixed;
    }
    for (std::size_t b = 0; b < ba_keyframes.size(); ++b) {
      const std::int32_t seg = keyframes[static_cast<std::size_t>(keyframe_of_ba[b])].segment;
      if (!segment_fixed[seg]) {
        ba_keyframes[b].fixed = true;  // the oldest of its segment here
        segment_fixed[seg] = true;
      }
    }
  }
  std::vector<BaObservation> ba_obs;
  for (std::size_t bp = 0; bp < point_of_ba.size(); ++bp) {
    for (const Observation& o : points[static_cast<std::size_t>(point_of_ba[bp])].observations) {
      const std::int32_t bk = ba_keyframe_of[static_cast<std::size_t>(o.keyframe)];
      if (bk < 0) continue;
      ba_obs.push_back(
          BaObservation{bk, static_cast<int>(bp), o.u_px, o.v_px, o.u_right_px,
                        keyframes[static_cast<std::size_t>(o.keyframe)].observation_sigma_px});
    }
  }
  if (ba_obs.empty()) return stats;
  BaOptions options;
  options.max_iterations = iterations;
  options.huber_px = config.huber_px;
  const BaResult r = bundle_adjust(K, ba_keyframes, ba_points, ba_obs, options);
  stats.iterations = r.iterations;
  stats.initial_cost = r.initial_cost;
  stats.final_cost = r.final_cost;
  stats.adjusted_keyframes = 0;
  for (std::size_t bk = 0; bk < ba_keyframes.size(); ++bk) {
    if (ba_keyframes[bk].fixed) continue;
    MapperKeyframe& k = keyframes[static_cast<std::size_t>(keyframe_of_ba[bk])];
    k.T_world_cam = ba_keyframes[bk].T_cam_world.inverse();
    out.keyframes.push_back(MapCorrection::Keyframe{k.id, k.T_world_cam});
    ++stats.adjusted_keyframes;
  }
  // Points: take the adjusted position, or cull the point when it does not fit its views.
  std::vector<double> error_sum(ba_points.size(), 0.0);
  std::vector<int> error_n(ba_points.size(), 0);
  for (const BaObservation& o : ba_obs) {
    const Eigen::Vector3d p = ba_keyframes[static_cast<std::size_t>(o.keyframe)].T_cam_world *
                              ba_points[static_cast<std::size_t>(o.point)].p_world;
    double e = 1e9;
    if (p.z() > 1e-3) {
      const Eigen::Vector3d uvr = K.project(p);
      e = std::hypot(uvr.x() - o.u_px, uvr.y() - o.v_px) / o.sigma_px;
    }
    error_sum[static_cast<std::size_t>(o.point)] += e;
    ++error_n[static_cast<std::size_t>(o.point)];
  }
  for (std::size_t bp = 0; bp < ba_points.size(); ++bp) {
    PointRecord& p = points[static_cast<std::size_t>(point_of_ba[bp])];
    const double mean_error = error_sum[bp] / std::max(1, error_n[bp]);
    if (!ba_points[bp].p_world.allFinite() || mean_error > config.cull_error_px) {
      kill_point(p, out, stats);
      continue;
    }
    p.p_world = ba_points[bp].p_world;
    // Seen from several key-frames, the point is as good as its best view's depth.
    p.sigma_m = static_cast<float>(p.sigma0_m / std::sqrt(static_cast<double>(std::max<std::size_t>(
                                                    1, p.observations.size()))));
    out.points.push_back(MapCorrection::Point{p.id, p.generation, p.p_world, p.sigma_m});
    ++stats.adjusted_points;
  }
  ++version;
  return stats;
}

/// Drops key-frames of the window whose points are nearly all seen by enough others (a head
/// that stays in one room keeps making key-frames where key-frames already are).
void Mapper::Impl::cull_redundant(const std::vector<int>& window, MapCorrection& out,
                                  MapperStats& stats) {
  const int keep_from = static_cast<int>(window.size()) - config.keep_newest_keyframes;
  for (int w = 0; w < keep_from; ++w) {
    const int k = window[static_cast<std::size_t>(w)];
    MapperKeyframe& kf = keyframes[static_cast<std::size_t>(k)];
    if (!kf.alive || kf.segment_start) continue;
    int seen = 0, redundant = 0;
    for (const PointSlot& slot : kf.points) {
      if (!sees(slot)) continue;
      ++seen;
      int others = 0;
      for (const Observation& o : points[static_cast<std::size_t>(slot.index)].observations) {
        if (o.keyframe != k && keyframes[static_cast<std::size_t>(o.keyframe)].alive) ++others;
      }
      redundant += others >= config.redundant_observers ? 1 : 0;
    }
    if (seen == 0 || static_cast<double>(redundant) < config.redundant_share * seen) continue;
    kf.alive = false;
    --alive_keyframes;
    ++culled_keyframes;
    ++stats.culled_keyframes;
    if (!out.culled_keyframes.full()) out.culled_keyframes.push_back(kf.id);
    for (const PointSlot& slot : kf.points) {
      if (!sees(slot)) continue;
      PointRecord& p = points[static_cast<std::size_t>(slot.index)];
      std::erase_if(p.observations, [k](const Observation& o) { return o.keyframe == k; });
      if (p.observations.empty()) kill_point(p, out, stats);
    }
    kf.points.clear();
    kf.points.shrink_to_fit();
  }
}

/// Points that no key-frame after the one that made them saw again within
/// confirm_keyframes key-frames are dropped (ORB-SLAM's recent-point culling): a key-frame makes
/// more points than the tracker follows, and those never seen again would fill the map.
void Mapper::Impl::cull_unconfirmed(MapCorrection& out, MapperStats& stats) {
  const int newest = static_cast<int>(keyframes.size()) - 1;
  const int judged = newest - config.confirm_keyframes;  // made by this key-frame index
  if (judged < 0) return;
  for (PointRecord& p : points) {
    if (!p.alive || p.first_keyframe != judged) continue;
    if (p.observations.size() < 2) kill_point(p, out, stats);
  }
}

MapperStats Mapper::local_adjust(MapCorrection& out) {
  Impl& m = *impl_;
  const std::vector<int> window = m.newest_alive(m.config.local_keyframes);
  MapperStats stats =
      m.adjust(window, m.config.local_iterations, m.config.local_fixed_keyframes, out);
  if (m.config.confirm_keyframes > 0) m.cull_unconfirmed(out, stats);
  if (m.alive_keyframes >= m.config.min_keyframes_for_ba) m.cull_redundant(window, out, stats);
  stats.keyframes = m.alive_keyframes;
  return stats;
}

MapperStats Mapper::global_adjust(MapCorrection& out) {
  Impl& m = *impl_;
  const std::vector<int> window = m.newest_alive(m.config.global_keyframes);
  MapperStats stats =
      m.adjust(window, m.config.global_iterations, 2 * m.config.local_fixed_keyframes, out);
  stats.keyframes = m.alive_keyframes;
  return stats;
}

MapSnapshot Mapper::snapshot() const {
  const Impl& m = *impl_;
  MapSnapshot s;
  s.version = m.version;
  std::vector<std::uint32_t> alive_index(m.keyframes.size(), 0);
  for (std::size_t k = 0; k < m.keyframes.size(); ++k) {
    const MapperKeyframe& kf = m.keyframes[k];
    if (!kf.alive) continue;
    alive_index[k] = static_cast<std::uint32_t>(s.keyframe_centres.size());
    s.keyframe_centres.push_back(kf.T_world_cam.translation());
    s.keyframe_image_down.push_back(kf.T_world_cam.linear().col(1));
    s.keyframe_t_ns.push_back(kf.t_ns);
  }
  s.viewer_offset.push_back(0);
  for (const PointRecord& p : m.points) {
    if (!p.alive) continue;
    s.points.push_back(p.p_world.cast<float>());
    s.points.observations.push_back(
        static_cast<std::uint16_t>(std::min<std::size_t>(p.observations.size(), 65535)));
    s.sigma_m.push_back(p.sigma_m);
    s.point_ids.push_back(p.id);
    for (const Observation& o : p.observations) {
      s.viewer_index.push_back(alive_index[static_cast<std::size_t>(o.keyframe)]);
    }
    s.viewer_offset.push_back(static_cast<std::uint32_t>(s.viewer_index.size()));
  }
  return s;
}

std::optional<Eigen::Vector3d> down_from_path(const MapSnapshot& map, double min_extent_m,
                                              double max_flatness) {
  const std::size_t n = map.keyframe_centres.size();
  if (n < 3 || map.keyframe_image_down.size() != n) return std::nullopt;
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const Eigen::Vector3d& c : map.keyframe_centres) mean += c;
  mean /= static_cast<double>(n);
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (const Eigen::Vector3d& c : map.keyframe_centres) cov += (c - mean) * (c - mean).transpose();
  cov /= static_cast<double>(n);
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);
  const Eigen::Vector3d sd = eig.eigenvalues().cwiseMax(0.0).cwiseSqrt();  // ascending
  // The spread as the path's extent (4 sigma of a uniform spread is about its length).
  if (4.0 * sd[1] < min_extent_m || sd[0] > max_flatness * sd[1]) return std::nullopt;
  Eigen::Vector3d down = eig.eigenvectors().col(0).normalized();
  Eigen::Vector3d image_down = Eigen::Vector3d::Zero();
  for (const Eigen::Vector3d& d : map.keyframe_image_down) image_down += d;
  if (std::abs(image_down.dot(down)) < 0.5 * static_cast<double>(n)) return std::nullopt;
  if (image_down.dot(down) < 0.0) down = -down;
  return down;
}

void local_map(const MapSnapshot& map, double radius_m, LocalMap& out) {
  out.points.clear();
  out.viewpoints.clear();
  out.sigma_scratch.clear();
  out.median_sigma_m = 0.0;
  const bool all = map.keyframe_centres.empty();
  const Eigen::Vector3d c = all ? Eigen::Vector3d::Zero() : map.keyframe_centres.back();
  const double r2 = radius_m * radius_m;
  for (const Eigen::Vector3d& k : map.keyframe_centres) {
    if ((k - c).squaredNorm() <= r2) out.viewpoints.push_back(k);
  }
  const bool with_sigma = map.sigma_m.size() == map.points.size();
  const bool with_weight = map.points.has_weight();
  const bool with_observations = map.points.has_observations();
  for (std::size_t i = 0; i < map.points.size(); ++i) {
    const Eigen::Vector3f p = map.points.point(i);
    if (!all && (p.cast<double>() - c).squaredNorm() > r2) continue;
    out.points.push_back(p);
    if (with_weight) out.points.weight.push_back(map.points.weight[i]);
    if (with_observations) out.points.observations.push_back(map.points.observations[i]);
    if (with_sigma) out.sigma_scratch.push_back(map.sigma_m[i]);
  }
  std::vector<float>& sigma = out.sigma_scratch;
  if (!sigma.empty()) {
    const auto mid = sigma.begin() + static_cast<std::ptrdiff_t>(sigma.size() / 2);
    std::nth_element(sigma.begin(), mid, sigma.end());
    out.median_sigma_m = *mid;
  }
}

}  // namespace wallar::dsp

// SPDX-License-Identifier: Apache-2.0
/// @file mapper.cpp
/// @brief Key-frame store, local/global bundle adjustment windows, culling, snapshots.
#include "wallar/dsp/tracking/mapper.hpp"

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
  Eigen::Vector3d p_world = Eigen::Vector3d::Zero();
  float sigma_m = 0.0f;
  float sigma0_m = 0.0f;  // from the creating stereo pair
  bool alive = true;
  std::vector<Observation> observations;
};
struct MapperKeyframe {
  std::int32_t id = -1;
  TimeNs t_ns = 0;
  SE3d T_world_cam = SE3d::Identity();
  std::vector<std::int32_t> points;  // indices into points
};

}  // namespace

struct Mapper::Impl {
  StereoIntrinsics K;
  MapperConfig config;
  std::vector<MapperKeyframe> keyframes;
  std::vector<PointRecord> points;
  std::unordered_map<std::int32_t, std::int32_t> point_index;  // tracker id -> index
  std::uint64_t version = 0;

  MapperStats adjust(int first_keyframe, int iterations, MapCorrection& out);
};

Mapper::Mapper(const StereoIntrinsics& K, const MapperConfig& config)
    : impl_(std::make_unique<Impl>()) {
  impl_->K = K;
  impl_->config = config;
}
Mapper::~Mapper() = default;

int Mapper::keyframe_count() const { return static_cast<int>(impl_->keyframes.size()); }

void Mapper::add_keyframe(const KeyframeMessage& message) {
  Impl& m = *impl_;
  const int k = static_cast<int>(m.keyframes.size());
  MapperKeyframe record;
  record.id = message.id;
  record.t_ns = message.t_ns;
  record.T_world_cam = message.T_world_cam;
  for (std::int32_t id : message.culled) {
    const auto it = m.point_index.find(id);
    if (it != m.point_index.end()) m.points[static_cast<std::size_t>(it->second)].alive = false;
  }
  for (const NewMapPoint& p : message.new_points) {
    auto [it, fresh] = m.point_index.try_emplace(p.point, static_cast<std::int32_t>(m.points.size()));
    if (fresh) {
      m.points.push_back(PointRecord{p.point, p.p_world, p.sigma_m, p.sigma_m, true, {}});
    } else {
      // The tracker reused the id of a culled point: a new point in the old slot.
      m.points[static_cast<std::size_t>(it->second)] = PointRecord{p.point, p.p_world, p.sigma_m, p.sigma_m, true, {}};
    }
  }
  for (const KeyframeObservation& o : message.observations) {
    const auto it = m.point_index.find(o.point);
    if (it == m.point_index.end()) continue;
    PointRecord& p = m.points[static_cast<std::size_t>(it->second)];
    if (!p.alive) continue;
    p.observations.push_back(Observation{k, o.u_px, o.v_px, o.u_right_px});
    record.points.push_back(it->second);
  }
  m.keyframes.push_back(std::move(record));
  ++m.version;
}

MapperStats Mapper::Impl::adjust(int first_keyframe, int iterations, MapCorrection& out) {
  out.clear();
  MapperStats stats;
  stats.keyframes = static_cast<int>(keyframes.size());
  for (const PointRecord& p : points) stats.points += p.alive ? 1 : 0;
  if (static_cast<int>(keyframes.size()) < config.min_keyframes_for_ba) return stats;
  first_keyframe = std::max(first_keyframe, 0);
  // The points seen by the window, and every key-frame that saw them.
  std::vector<std::int32_t> ba_point_of(points.size(), -1);
  std::vector<std::int32_t> ba_keyframe_of(keyframes.size(), -1);
  std::vector<BaKeyframe> ba_keyframes;
  std::vector<BaPoint> ba_points;
  std::vector<std::int32_t> point_of_ba, keyframe_of_ba;
  const auto add_keyframe_to_ba = [&](int k, bool fixed) {
    if (ba_keyframe_of[static_cast<std::size_t>(k)] >= 0) return;
    ba_keyframe_of[static_cast<std::size_t>(k)] = static_cast<std::int32_t>(ba_keyframes.size());
    ba_keyframes.push_back(
        BaKeyframe{keyframes[static_cast<std::size_t>(k)].T_world_cam.inverse(), fixed});
    keyframe_of_ba.push_back(k);
  };
  for (int k = first_keyframe; k < static_cast<int>(keyframes.size()); ++k) {
    add_keyframe_to_ba(k, k == 0);
  }
  for (int k = first_keyframe; k < static_cast<int>(keyframes.size()); ++k) {
    for (std::int32_t pi : keyframes[static_cast<std::size_t>(k)].points) {
      PointRecord& p = points[static_cast<std::size_t>(pi)];
      if (!p.alive || ba_point_of[static_cast<std::size_t>(pi)] >= 0) continue;
      ba_point_of[static_cast<std::size_t>(pi)] = static_cast<std::int32_t>(ba_points.size());
      ba_points.push_back(BaPoint{p.p_world, false});
      point_of_ba.push_back(pi);
      for (const Observation& o : p.observations) add_keyframe_to_ba(o.keyframe, true);
    }
  }
  // Gauge: at least one key-frame holds still.
  bool any_fixed = false;
  for (const BaKeyframe& k : ba_keyframes) any_fixed = any_fixed || k.fixed;
  if (!any_fixed && !ba_keyframes.empty()) ba_keyframes.front().fixed = true;
  std::vector<BaObservation> ba_obs;
  for (std::size_t bp = 0; bp < point_of_ba.size(); ++bp) {
    for (const Observation& o : points[static_cast<std::size_t>(point_of_ba[bp])].observations) {
      const std::int32_t bk = ba_keyframe_of[static_cast<std::size_t>(o.keyframe)];
      if (bk < 0) continue;
      ba_obs.push_back(BaObservation{bk, static_cast<int>(bp), o.u_px, o.v_px, o.u_right_px});
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
    const Eigen::Vector3d p =
        ba_keyframes[static_cast<std::size_t>(o.keyframe)].T_cam_world *
        ba_points[static_cast<std::size_t>(o.point)].p_world;
    double e = 1e9;
    if (p.z() > 1e-3) {
      const Eigen::Vector3d uvr = K.project(p);
      e = std::hypot(uvr.x() - o.u_px, uvr.y() - o.v_px);
    }
    error_sum[static_cast<std::size_t>(o.point)] += e;
    ++error_n[static_cast<std::size_t>(o.point)];
  }
  for (std::size_t bp = 0; bp < ba_points.size(); ++bp) {
    PointRecord& p = points[static_cast<std::size_t>(point_of_ba[bp])];
    const double mean_error = error_sum[bp] / std::max(1, error_n[bp]);
    if (!ba_points[bp].p_world.allFinite() || mean_error > config.cull_error_px) {
      p.alive = false;
      out.culled.push_back(p.id);
      ++stats.culled;
      continue;
    }
    p.p_world = ba_points[bp].p_world;
    // Seen from several key-frames, the point is as good as its best view's depth.
    p.sigma_m = static_cast<float>(p.sigma0_m / std::sqrt(static_cast<double>(std::max<std::size_t>(1, p.observations.size()))));
    out.points.push_back(MapCorrection::Point{p.id, p.p_world, p.sigma_m});
    ++stats.adjusted_points;
  }
  ++version;
  return stats;
}

MapperStats Mapper::local_adjust(MapCorrection& out) {
  const int n = static_cast<int>(impl_->keyframes.size());
  return impl_->adjust(n - impl_->config.local_keyframes, impl_->config.local_iterations, out);
}

MapperStats Mapper::global_adjust(MapCorrection& out) {
  return impl_->adjust(0, impl_->config.global_iterations, out);
}

MapSnapshot Mapper::snapshot() const {
  const Impl& m = *impl_;
  MapSnapshot s;
  s.version = m.version;
  for (const MapperKeyframe& k : m.keyframes) {
    s.keyframe_centres.push_back(k.T_world_cam.translation());
    s.keyframe_t_ns.push_back(k.t_ns);
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
      s.viewer_index.push_back(static_cast<std::uint32_t>(o.keyframe));
    }
    s.viewer_offset.push_back(static_cast<std::uint32_t>(s.viewer_index.size()));
  }
  return s;
}

}  // namespace wallar::dsp

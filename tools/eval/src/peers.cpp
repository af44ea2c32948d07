// SPDX-License-Identifier: Apache-2.0
/// @file peers.cpp
/// @brief PCL and Open3D plane RANSAC behind one call (host builds only).
#include "wallar/eval/peers.hpp"

#include <omp.h>
#include <open3d/geometry/PointCloud.h>
#include <open3d/utility/Logging.h>
#include <open3d/utility/Random.h>
#include <pcl/ModelCoefficients.h>
#include <pcl/PointIndices.h>
#include <pcl/console/print.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <pcl/sample_consensus/method_types.h>
#include <pcl/sample_consensus/model_types.h>
#include <pcl/segmentation/sac_segmentation.h>

#include <cmath>

namespace wallar::eval {
namespace {

PeerFit from_coefficients(double a, double b, double c, double d, std::size_t inliers) {
  // a x + b y + c z + d = 0  ->  n.p - d' = 0 with d' = -d / |n|.
  PeerFit f;
  const Eigen::Vector3d n(a, b, c);
  const double norm = n.norm();
  if (!(norm > 0.0) || !std::isfinite(d)) return f;
  f.found = inliers > 0;
  f.plane = Plane{n / norm, -d / norm}.facing(Eigen::Vector3d::Zero());
  f.inliers = static_cast<std::uint32_t>(inliers);
  return f;
}

}  // namespace

bool peers_available() { return true; }

PeerFit fit_plane_peer(Peer peer, const PointCloud& cloud, double threshold_m,
                       std::uint32_t max_rounds, double probability, std::uint64_t seed) {
  if (peer == Peer::kOpen3d) {
    open3d::utility::SetVerbosityLevel(open3d::utility::VerbosityLevel::Error);
    omp_set_num_threads(1);
    open3d::utility::random::Seed(static_cast<int>(seed & 0x7FFFFFFF));
    open3d::geometry::PointCloud pc;
    pc.points_.reserve(cloud.size());
    for (std::size_t i = 0; i < cloud.size(); ++i)
      pc.points_.push_back(cloud.point(i).cast<double>());
    if (pc.points_.size() < 3) return {};
    const auto [model, inliers] =
        pc.SegmentPlane(threshold_m, 3, static_cast<int>(max_rounds), probability);
    return from_coefficients(model[0], model[1], model[2], model[3], inliers.size());
  }
  pcl::console::setVerbosityLevel(pcl::console::L_ALWAYS);
  pcl::PointCloud<pcl::PointXYZ>::Ptr pc(new pcl::PointCloud<pcl::PointXYZ>);
  pc->reserve(cloud.size());
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    const Eigen::Vector3f p = cloud.point(i);
    pc->push_back(pcl::PointXYZ(p.x(), p.y(), p.z()));
  }
  if (pc->size() < 3) return {};
  // PCL takes no seed: SACSegmentation(false) seeds its generator with 12345 on every call
  // (true would seed it from the clock), so a trial is repeatable and `seed` goes unused.
  pcl::SACSegmentation<pcl::PointXYZ> seg(false);
  seg.setOptimizeCoefficients(true);
  seg.setModelType(pcl::SACMODEL_PLANE);
  seg.setMethodType(pcl::SAC_RANSAC);
  seg.setMaxIterations(static_cast<int>(max_rounds));
  seg.setProbability(probability);
  seg.setDistanceThreshold(threshold_m);
  seg.setInputCloud(pc);
  pcl::PointIndices inliers;
  pcl::ModelCoefficients coeffs;
  seg.segment(inliers, coeffs);
  if (coeffs.values.size() != 4) return {};
  const auto& v = coeffs.values;
  return from_coefficients(v[0], v[1], v[2], v[3], inliers.indices.size());
}

}  // namespace wallar::eval

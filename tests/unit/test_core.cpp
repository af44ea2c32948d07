// SPDX-License-Identifier: Apache-2.0
/// @file test_core.cpp
/// @brief Core types: planes, images' reference counts, point clouds.
#include <gtest/gtest.h>

#include <thread>
#include <vector>

#include "wallar/core/image.hpp"
#include "wallar/core/plane.hpp"
#include "wallar/core/point_cloud.hpp"

namespace wallar {
namespace {

TEST(Plane, ThroughThreePointsHasUnitNormalAndContainsThem) {
  const Eigen::Vector3d a(0, 0, 2), b(1, 0, 2), c(0, 1, 2);
  const auto p = Plane::through(a, b, c);
  ASSERT_TRUE(p.has_value());
  EXPECT_NEAR(p->n.norm(), 1.0, 1e-12);
  EXPECT_NEAR(p->n.z(), 1.0, 1e-12);
  EXPECT_NEAR(p->d, 2.0, 1e-12);
  for (const auto& q : {a, b, c}) EXPECT_NEAR(p->signed_distance(q), 0.0, 1e-12);
}

TEST(Plane, CollinearPointsGiveNoPlane) {
  EXPECT_FALSE(Plane::through({0, 0, 0}, {1, 1, 1}, {2, 2, 2}).has_value());
}

TEST(Plane, FacingPutsTheViewerInFront) {
  const Plane wall{Eigen::Vector3d::UnitZ(), 2.0};  // z = 2, front toward +z
  const Eigen::Vector3d camera(0, 0, 0);            // camera at the origin, so front is -z
  const Plane f = wall.facing(camera);
  EXPECT_GT(f.signed_distance(camera), 0.0);
  EXPECT_NEAR(f.n.z(), -1.0, 1e-12);
  EXPECT_NEAR(f.signed_distance({0, 0, 3}), -1.0, 1e-12);  // behind the wall: a backlier
  EXPECT_NEAR((f.project({1, 2, 5}) - Eigen::Vector3d(1, 2, 2)).norm(), 0.0, 1e-12);
}

TEST(Image, CopiesShareOneBufferAndTheLastDropFreesIt) {
  Image a = Image::allocate(4, 3, PixelFormat::kGray8);
  EXPECT_EQ(a.use_count(), 1);
  EXPECT_EQ(a.stride_bytes(), 4);
  a.mutable_data()[5] = 42;
  {
    Image b = a;
    EXPECT_EQ(a.use_count(), 2);
    EXPECT_EQ(b.data(), a.data());  // no pixel copy
    EXPECT_EQ(b.row(1)[1], 42);
  }
  EXPECT_EQ(a.use_count(), 1);
  Image moved = std::move(a);
  EXPECT_TRUE(a.empty());  // NOLINT(bugprone-use-after-move): moved-from is empty by contract
  EXPECT_EQ(moved.use_count(), 1);
}

// A buffer that counts its releases, like a V4L2 buffer that must be re-queued exactly once.
class CountingBuffer final : public ImageBuffer {
 public:
  explicit CountingBuffer(std::atomic<int>& released) : released_(released) {
    set_memory(storage_, sizeof storage_);
  }
  void release() override { released_.fetch_add(1); }

 private:
  std::uint8_t storage_[16]{};
  std::atomic<int>& released_;
};

TEST(Image, ReleaseRunsOnceWhenReferencesDropOnManyThreads) {
  std::atomic<int> released{0};
  CountingBuffer buffer(released);
  {
    Image img(&buffer, 4, 4, 4, PixelFormat::kGray8);
    std::vector<std::thread> threads;
    for (int t = 0; t < 4; ++t) {
      threads.emplace_back([img] {  // each thread holds and drops copies
        for (int i = 0; i < 1000; ++i) {
          Image copy = img;
          (void)copy;
        }
      });
    }
    for (auto& t : threads) t.join();
    EXPECT_EQ(released.load(), 0);
  }
  EXPECT_EQ(released.load(), 1);
}

TEST(PointCloud, OptionalColumnsMustMatchTheCoordinates) {
  PointCloud cloud;
  cloud.push_back({1, 2, 3});
  cloud.push_back({4, 5, 6});
  EXPECT_TRUE(cloud.consistent());
  EXPECT_FALSE(cloud.has_weight());
  cloud.observations = {3, 4};
  EXPECT_TRUE(cloud.consistent());
  cloud.weight = {1.0f};
  EXPECT_FALSE(cloud.consistent());
  EXPECT_EQ(cloud.point(1), Eigen::Vector3f(4, 5, 6));
}

}  // namespace
}  // namespace wallar

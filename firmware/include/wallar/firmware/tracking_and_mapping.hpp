// SPDX-License-Identifier: Apache-2.0
/// @file tracking_and_mapping.hpp
/// @brief Tracking and mapping wired together (thesis fig. 3.3: tracking and mapping on their
/// own threads): the Tracker on the caller's thread, the Mapper on a mapping thread that it
/// never waits for, and the gyro's rotation between frames as the tracker's prior.
///
/// Tracker -> mapper: key-frames through a lock-free SPSC ring of fixed-size slots (a full ring
/// drops the key-frame and counts it; tracking never blocks). Mapper -> tracker: corrections
/// through a second ring, applied at the start of the next frame. The mapping thread sleeps on
/// a Wakeup that the tracker notifies when it pushes a key-frame or frees a correction slot,
/// and never polls. A reset never waits for it either: the tracker starts a new map epoch, and
/// the mapping thread drops the old map, and every key-frame and correction of it, when it
/// next wakes. The mapper runs a local
/// bundle adjustment after each key-frame (and a global one every
/// TrackingOptions::global_adjustment_keyframes, when set) and publishes a map snapshot after
/// each; finish() ends with a global one.
/// In lock-step mode (no thread) the mapper runs right after each key-frame on the caller's
/// thread, on the same schedule: slower per key-frame, but bit-for-bit repeatable (tests,
/// evaluation).
///
/// Threading: on_imu() and on_stereo() belong to one thread (the tracking thread);
/// latest_map() may be called from any thread; finish() and reset() from the tracking thread
/// (finish once; or from another thread after the tracking thread was joined).
#pragma once

#include <atomic>
#include <functional>
#include <memory>
#include <mutex>
#include <thread>
#include <vector>

#include "wallar/core/imu_sample.hpp"
#include "wallar/core/spsc_ring.hpp"
#include "wallar/core/stereo_frame.hpp"
#include "wallar/core/triple_buffer.hpp"
#include "wallar/dsp/tracking/mapper.hpp"
#include "wallar/dsp/tracking/tracker.hpp"
#include "wallar/firmware/board.hpp"
#include "wallar/firmware/rt_thread.hpp"
#include "wallar/firmware/wakeup.hpp"

namespace wallar::firmware {

struct TrackingOptions {
  dsp::TrackerConfig tracker;
  dsp::MapperConfig mapper;
  bool mapping_thread = true;  //!< false: lock step (repeatable)
  bool use_gyro = true;
  int imu_capacity = 4096;  //!< gyro samples kept between frames
  /// A global bundle adjustment after every this many key-frames while tracking (0: only the
  /// one finish() runs). Off: the threaded mode ran one whenever the mapper was idle after 5
  /// key-frames, and without them its tracked trajectories came out better where the head turns
  /// on the spot (synth-rig quick-turns seed 2 2.06 -> 1.36 cm, seed 1 0.90-1.02 -> 0.79 cm),
  /// the same on the street clip and on seed 3, and a walk with glances (walk-turns seed 2)
  /// 1.04 -> 1.35 cm mean, still under 0.1 % of its path (docs/results.md). Lock step never
  /// ran them; the local adjustments keep the map.
  int global_adjustment_keyframes = 0;
  ThreadSpec mapping_thread_spec{"mapping", 0, -1, 0};
  /// Also publish each map here (one reader, e.g. the reconstruction thread); may be null.
  TripleBuffer<std::shared_ptr<const dsp::MapSnapshot>>* map_channel = nullptr;
  /// And here (the live server's, its own reader); may be null.
  TripleBuffer<std::shared_ptr<const dsp::MapSnapshot>>* live_map_channel = nullptr;
  /// Test tooling: called on the mapping thread before it maps each key-frame (a slow bundle
  /// adjustment, to race a reset against); empty in the product.
  std::function<void()> before_mapping;
};

/// The board file's tracking section as tracker and mapper settings.
TrackingOptions tracking_options(const TrackingConfig& board);

struct TrackingCounters {
  std::uint64_t frames = 0, keyframes = 0, corrections_applied = 0;
  /// Key-frames due while the mapper's queue was full: not made, the tracker kept tracking on
  /// the map it had (the mapper never misses a key-frame that was made).
  std::uint64_t keyframes_deferred = 0;
  std::uint64_t lost_frames = 0, rejected_frames = 0, relocalisations = 0, local_adjustments = 0,
                global_adjustments = 0, culled_points = 0;
  std::uint64_t new_segments = 0;        //!< maps restarted after relocalisation kept failing
  std::uint64_t map_full_keyframes = 0;  //!< key-frames that could not add every point
  std::uint64_t culled_keyframes = 0;    //!< redundant key-frames the mapper dropped
  std::uint64_t map_keyframes = 0, map_points = 0;  //!< the mapper's map after its last update
  /// Corrections, culls or observations that named a point's older generation (ignored).
  std::uint64_t stale_updates = 0;
};

class TrackingAndMapping {
 public:
  TrackingAndMapping(const RigCalibration& rig, const TrackingOptions& options,
                     dsp::Tracker::Clock clock = nullptr);
  ~TrackingAndMapping();  // stops the mapping thread
  TrackingAndMapping(const TrackingAndMapping&) = delete;
  TrackingAndMapping& operator=(const TrackingAndMapping&) = delete;

  void on_imu(const ImuSample& sample);
  /// The gyro bias the attitude filter estimates, subtracted from the rates of the rotation
  /// prior (zero until set).
  void set_gyro_bias(const Eigen::Vector3d& bias_rad_s);
  dsp::TrackResult on_stereo(const StereoFrame& frame);
  /// Stops the mapping thread after it has taken every key-frame, runs a global bundle
  /// adjustment and returns the final map.
  std::shared_ptr<const dsp::MapSnapshot> finish();
  /// Forgets the map and the tracker's state; allocates. With a mapping thread, never waits
  /// for it (no join on the tracking thread): the mapping thread starts the new map itself.
  void reset();
  /// The mapping thread (null in lock step); the same thread from start to finish().
  [[nodiscard]] const RtThread* mapping_thread() const { return thread_.get(); }
  /// The newest published map (null before the first key-frame was mapped).
  [[nodiscard]] std::shared_ptr<const dsp::MapSnapshot> latest_map() const;

  [[nodiscard]] const dsp::Tracker& tracker() const { return tracker_; }
  [[nodiscard]] TrackingCounters counters() const;
  /// Wall time of each local bundle adjustment [ns] (mapping time per key-frame).
  [[nodiscard]] std::vector<std::int64_t> mapping_times_ns() const;

 private:
  // Ring slots carry the map epoch they belong to: after a reset the mapping thread drops the
  // old epoch's key-frames and the tracker its corrections.
  struct KeyframeSlot {
    std::uint32_t epoch = 0;
    dsp::KeyframeMessage message;
  };
  struct CorrectionSlot {
    std::uint32_t epoch = 0;
    dsp::MapCorrection correction;
  };

  void mapping_loop();
  void new_map();  //!< the mapper's side of a reset: a fresh mapper, no map published
  void map_keyframe(const dsp::KeyframeMessage& message, dsp::MapCorrection& out);
  void publish_map();
  void note(const dsp::MapperStats& stats);  //!< mapping side: counters after an adjustment
  [[nodiscard]] bool global_due(int keyframes_since) const;
  void global_adjust(dsp::MapCorrection& out);  //!< mapping side: counted
  void start_mapping();
  dsp::RotationPrior gyro_prior(TimeNs t_ns);

  TrackingOptions options_;
  dsp::Tracker tracker_;
  std::unique_ptr<dsp::Mapper> mapper_;
  SE3d T_rect_imu_ = SE3d::Identity();
  std::int64_t timeshift_cam_imu_ns_ = 0;                      //!< t_imu = t_cam + this
  Eigen::Vector3d accel_bias_m_s2_ = Eigen::Vector3d::Zero();  //!< the calibration's
  Eigen::Vector3d gyro_bias_rad_s_ = Eigen::Vector3d::Zero();
  bool gyro_bias_known_ = false;      //!< set_gyro_bias() was called
  dsp::StereoIntrinsics intrinsics_;  //!< the tracker's, for new mappers on either thread
  SpscRing<KeyframeSlot> keyframes_;
  SpscRing<CorrectionSlot> corrections_;
  std::uint32_t epoch_ = 0;                    //!< tracking side: the map epoch (one per reset)
  std::atomic<std::uint32_t> reset_epoch_{0};  //!< tracking -> mapping: the epoch asked for
  std::uint32_t mapper_epoch_ = 0;             //!< mapping side: the mapper's epoch
  Wakeup mapper_wakeup_;  //!< a key-frame pushed, a correction slot freed, a reset, the stop
  dsp::MapCorrection lockstep_correction_;
  int lockstep_since_global_ = 0;  //!< key-frames mapped in lock step since a global adjustment
  std::vector<ImuSample> gyro_;    // ring, sized once
  std::size_t gyro_head_ = 0, gyro_count_ = 0;
  TimeNs last_frame_t_ns_ = -1;
  TrackingCounters counters_;
  std::atomic<std::uint64_t> local_adjustments_{0}, global_adjustments_{0}, culled_{0},
      culled_keyframes_{0}, map_keyframes_{0}, map_points_{0}, stale_messages_{0};
  mutable std::mutex map_mutex_;  // guards map_ and mapping_times_ (mapping side only)
  std::shared_ptr<const dsp::MapSnapshot> map_;
  std::vector<std::int64_t> mapping_times_;
  std::atomic<bool> stop_{false};
  std::unique_ptr<RtThread> thread_;
};

}  // namespace wallar::firmware

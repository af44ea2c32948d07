// SPDX-License-Identifier: Apache-2.0
/// @file live_publisher.cpp
/// @brief The live module: the appliance's outputs on Foxglove's WebSocket protocol.
#include "wallar/firmware/appliance/live_publisher.hpp"

#include <unistd.h>

#include <cmath>
#include <ctime>
#include <fstream>

#include "wallar/core/error.hpp"
#include "wallar/drivers/recording/jpeg.hpp"
#include "wallar/firmware/foxglove_messages.hpp"
#include "wallar/firmware/viewer_files.hpp"

namespace wallar::firmware {
namespace {

namespace fg = foxglove;

constexpr double kTrajectoryStepM = 0.05;
constexpr double kTrajectoryStepRad = 5.0 * M_PI / 180.0;

std::string read_token(const std::filesystem::path& file) {
  std::ifstream in(file);
  std::string token;
  if (!in || !std::getline(in, token)) {
    throw InputError(file.string() + ": live.token_file: cannot read the token (its first line)");
  }
  while (!token.empty() && (token.back() == '\r' || token.back() == ' ')) token.pop_back();
  if (token.empty()) throw InputError(file.string() + ": live.token_file: the first line is empty");
  return token;
}

net::FoxgloveServerOptions server_options(const LiveConfig& c) {
  net::FoxgloveServerOptions o;
  o.address = c.address;
  o.port = c.port;
  if (c.token_file) o.token = read_token(*c.token_file);
  o.name = "wallar";
  return o;
}

SE3d pose_of(const PoseSnapshot& p) {
  SE3d T = SE3d::Identity();
  T.linear() = Eigen::Map<const Eigen::Matrix3d>(p.R);
  T.translation() = Eigen::Vector3d(p.p[0], p.p[1], p.p[2]);
  return T;
}

// Far enough from `last` to be a new trajectory pose.
bool moved(const SE3d& last, const SE3d& now) {
  const double dp = (now.translation() - last.translation()).norm();
  const double da = Eigen::AngleAxisd(last.linear().transpose() * now.linear()).angle();
  return dp >= kTrajectoryStepM || da >= kTrajectoryStepRad;
}

bool is_loopback(const std::string& address) { return address.rfind("127.", 0) == 0; }

}  // namespace

LivePublisher::LivePublisher(const LiveConfig& config, const RigCalibration& rig,
                             LivePublisherOptions options, const Seqlock<PoseSnapshot>& pose,
                             TripleBuffer<MapPtr>& maps, TripleBuffer<WallModel>& walls)
    : config_(config),
      options_(options),
      pose_(pose),
      maps_(maps),
      walls_(walls),
      T_body_cam_{rig.cams[0].T_body_cam, rig.cams[1].T_body_cam},
      server_(server_options(config)) {
  auto add = [this](const fg::Schema& s, const char* topic, std::size_t history = 1) {
    net::FoxgloveChannel c;
    c.topic = topic;
    c.schema_name = s.name;
    c.schema = s.json_schema;
    c.history = history;
    return server_.add_channel(std::move(c));
  };
  ch_.pose = add(fg::pose_in_frame_schema(), "/pose");
  ch_.tf = add(fg::frame_transforms_schema(), "/tf");
  ch_.trajectory = add(fg::poses_in_frame_schema(), "/trajectory");
  ch_.map = add(fg::point_cloud_schema(), "/map");
  ch_.walls = add(fg::scene_update_schema(), "/walls");
  ch_.cam[0] = add(fg::compressed_image_schema(), "/cam0");
  ch_.cam[1] = add(fg::compressed_image_schema(), "/cam1");
  ch_.stats = add(fg::stats_schema(), "/stats");
  ch_.log = add(fg::log_schema(), "/log", std::max<std::size_t>(options_.log_history, 1));
  // The viewer page on the same port (http://HOST:PORT/), a client of these channels.
  for (const ViewerFile& f : viewer_files())
    server_.add_http_file({f.path, f.content_type, f.body});
  trajectory_.reserve(options_.max_trajectory_poses);
  thread_rows_.reserve(16);
  stage_rows_.reserve(16);
  server_.start();  // InputError "live server ADDRESS:PORT: cannot listen ..."
  std::lock_guard lock(log_mutex_);
  serving_ = true;
}

LivePublisher::~LivePublisher() { stop(); }

std::string LivePublisher::url() const {
  // Bound to every address: 0.0.0.0 is no address a laptop can connect to; the host's name is
  // (on the headset's network, with mDNS or DNS).
  std::string host = config_.address;
  if (host == "0.0.0.0") {
    char name[256] = {};
    if (gethostname(name, sizeof name - 1) == 0 && name[0] != '\0') host = name;
  }
  return "ws://" + host + ":" + std::to_string(server_.port()) + "/";
}

void LivePublisher::start(ThreadSpec spec, StatsSource stats) {
  stats_ = std::move(stats);
  thread_ = std::make_unique<RtThread>(std::move(spec), [this] { loop(stop_); });
}

std::string LivePublisher::describe() const {
  std::string d = "live server on " + url() +
                  " (Foxglove: Open connection, Foxglove WebSocket; a "
                  "browser: http" +
                  url().substr(2) + ")";
  if (!is_loopback(config_.address) && !config_.token_file) {
    d += "; without a token: anyone on that network can watch (board: live.token_file)";
  }
  return d;
}

void LivePublisher::stop() {
  stop_.store(true, std::memory_order_release);
  if (thread_ && thread_->joinable()) thread_->join();
  {
    std::lock_guard lock(log_mutex_);
    if (!serving_) return;
    serving_ = false;
  }
  server_.stop();
}

void LivePublisher::log(const std::string& line) {
  std::lock_guard lock(log_mutex_);
  if (!serving_) return;
  // The log's records carry no level: what reports a fault is a warning.
  const bool warning =
      line.find("lost") != std::string::npos || line.find("stalled") != std::string::npos ||
      line.find("cannot") != std::string::npos || line.find("failed") != std::string::npos ||
      line.find("without") != std::string::npos;
  const TimeNs t = sensor_now_ns_.load(std::memory_order_relaxed);
  server_.publish(
      ch_.log, t,
      fg::log(t, warning ? fg::LogLevel::kWarning : fg::LogLevel::kInfo, line, "wallar"));
}

std::vector<std::pair<const char*, std::uint64_t>> LivePublisher::counters() const {
  const net::FoxgloveServerStats s = server_.stats();
  return {{"clients", s.clients_connected},
          {"clients_total", s.clients_total},
          {"clients_refused", s.clients_refused},
          {"client_errors", s.client_errors},
          {"subscriptions", s.subscriptions},
          {"published", s.published},
          {"sent", s.sent},
          {"dropped", s.dropped},
          {"bytes_sent", s.bytes_sent},
          {"images", images()},
          {"frames_skipped", frames_.overwritten()}};
}

void LivePublisher::loop(const std::atomic<bool>& stop) {
  const DurationNs image_period_ns =
      config_.image_rate_hz > 0.0 ? static_cast<DurationNs>(1e9 / config_.image_rate_hz) : 0;
  StereoFrame frame;
  while (!stop.load(std::memory_order_acquire)) {
    const timespec ts{0, static_cast<long>(options_.pose_period_ns)};
    nanosleep(&ts, nullptr);
    const TimeNs now = monotonic_now_ns();
    const PoseSnapshot p = pose_.load();
    if (p.t_ns > 0 && p.t_ns != last_pose_t_ns_) publish_pose(p);
    // Messages are stamped in the sensors' time (a replay's is the recording's), as the poses.
    const TimeNs t = sensor_now_ns_.load(std::memory_order_relaxed);
    const bool walls_changed = walls_.refresh();
    if (maps_.refresh()) {
      const MapPtr& m = maps_.front();
      if (m && m->version != map_version_) {
        map_version_ = m->version;
        map_changed_ = true;
      }
    }
    if (walls_changed) {
      server_.publish(ch_.walls, t, fg::scene_update(t, walls_.front().walls, true));
    }
    if (walls_changed || now >= next_scene_ns_) {  // the map's colours follow the walls
      publish_scene(t, walls_changed);
      next_scene_ns_ = now + options_.scene_period_ns;
    }
    // Images: asked of the tracking thread only while someone watches a camera.
    if (image_period_ns > 0 && now >= next_image_ns_ &&
        (server_.has_subscribers(ch_.cam[0]) || server_.has_subscribers(ch_.cam[1]))) {
      image_due_.store(true, std::memory_order_relaxed);
      next_image_ns_ = now + image_period_ns;
    }
    if (frames_.take(frame)) {
      publish_images(frame);
      frame = StereoFrame{};  // the pixels go back now, not at the next image
    }
    if (stats_ && now >= next_stats_ns_) {
      next_stats_ns_ = now + options_.stats_period_ns;
      thread_rows_.clear();
      stage_rows_.clear();
      stats_(thread_rows_, stage_rows_);
      server_.publish(ch_.stats, t, fg::stats(t, thread_rows_, stage_rows_, counters()));
    }
  }
}

void LivePublisher::publish_pose(const PoseSnapshot& p) {
  last_pose_t_ns_ = p.t_ns;
  sensor_now_ns_.store(p.t_ns, std::memory_order_relaxed);
  if (p.epoch != epoch_) {  // a reset: a new world, a new path
    epoch_ = p.epoch;
    trajectory_.clear();
    trajectory_changed_ = true;
  }
  const SE3d T_world_body = pose_of(p);
  server_.publish(ch_.pose, p.t_ns, fg::pose_in_frame(p.t_ns, T_world_body));
  std::vector<fg::NamedTransform> tf;
  if (const std::optional<Eigen::Vector3d> down = down_of(p)) {
    SE3d T_up_world = SE3d::Identity();
    T_up_world.linear() =
        Eigen::Quaterniond::FromTwoVectors(*down, -Eigen::Vector3d::UnitZ()).toRotationMatrix();
    tf.push_back({"up", "world", T_up_world});
  }
  tf.push_back({"world", "body", T_world_body});
  tf.push_back({"body", "cam0", T_body_cam_[0]});
  tf.push_back({"body", "cam1", T_body_cam_[1]});
  server_.publish(ch_.tf, p.t_ns, fg::frame_transforms(p.t_ns, tf));
  if (trajectory_.empty() || moved(trajectory_.back(), T_world_body)) {
    if (trajectory_.size() == options_.max_trajectory_poses) {  // thinned, never grown
      std::size_t k = 0;
      for (std::size_t i = 0; i < trajectory_.size(); i += 2) trajectory_[k++] = trajectory_[i];
      trajectory_.resize(k);
    }
    trajectory_.push_back(T_world_body);
    trajectory_changed_ = true;
  }
}

void LivePublisher::publish_scene(TimeNs now_ns, bool walls_changed) {
  const std::vector<Wall>& walls = walls_.front().walls;
  if ((map_changed_ || walls_changed) && maps_.front()) {  // coloured by the surfaces
    map_changed_ = false;
    const dsp::MapSnapshot& m = *maps_.front();
    server_.publish(ch_.map, now_ns, fg::point_cloud(now_ns, m.points, m.sigma_m, walls));
  }
  if (trajectory_changed_) {
    trajectory_changed_ = false;
    server_.publish(ch_.trajectory, now_ns, fg::poses_in_frame(now_ns, trajectory_));
  }
}

void LivePublisher::publish_images(const StereoFrame& frame) {
  const CameraFrame* cams[2] = {&frame.left, &frame.right};
  const char* frames[2] = {"cam0", "cam1"};
  for (int i = 0; i < 2; ++i) {
    if (cams[i]->image.empty() || !server_.has_subscribers(ch_.cam[i])) continue;
    const std::vector<std::uint8_t> jpeg =
        recording::encode_jpeg_gray(cams[i]->image, config_.jpeg_quality);
    server_.publish(ch_.cam[i], cams[i]->t_ns,
                    fg::compressed_image(cams[i]->t_ns, frames[i], "jpeg", jpeg));
    images_.fetch_add(1, std::memory_order_relaxed);
  }
}

}  // namespace wallar::firmware

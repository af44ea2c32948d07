// SPDX-License-Identifier: Apache-2.0
/// @file mcap_recording.cpp
/// @brief wallar's recording layout in MCAP: writer, reader, converter (see mcap_recording.hpp).
#include "wallar/drivers/recording/mcap_recording.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <optional>
#include <string_view>

#include "wallar/core/error.hpp"
#include "wallar/drivers/recording/foxglove_json.hpp"

namespace wallar::recording {
namespace {

namespace fs = std::filesystem;
namespace fj = foxglove_json;
using nlohmann::json;

constexpr const char* kRigMetadata = "wallar.rig";
constexpr const char* kCamTopic[2] = {"/cam0", "/cam1"};
constexpr const char* kImuTopic = "/imu0";
constexpr const char* kGroundTruthTopic = "/ground_truth";

// ---- schemas ----------------------------------------------------------------------------------

json vector3_schema(const std::string& description) {
  json number = {{"type", "number"}};
  return {{"type", "object"},
          {"title", "foxglove.Vector3"},
          {"description", description},
          {"properties", {{"x", number}, {"y", number}, {"z", number}}}};
}

// Foxglove's CameraCalibration (its published JSON Schema, with the fields it lists as required).
std::string camera_calibration_schema() {
  auto numbers = [](const char* description, int n) {
    json a = {{"type", "array"}, {"items", {{"type", "number"}}}, {"description", description}};
    if (n > 0) {
      a["minItems"] = n;
      a["maxItems"] = n;
    }
    return a;
  };
  const json s = {
      {"title", "foxglove.CameraCalibration"},
      {"description", "Camera calibration parameters"},
      {"type", "object"},
      {"properties",
       {{"timestamp", fj::time_schema()},
        {"frame_id", {{"type", "string"}, {"description", "Frame of reference for the camera"}}},
        {"width", {{"type", "integer"}, {"minimum", 0}, {"description", "Image width"}}},
        {"height", {{"type", "integer"}, {"minimum", 0}, {"description", "Image height"}}},
        {"distortion_model",
         {{"type", "string"},
          {"description", "Name of distortion model: plumb_bob or kannala_brandt"}}},
        {"D", numbers("Distortion parameters", 0)},
        {"K", numbers("Intrinsic camera matrix (3x3 row-major matrix)", 9)},
        {"R", numbers("Rectification matrix (3x3 row-major matrix)", 9)},
        {"P", numbers("Projection/camera matrix (3x4 row-major matrix)", 12)}}},
      {"required",
       {"timestamp", "frame_id", "width", "height", "distortion_model", "D", "K", "R", "P"}}};
  return s.dump();
}

// One camera's calibration as Foxglove's CameraCalibration, without its timestamp: the members
// after it, for `{"timestamp":...,` + this. The images are the raw ones, so R is the identity
// and P is [K | 0] (Foxglove undistorts with K and D, then projects with P); radial-tangential is
// OpenCV's plumb_bob (k1 k2 p1 p2 k3, k3 zero when absent), equidistant its fisheye model,
// Foxglove's kannala_brandt (k1..k4).
std::string camera_calibration_members(const CameraCalibration& c, const std::string& frame_id) {
  std::vector<double> d = c.distortion;
  std::string model = "kannala_brandt";
  if (c.distortion_model == "radial-tangential") {
    model = "plumb_bob";
    d.resize(5, 0.0);
  }
  const json j = {{"frame_id", frame_id},
                  {"width", c.width_px},
                  {"height", c.height_px},
                  {"distortion_model", model},
                  {"D", d},
                  {"K", {c.fx, 0.0, c.cx, 0.0, c.fy, c.cy, 0.0, 0.0, 1.0}},
                  {"R", {1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0}},
                  {"P", {c.fx, 0.0, c.cx, 0.0, 0.0, c.fy, c.cy, 0.0, 0.0, 0.0, 1.0, 0.0}}};
  std::string text = j.dump();
  return text.substr(1);  // without the opening brace
}

std::string imu_schema() {
  const json s = {
      {"title", "wallar.Imu"},
      {"description", "One IMU sample in the body (IMU) frame"},
      {"type", "object"},
      {"properties",
       {{"timestamp", fj::time_schema()},
        {"frame_id", {{"type", "string"}}},
        {"angular_velocity", vector3_schema("angular rate [rad/s]")},
        {"linear_acceleration", vector3_schema("specific force [m/s^2]")},
        {"magnetic_field", vector3_schema("magnetic field [uT], when measured")},
        {"temperature", {{"type", "number"}, {"description", "die temperature [deg C]"}}}}},
      {"required", {"timestamp", "angular_velocity", "linear_acceleration"}}};
  return s.dump();
}

std::string ground_truth_schema() {
  const json s = {
      {"title", "wallar.GroundTruthState"},
      {"description", "The body's pose in the world frame, its velocity and the IMU biases"},
      {"type", "object"},
      {"properties",
       {{"timestamp", fj::time_schema()},
        {"frame_id", {{"type", "string"}}},
        {"position", vector3_schema("body origin in the world frame [m]")},
        {"orientation",
         {{"type", "object"},
          {"title", "foxglove.Quaternion"},
          {"properties",
           {{"x", {{"type", "number"}}},
            {"y", {{"type", "number"}}},
            {"z", {{"type", "number"}}},
            {"w", {{"type", "number"}}}}}}},
        {"velocity", vector3_schema("world frame [m/s]")},
        {"gyro_bias", vector3_schema("[rad/s]")},
        {"accel_bias", vector3_schema("[m/s^2]")}}},
      {"required", {"timestamp", "position", "orientation"}}};
  return s.dump();
}

std::span<const std::uint8_t> bytes_of(const std::string& s) {
  return {reinterpret_cast<const std::uint8_t*>(s.data()), s.size()};
}

std::uint64_t log_time(TimeNs t_ns, const fs::path& path) {
  if (t_ns < 0) {
    throw_input_error(path.string(), 0,
                      "sample time " + std::to_string(t_ns) +
                          " ns is negative (MCAP times are "
                          "unsigned)");
  }
  return static_cast<std::uint64_t>(t_ns);
}

// ---- reading ----------------------------------------------------------------------------------

// Errors while decoding one message name the file, topic and time.
struct MessageContext {
  const fs::path* path;
  const char* topic;
  std::uint64_t t_ns;
  [[noreturn]] void fail(const std::string& what) const {
    throw_input_error(path->string(), 0,
                      std::string(topic) + " message at t=" + std::to_string(t_ns) + ": " + what);
  }
};

json parse_message(const std::vector<std::uint8_t>& data, const MessageContext& ctx) {
  json j = json::parse(data.begin(), data.end(), nullptr, false);
  if (j.is_discarded() || !j.is_object()) ctx.fail("not a JSON object");
  return j;
}

double number_at(const json& j, const char* key, const MessageContext& ctx) {
  const auto it = j.find(key);
  if (it == j.end() || !it->is_number()) ctx.fail(std::string("'") + key + "' is not a number");
  const double v = it->get<double>();
  if (!std::isfinite(v)) ctx.fail(std::string("'") + key + "' is not finite");
  return v;
}

Eigen::Vector3d vec3_at(const json& j, const char* key, const MessageContext& ctx) {
  const auto it = j.find(key);
  if (it == j.end() || !it->is_object()) ctx.fail(std::string("no '") + key + "' {x, y, z}");
  return {number_at(*it, "x", ctx), number_at(*it, "y", ctx), number_at(*it, "z", ctx)};
}

// The value of the object member `"key": "..."` when it is a string without escapes, found
// without parsing the rest. A match is a member name only when a ':' follows it (a string value
// followed by ':' is not JSON) and no backslash precedes it (inside a string the quotes would be
// escaped). nullopt when absent or not that simple: the caller then parses the message.
std::optional<std::string_view> plain_string_member(std::string_view text, std::string_view key) {
  const std::string quoted = "\"" + std::string(key) + "\"";
  for (std::size_t at = text.find(quoted); at != std::string_view::npos;
       at = text.find(quoted, at + 1)) {
    if (at > 0 && text[at - 1] == '\\') continue;
    std::size_t p = at + quoted.size();
    auto skip_space = [&] {
      while (p < text.size() &&
             (text[p] == ' ' || text[p] == '\n' || text[p] == '\r' || text[p] == '\t'))
        ++p;
    };
    skip_space();
    if (p >= text.size() || text[p] != ':') continue;
    ++p;
    skip_space();
    if (p >= text.size() || text[p] != '"') return std::nullopt;
    const std::size_t end = text.find_first_of("\"\\", p + 1);
    if (end == std::string_view::npos || text[end] != '"') return std::nullopt;
    return text.substr(p + 1, end - p - 1);
  }
  return std::nullopt;
}

class McapFrames final : public FrameStore {
 public:
  explicit McapFrames(std::shared_ptr<const mcap::File> file) : file_(std::move(file)) {}

  std::vector<std::uint8_t> encoded(int cam, const FrameEntry& f) const override {
    const MessageContext ctx{&file_->path(), kCamTopic[cam], static_cast<std::uint64_t>(f.t_ns)};
    const std::vector<std::uint8_t> message =
        file_->read_message(file_->messages().at(f.store_index));
    std::vector<std::uint8_t> png;
    // The usual message (ours, or any writer's that escapes nothing in these two strings) is
    // read without building a JSON tree of the 0.3 MB string; anything else takes the parser.
    const std::string_view text(reinterpret_cast<const char*>(message.data()), message.size());
    const std::optional<std::string_view> format = plain_string_member(text, "format");
    const std::optional<std::string_view> data = plain_string_member(text, "data");
    if (format && *format == "png" && data && base64_decode(*data, png)) return png;
    const json j = parse_message(message, ctx);
    const auto format_it = j.find("format");
    if (format_it == j.end() || !format_it->is_string() || *format_it != "png") {
      ctx.fail("image format is not \"png\"");
    }
    const auto data_it = j.find("data");
    if (data_it == j.end() || !data_it->is_string() ||
        !base64_decode(data_it->get_ref<const std::string&>(), png)) {
      ctx.fail("'data' is not base64");
    }
    return png;
  }

  std::string describe(int cam, const FrameEntry& f) const override {
    return file_->path().string() + ": " + kCamTopic[cam] +
           " message at t=" + std::to_string(f.t_ns);
  }

 private:
  std::shared_ptr<const mcap::File> file_;
};

}  // namespace

// ---- base64 (RFC 4648, with padding): how JSON Schema's contentEncoding carries bytes. -------

constexpr char kB64[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";

std::string base64_encode(std::span<const std::uint8_t> in) {
  std::string out;
  out.reserve((in.size() + 2) / 3 * 4);
  std::size_t i = 0;
  for (; i + 3 <= in.size(); i += 3) {
    const std::uint32_t v = (in[i] << 16) | (in[i + 1] << 8) | in[i + 2];
    out += kB64[(v >> 18) & 63];
    out += kB64[(v >> 12) & 63];
    out += kB64[(v >> 6) & 63];
    out += kB64[v & 63];
  }
  if (i + 1 == in.size()) {
    const std::uint32_t v = in[i] << 16;
    out += kB64[(v >> 18) & 63];
    out += kB64[(v >> 12) & 63];
    out += "==";
  } else if (i + 2 == in.size()) {
    const std::uint32_t v = (in[i] << 16) | (in[i + 1] << 8);
    out += kB64[(v >> 18) & 63];
    out += kB64[(v >> 12) & 63];
    out += kB64[(v >> 6) & 63];
    out += '=';
  }
  return out;
}

// Decodes base64; false on a character outside the alphabet or a bad length/padding.
bool base64_decode(std::string_view in, std::vector<std::uint8_t>& out) {
  static const auto table = [] {
    std::array<std::int8_t, 256> t{};
    t.fill(-1);
    for (int i = 0; i < 64; ++i)
      t[static_cast<unsigned char>(kB64[i])] = static_cast<std::int8_t>(i);
    return t;
  }();
  if (in.size() % 4 != 0) return false;
  out.clear();
  out.reserve(in.size() / 4 * 3);
  for (std::size_t i = 0; i < in.size(); i += 4) {
    int pad = 0;
    std::uint32_t v = 0;
    for (std::size_t k = 0; k < 4; ++k) {
      const char c = in[i + k];
      if (c == '=' && i + 4 == in.size() && k >= 2) {
        ++pad;
        v <<= 6;
        continue;
      }
      const std::int8_t d = table[static_cast<unsigned char>(c)];
      if (d < 0 || pad > 0) return false;
      v = (v << 6) | static_cast<std::uint32_t>(d);
    }
    out.push_back(static_cast<std::uint8_t>(v >> 16));
    if (pad < 2) out.push_back(static_cast<std::uint8_t>(v >> 8));
    if (pad < 1) out.push_back(static_cast<std::uint8_t>(v));
  }
  return true;
}

// ---- writer -----------------------------------------------------------------------------------

McapRecordingWriter::McapRecordingWriter(const fs::path& path, const RigCalibration& rig,
                                         const McapRecordingOptions& options,
                                         bool with_ground_truth)
    : path_(path), with_ground_truth_(with_ground_truth) {
  std::error_code ec;
  if (fs::exists(path, ec))
    throw_input_error(path.string(), 0, "already exists; refusing to overwrite it");
  mcap::WriterOptions o;
  o.compression = options.compression;
  o.chunk_bytes = options.chunk_bytes;
  o.library = "wallar";
  writer_ = std::make_unique<mcap::Writer>(path, o);
  mcap::StringMap rig_files;
  for (int i = 0; i < 2; ++i) {
    rig_files["cam" + std::to_string(i) + "/sensor.yaml"] =
        format_camera_sensor_yaml(rig.cams[static_cast<std::size_t>(i)]);
  }
  if (rig.imu.rate_hz > 0.0) rig_files["imu0/sensor.yaml"] = format_imu_sensor_yaml(rig.imu);
  writer_->add_metadata(kRigMetadata, rig_files);
  const std::uint16_t image = writer_->add_schema("foxglove.CompressedImage", "jsonschema",
                                                  bytes_of(fj::compressed_image_schema().dump()));
  const std::uint16_t calibration = writer_->add_schema("foxglove.CameraCalibration", "jsonschema",
                                                        bytes_of(camera_calibration_schema()));
  for (int i = 0; i < 2; ++i) {
    const auto k = static_cast<std::size_t>(i);
    cam_channel_[k] = writer_->add_channel(image, kCamTopic[i], "json");
    calibration_channel_[k] =
        writer_->add_channel(calibration, std::string(kCamTopic[i]) + "/calibration", "json");
    calibration_members_[k] = camera_calibration_members(rig.cams[k], "cam" + std::to_string(i));
  }
  const std::uint16_t imu = writer_->add_schema("wallar.Imu", "jsonschema", bytes_of(imu_schema()));
  imu_channel_ = writer_->add_channel(imu, kImuTopic, "json");
  if (with_ground_truth_) {
    const std::uint16_t gt = writer_->add_schema("wallar.GroundTruthState", "jsonschema",
                                                 bytes_of(ground_truth_schema()));
    gt_channel_ = writer_->add_channel(gt, kGroundTruthTopic, "json");
  }
}

McapRecordingWriter::~McapRecordingWriter() = default;  // the mcap::Writer closes the file

void McapRecordingWriter::write_imu(const ImuSample& s) {
  json j = {{"timestamp", fj::time(s.t_ns)},
            {"frame_id", "imu0"},
            {"angular_velocity", fj::vector3(s.gyro_rad_s)},
            {"linear_acceleration", fj::vector3(s.accel_m_s2)}};
  if (s.mag_uT) j["magnetic_field"] = fj::vector3(*s.mag_uT);
  if (s.temperature_c) j["temperature"] = *s.temperature_c;
  const std::uint64_t t = log_time(s.t_ns, path_);
  writer_->write_message(imu_channel_, t, t, bytes_of(j.dump()));
  ++imu_;
}

void McapRecordingWriter::write_camera_png(int cam, TimeNs t_ns,
                                           std::span<const std::uint8_t> png) {
  const auto k = static_cast<std::size_t>(cam);
  const json j = {{"timestamp", fj::time(t_ns)},
                  {"frame_id", "cam" + std::to_string(cam)},
                  {"data", base64_encode(png)},
                  {"format", "png"}};
  const std::uint64_t t = log_time(t_ns, path_);
  writer_->write_message(cam_channel_[k], t, t, bytes_of(j.dump()));
  // Its calibration beside each image, as Foxglove's image and 3-D panels pair them (a seek
  // anywhere in the file finds one at the image's time).
  const std::string calibration =
      "{\"timestamp\":" + fj::time(t_ns).dump() + "," + calibration_members_[k];
  writer_->write_message(calibration_channel_[k], t, t, bytes_of(calibration));
  ++frames_[k];
}

void McapRecordingWriter::write_camera(int cam, const CameraFrame& frame) {
  write_camera_png(cam, frame.t_ns, encode_png_gray(frame.image, path_.string()));
}

void McapRecordingWriter::write_ground_truth(const GroundTruthState& g) {
  if (!with_ground_truth_) {
    throw_input_error(path_.string(), 0, "this recording was opened without ground truth");
  }
  const Eigen::Quaterniond q(g.T_world_body.linear());
  const json j = {{"timestamp", fj::time(g.t_ns)},
                  {"frame_id", "world"},
                  {"position", fj::vector3(g.T_world_body.translation())},
                  {"orientation", fj::quaternion(q)},
                  {"velocity", fj::vector3(g.vel_world_m_s)},
                  {"gyro_bias", fj::vector3(g.gyro_bias_rad_s)},
                  {"accel_bias", fj::vector3(g.accel_bias_m_s2)}};
  const std::uint64_t t = log_time(g.t_ns, path_);
  writer_->write_message(gt_channel_, t, t, bytes_of(j.dump()));
}

std::uint16_t McapRecordingWriter::add_json_channel(const std::string& schema_name,
                                                    const std::string& json_schema,
                                                    const std::string& topic) {
  const std::uint16_t schema =
      writer_->add_schema(schema_name, "jsonschema", bytes_of(json_schema));
  return writer_->add_channel(schema, topic, "json");
}

void McapRecordingWriter::write_json(std::uint16_t channel, TimeNs t_ns, const std::string& json) {
  const std::uint64_t t = log_time(t_ns, path_);
  writer_->write_message(channel, t, t, bytes_of(json));
}

void McapRecordingWriter::close() { writer_->close(); }

// ---- reader -----------------------------------------------------------------------------------

bool is_mcap_recording(const fs::path& path) {
  std::error_code ec;
  return fs::is_regular_file(path, ec) && mcap::is_mcap_file(path);
}

EurocRecording read_mcap_recording(const fs::path& path, bool require_cameras) {
  std::shared_ptr<const mcap::File> file = mcap::File::open(path);
  const std::string name = path.string();
  EurocRecording rec;
  rec.mav0 = path;
  const mcap::ReadReport& report = file->report();
  if (!report.complete) {
    char note[512];
    std::snprintf(note, sizeof note,
                  "%s: cut off or damaged: read %llu of %llu bytes, %llu whole chunks (%zu "
                  "messages); what follows is lost: %s",
                  name.c_str(), static_cast<unsigned long long>(report.bytes_used),
                  static_cast<unsigned long long>(report.file_bytes),
                  static_cast<unsigned long long>(report.chunks), file->messages().size(),
                  report.stop_reason.c_str());
    rec.read_note = note;
  }

  // The calibration.
  const mcap::StringMap* rig = nullptr;
  for (const auto& [n, m] : file->metadata()) {
    if (n == kRigMetadata) rig = &m;
  }
  if (rig == nullptr) {
    throw_input_error(name, 0,
                      std::string("no '") + kRigMetadata +
                          "' metadata (the cameras' calibration); not a wallar recording");
  }
  for (int i = 0; i < 2; ++i) {
    const std::string key = "cam" + std::to_string(i) + "/sensor.yaml";
    const auto it = rig->find(key);
    if (it == rig->end() && !require_cameras) continue;
    if (it == rig->end()) throw_input_error(name, 0, "'wallar.rig' metadata has no " + key);
    CameraStream& cam = rec.cams[static_cast<std::size_t>(i)];
    cam.calib = parse_camera_sensor_yaml(it->second, name + ": " + key);
    cam.calib.name = "cam" + std::to_string(i);
    cam.dir = path;
  }
  if (const auto it = rig->find("imu0/sensor.yaml"); it != rig->end()) {
    rec.imu_calib = parse_imu_sensor_yaml(it->second, name + ": imu0/sensor.yaml");
  }

  // The channels, by topic.
  std::map<std::uint16_t, int> role;  // channel -> 0, 1 camera, 2 IMU, 3 ground truth
  for (const auto& [id, ch] : file->channels()) {
    int r = -1;
    if (ch.topic == kCamTopic[0]) r = 0;
    if (ch.topic == kCamTopic[1]) r = 1;
    if (ch.topic == kImuTopic) r = 2;
    if (ch.topic == kGroundTruthTopic) r = 3;
    if (r < 0) continue;  // another tool's channel: not ours to read
    if (ch.message_encoding != "json") {
      throw_input_error(name, 0,
                        "channel " + ch.topic + " is '" + ch.message_encoding +
                            "'-encoded; wallar reads \"json\"");
    }
    role[id] = r;
  }
  for (int i = 0; i < 2; ++i) {
    const bool found =
        std::any_of(role.begin(), role.end(), [i](const auto& e) { return e.second == i; });
    if (!found && require_cameras) {
      throw_input_error(name, 0,
                        std::string("no ") + kCamTopic[i] +
                            " channel (a stereo recording needs /cam0 and /cam1)");
    }
  }

  const auto& messages = file->messages();
  for (std::size_t k = 0; k < messages.size(); ++k) {
    const mcap::MessageRef& m = messages[k];
    const auto r = role.find(m.channel_id);
    if (r == role.end()) continue;
    if (m.log_time_ns > static_cast<std::uint64_t>(INT64_MAX)) {
      throw_input_error(
          name, 0,
          "message at t=" + std::to_string(m.log_time_ns) + " is past the int64 nanosecond range");
    }
    const auto t_ns = static_cast<TimeNs>(m.log_time_ns);
    if (r->second < 2) {
      FrameEntry f;
      f.t_ns = t_ns;
      f.filename = std::to_string(t_ns) + ".png";
      f.line = static_cast<int>(std::min<std::size_t>(k + 1, INT32_MAX));
      f.store_index = k;
      rec.cams[static_cast<std::size_t>(r->second)].frames.push_back(std::move(f));
      continue;
    }
    const MessageContext ctx{&path, r->second == 2 ? kImuTopic : kGroundTruthTopic, m.log_time_ns};
    const json j = parse_message(file->read_message(m), ctx);
    if (r->second == 2) {
      ImuSample s;
      s.t_ns = t_ns;
      s.gyro_rad_s = vec3_at(j, "angular_velocity", ctx);
      s.accel_m_s2 = vec3_at(j, "linear_acceleration", ctx);
      if (j.contains("magnetic_field")) s.mag_uT = vec3_at(j, "magnetic_field", ctx);
      if (j.contains("temperature")) s.temperature_c = number_at(j, "temperature", ctx);
      rec.imu.push_back(s);
    } else {
      GroundTruthState g;
      g.t_ns = t_ns;
      const auto o = j.find("orientation");
      if (o == j.end() || !o->is_object()) ctx.fail("no 'orientation' {x, y, z, w}");
      Eigen::Quaterniond q(number_at(*o, "w", ctx), number_at(*o, "x", ctx),
                           number_at(*o, "y", ctx), number_at(*o, "z", ctx));
      if (std::abs(q.norm() - 1.0) > 1e-3) ctx.fail("'orientation' is not a unit quaternion");
      q.normalize();
      g.T_world_body = SE3d::Identity();
      g.T_world_body.linear() = q.toRotationMatrix();
      g.T_world_body.translation() = vec3_at(j, "position", ctx);
      if (j.contains("velocity")) g.vel_world_m_s = vec3_at(j, "velocity", ctx);
      if (j.contains("gyro_bias")) g.gyro_bias_rad_s = vec3_at(j, "gyro_bias", ctx);
      if (j.contains("accel_bias")) g.accel_bias_m_s2 = vec3_at(j, "accel_bias", ctx);
      rec.ground_truth.push_back(g);
    }
  }

  // Each stream in time order (a live recording writes in arrival order), one sample a time.
  auto order = [&](auto& v, const char* topic) {
    std::stable_sort(v.begin(), v.end(),
                     [](const auto& a, const auto& b) { return a.t_ns < b.t_ns; });
    for (std::size_t i = 1; i < v.size(); ++i) {
      if (v[i].t_ns == v[i - 1].t_ns) {
        throw_input_error(name, 0,
                          std::string(topic) + ": two messages at t=" + std::to_string(v[i].t_ns));
      }
    }
  };
  order(rec.cams[0].frames, kCamTopic[0]);
  order(rec.cams[1].frames, kCamTopic[1]);
  order(rec.imu, kImuTopic);
  order(rec.ground_truth, kGroundTruthTopic);
  if (!rec.imu.empty() && rec.imu_calib.rate_hz <= 0.0) {
    throw_input_error(name, 0, "has /imu0 samples but no imu0/sensor.yaml in 'wallar.rig'");
  }
  rec.store = std::make_shared<McapFrames>(std::move(file));
  return rec;
}

EurocRecording read_recording(const fs::path& path, const ReadOptions& options) {
  if (is_mcap_recording(path)) return read_mcap_recording(path);
  return read_euroc(path, options);
}

EurocRecording read_recording_imu(const fs::path& path) {
  if (is_mcap_recording(path)) return read_mcap_recording(path, false);
  return read_euroc_imu(path);
}

// ---- converter --------------------------------------------------------------------------------

namespace {

// Every stream of `rec` in time order (IMU first on ties, as replay delivers them) into the
// writer's write_imu, write_camera_png and write_ground_truth.
template <typename Writer>
ConvertCounts copy_streams(const EurocRecording& rec, Writer& writer) {
  ConvertCounts counts;
  std::size_t i_imu = 0;
  std::size_t i_gt = 0;
  std::array<std::size_t, 2> i_cam{0, 0};
  for (;;) {
    TimeNs t = INT64_MAX;
    int which = -1;  // 0, 1 camera, 2 IMU, 3 ground truth
    if (i_imu < rec.imu.size()) {
      t = rec.imu[i_imu].t_ns;
      which = 2;
    }
    for (int c = 0; c < 2; ++c) {
      const auto& frames = rec.cams[static_cast<std::size_t>(c)].frames;
      const std::size_t i = i_cam[static_cast<std::size_t>(c)];
      if (i < frames.size() && frames[i].t_ns < t) {
        t = frames[i].t_ns;
        which = c;
      }
    }
    if (i_gt < rec.ground_truth.size() && rec.ground_truth[i_gt].t_ns < t) which = 3;
    if (which < 0) break;
    if (which == 2) {
      writer.write_imu(rec.imu[i_imu++]);
      ++counts.imu;
    } else if (which == 3) {
      writer.write_ground_truth(rec.ground_truth[i_gt++]);
      ++counts.ground_truth;
    } else {
      const auto c = static_cast<std::size_t>(which);
      const FrameEntry& f = rec.cams[c].frames[i_cam[c]++];
      writer.write_camera_png(which, f.t_ns, load_frame_encoded(rec, which, f));
      ++counts.frames[c];
    }
  }
  return counts;
}

}  // namespace

ConvertCounts write_streams(const EurocRecording& rec, McapRecordingWriter& writer) {
  return copy_streams(rec, writer);
}

ConvertCounts convert_recording(const EurocRecording& rec, const fs::path& out, bool to_mcap,
                                const McapRecordingOptions& options) {
  std::error_code ec;
  if (!to_mcap && fs::exists(out / "mav0", ec)) {
    throw_input_error(out.string(), 0,
                      "already holds a recording (mav0/); refusing to overwrite it");
  }
  if (to_mcap) {
    McapRecordingWriter w(out, rec.rig(), options, !rec.ground_truth.empty());
    ConvertCounts counts = copy_streams(rec, w);
    w.close();
    counts.bytes_written = w.bytes_written();
    return counts;
  }
  EurocWriter w(out, rec.rig());
  ConvertCounts counts = copy_streams(rec, w);
  w.close();
  counts.bytes_written = w.bytes_written();
  return counts;
}

}  // namespace wallar::recording

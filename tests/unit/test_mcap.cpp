// SPDX-License-Identifier: Apache-2.0
/// @file test_mcap.cpp
/// @brief MCAP: the container round trip in every compression, files cut at random bytes read
/// up to their last complete chunk, damage found by the CRCs, and wallar's recording layout
/// (every sample, pixel and calibration value back exactly; EuRoC -> MCAP -> EuRoC).
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <random>
#include <string>
#include <vector>

#include "test_support.hpp"
#include "wallar/drivers/recording/csv.hpp"
#include "wallar/drivers/recording/mcap.hpp"
#include "wallar/drivers/recording/mcap_recording.hpp"

namespace wallar::test {
namespace {
namespace fs = std::filesystem;
namespace mcap = recording::mcap;

std::vector<std::uint8_t> file_bytes(const fs::path& p) {
  const std::string s = recording::read_text_file(p);
  return {s.begin(), s.end()};
}

void write_bytes(const fs::path& p, const std::vector<std::uint8_t>& b, std::size_t n) {
  std::ofstream out(p, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(b.data()), static_cast<std::streamsize>(n));
}

struct Written {
  std::vector<std::uint16_t> channel;
  std::vector<std::uint64_t> t_ns;
  std::vector<std::vector<std::uint8_t>> data;
};

// Two channels, `n` messages of seeded random sizes (0-3000 bytes, partly compressible), each
// chunk closing after `per_chunk` messages (the span option: one message every 1 ms).
Written write_file(const fs::path& p, mcap::Compression c, int n, int per_chunk, unsigned seed) {
  mcap::WriterOptions o;
  o.compression = c;
  o.chunk_bytes = 1u << 30;
  o.chunk_span_ns = static_cast<std::int64_t>(per_chunk - 1) * 1'000'000;
  mcap::Writer w(p, o);
  const std::string schema = R"({"type":"object"})";
  const std::uint16_t s =
      w.add_schema("test.Blob", "jsonschema",
                   {reinterpret_cast<const std::uint8_t*>(schema.data()), schema.size()});
  const std::uint16_t a = w.add_channel(s, "/a", "x-blob", {{"k", "v"}});
  const std::uint16_t b = w.add_channel(s, "/b", "x-blob");
  w.add_metadata("wallar.test", {{"seed", std::to_string(seed)}, {"empty", ""}});
  std::mt19937 rng(seed);
  Written out;
  for (int i = 0; i < n; ++i) {
    const std::uint16_t ch = (rng() % 3 == 0) ? b : a;
    std::vector<std::uint8_t> d(rng() % 3001);
    for (std::size_t k = 0; k < d.size(); ++k) {
      d[k] = static_cast<std::uint8_t>(k % 7 == 0 ? rng() : k / 13);
    }
    const std::uint64_t t = 1'000'000'000ull + static_cast<std::uint64_t>(i) * 1'000'000;
    w.write_message(ch, t, t + 5, d);
    out.channel.push_back(ch);
    out.t_ns.push_back(t);
    out.data.push_back(std::move(d));
  }
  w.close();
  return out;
}

TEST(Mcap, EveryCompressionRoundTripsSchemasChannelsMetadataAndMessages) {
  TempDir dir;
  for (const auto c :
       {mcap::Compression::kNone, mcap::Compression::kZstd, mcap::Compression::kLz4}) {
    const fs::path p = dir.path() / (std::string("f_") + mcap::compression_name(c) + ".mcap");
    const Written w = write_file(p, c, 500, 37, 7);
    ASSERT_TRUE(mcap::is_mcap_file(p));
    const auto f = mcap::File::open(p);
    EXPECT_TRUE(f->report().complete) << f->report().stop_reason;
    EXPECT_TRUE(f->report().summary_checked);
    EXPECT_EQ(f->report().chunks, (500u + 36u) / 37u);
    ASSERT_EQ(f->schemas().size(), 1u);
    EXPECT_EQ(f->schemas().at(1).name, "test.Blob");
    ASSERT_EQ(f->channels().size(), 2u);
    EXPECT_EQ(f->channels().at(0).topic, "/a");
    EXPECT_EQ(f->channels().at(0).metadata.at("k"), "v");
    EXPECT_EQ(f->channels().at(1).message_encoding, "x-blob");
    ASSERT_EQ(f->metadata().size(), 1u);
    EXPECT_EQ(f->metadata()[0].second.at("seed"), "7");
    EXPECT_EQ(f->metadata()[0].second.at("empty"), "");
    ASSERT_EQ(f->messages().size(), w.data.size());
    for (std::size_t i = 0; i < w.data.size(); ++i) {
      const mcap::MessageRef& m = f->messages()[i];
      EXPECT_EQ(m.channel_id, w.channel[i]);
      EXPECT_EQ(m.log_time_ns, w.t_ns[i]);
      EXPECT_EQ(m.publish_time_ns, w.t_ns[i] + 5);
      ASSERT_EQ(f->read_message(m), w.data[i]) << "message " << i;
    }
  }
}

TEST(Mcap, CutAtTwentyRandomBytesReadsUpToTheLastCompleteChunkAndSaysSo) {
  TempDir dir;
  const fs::path whole = dir.path() / "whole.mcap";
  const Written w = write_file(whole, mcap::Compression::kZstd, 400, 20, 3);
  const std::vector<std::uint8_t> bytes = file_bytes(whole);
  std::mt19937 rng(20261206);
  std::uniform_int_distribution<std::size_t> at(0, bytes.size() - 1);
  for (int k = 0; k < 20; ++k) {
    const std::size_t cut = at(rng);
    const fs::path p = dir.path() / ("cut" + std::to_string(k) + ".mcap");
    write_bytes(p, bytes, cut);
    SCOPED_TRACE("cut at byte " + std::to_string(cut) + " of " + std::to_string(bytes.size()));
    if (cut < 8) {  // not even the magic: no recording at all, said as such
      EXPECT_NE(input_error_of([&] { mcap::File::open(p); }).find("not an MCAP file"),
                std::string::npos);
      continue;
    }
    const auto f = mcap::File::open(p);
    const mcap::ReadReport& r = f->report();
    EXPECT_FALSE(r.complete);
    EXPECT_FALSE(r.stop_reason.empty());
    EXPECT_EQ(r.file_bytes, cut);
    ASSERT_LE(r.bytes_used, cut);
    // Whole chunks only (20 messages each), the first ones of the file, every byte intact.
    const std::size_t n = f->messages().size();
    EXPECT_EQ(n % 20, 0u);
    EXPECT_EQ(n, r.chunks * 20);
    for (std::size_t i = 0; i < n; ++i) {
      ASSERT_EQ(f->read_message(f->messages()[i]), w.data[i]);
    }
    // And the record that follows is the one the cut went through: none complete was left.
    if (r.bytes_used + 9 <= cut) {
      std::uint64_t len = 0;
      for (int i = 0; i < 8; ++i) len |= std::uint64_t{bytes[r.bytes_used + 1 + i]} << (8 * i);
      EXPECT_GT(r.bytes_used + 9 + len, cut) << "a complete record was left unread";
    }
  }
}

// A disk that is full from the first byte: the writer says so naming the file, and leaves no
// file descriptor open (its constructor throws, so no destructor closes it).
TEST(Mcap, AFullDiskIsAnErrorNamingTheFileAndLeaksNoDescriptor) {
  if (!fs::exists("/dev/full")) GTEST_SKIP() << "no /dev/full";
  auto open_fds = [] {
    return std::distance(fs::directory_iterator("/proc/self/fd"), fs::directory_iterator{});
  };
  const auto before = open_fds();
  for (int i = 0; i < 3; ++i) {
    const std::string err = input_error_of([] { mcap::Writer w("/dev/full", {}); });
    EXPECT_NE(err.find("/dev/full"), std::string::npos) << err;
  }
  EXPECT_EQ(open_fds(), before);
}

TEST(Mcap, ADamagedChunkEndsTheReadThereAndIsNamed) {
  TempDir dir;
  const fs::path p = dir.path() / "d.mcap";
  const Written w = write_file(p, mcap::Compression::kNone, 60, 20, 5);
  std::vector<std::uint8_t> bytes = file_bytes(p);
  // One byte in the middle of a message of the second chunk (uncompressed: found verbatim).
  std::size_t victim = 20;
  while (w.data[victim].size() < 100) ++victim;
  ASSERT_LT(victim, 40u);
  const auto it =
      std::search(bytes.begin(), bytes.end(), w.data[victim].begin(), w.data[victim].end());
  ASSERT_NE(it, bytes.end());
  const auto flip = static_cast<std::size_t>(it - bytes.begin()) + w.data[victim].size() / 2;
  bytes[flip] ^= 0x5a;
  write_bytes(p, bytes, bytes.size());
  {
    const auto f = mcap::File::open(p);
    EXPECT_FALSE(f->report().complete);
    EXPECT_NE(f->report().stop_reason.find("a damaged chunk at byte"), std::string::npos)
        << f->report().stop_reason;
    EXPECT_NE(f->report().stop_reason.find("CRC"), std::string::npos);
    ASSERT_EQ(f->messages().size(), 20u);  // the first chunk, whole
    for (std::size_t i = 0; i < 20; ++i) EXPECT_EQ(f->read_message(f->messages()[i]), w.data[i]);
  }
  // Power loss on a file system that had grown the file but not written its last blocks:
  // zeros from the middle on. What precedes them reads; nothing crashes.
  const Written z = write_file(p, mcap::Compression::kZstd, 60, 20, 6);
  bytes = file_bytes(p);
  std::fill(bytes.begin() + static_cast<std::ptrdiff_t>(bytes.size() / 2), bytes.end(), 0);
  write_bytes(p, bytes, bytes.size());
  {
    const auto f = mcap::File::open(p);
    EXPECT_FALSE(f->report().complete);
    EXPECT_FALSE(f->report().stop_reason.empty());
    ASSERT_LT(f->messages().size(), 60u);
    EXPECT_EQ(f->messages().size() % 20, 0u);
    for (std::size_t i = 0; i < f->messages().size(); ++i) {
      EXPECT_EQ(f->read_message(f->messages()[i]), z.data[i]);
    }
  }
  const fs::path junk = dir.path() / "junk.mcap";
  write_bytes(junk, std::vector<std::uint8_t>(100, 7), 100);
  EXPECT_FALSE(mcap::is_mcap_file(junk));
  EXPECT_NE(input_error_of([&] { mcap::File::open(junk); }).find("not an MCAP file"),
            std::string::npos);
}

TEST(McapRecording, EverySampleFrameAndCalibrationValueComesBackExactly) {
  TempDir dir;
  const fs::path p = dir.path() / "rec.mcap";
  RigCalibration rig = small_rig();
  rig.imu.timeshift_cam_imu_ns = 1'250'000;
  std::vector<ImuSample> imu;
  std::vector<std::vector<std::uint8_t>> blobs;
  {
    // Out of time order on purpose (the extras are later than the stream written after them):
    // the reader orders each stream. write_small_stream closes the writer.
    recording::McapRecordingWriter w(p, rig, {}, true);
    ImuSample extra;  // a sample with the optional fields EuRoC cannot hold
    extra.t_ns = 5 * kNsPerS;
    extra.gyro_rad_s = Eigen::Vector3d(0.1, -1e-300, 3.0000000000000004);
    extra.accel_m_s2 = Eigen::Vector3d(1.0 / 3.0, 9.81, -2.5e-7);
    extra.mag_uT = Eigen::Vector3d(20.5, -3.25, 41.0);
    extra.temperature_c = 31.5;
    w.write_imu(extra);
    imu.push_back(extra);
    // Encoded blobs of every length mod 3 (base64 padding) come back byte for byte.
    for (std::size_t n : {0u, 1u, 2u, 3u, 4u, 5u, 1000u}) {
      std::vector<std::uint8_t> b(n);
      for (std::size_t k = 0; k < n; ++k) b[k] = static_cast<std::uint8_t>(k * 37 + n);
      w.write_camera_png(1, 6 * kNsPerS + static_cast<TimeNs>(n), b);
      blobs.push_back(b);
    }
    recording::GroundTruthState g;
    g.t_ns = 2 * kNsPerS;
    g.T_world_body.linear() =
        Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
    g.T_world_body.translation() = Eigen::Vector3d(1.5, -2.0, 0.25);
    g.vel_world_m_s = Eigen::Vector3d(0.1, 0.2, 0.3);
    w.write_ground_truth(g);
    write_small_stream(w, 12, 9);
  }
  // The same stream through the EuRoC writer: the reference for every value.
  const fs::path euroc = dir.path() / "euroc";
  {
    recording::EurocWriter w(euroc, rig);
    write_small_stream(w, 12, 9);
  }
  const recording::EurocRecording want = recording::read_euroc(euroc);
  const recording::EurocRecording got = recording::read_recording(p);
  EXPECT_TRUE(got.read_note.empty()) << got.read_note;
  ASSERT_NE(got.store, nullptr);
  ASSERT_EQ(got.imu.size(), want.imu.size() + 1);
  for (std::size_t i = 0; i < want.imu.size(); ++i) {
    EXPECT_EQ(got.imu[i].t_ns, want.imu[i].t_ns);
    EXPECT_EQ(got.imu[i].gyro_rad_s, want.imu[i].gyro_rad_s) << i;
    EXPECT_EQ(got.imu[i].accel_m_s2, want.imu[i].accel_m_s2) << i;
  }
  const ImuSample& e = got.imu.back();
  EXPECT_EQ(e.gyro_rad_s, imu[0].gyro_rad_s);
  EXPECT_EQ(e.accel_m_s2, imu[0].accel_m_s2);
  ASSERT_TRUE(e.mag_uT && e.temperature_c);
  EXPECT_EQ(*e.mag_uT, *imu[0].mag_uT);
  EXPECT_EQ(*e.temperature_c, 31.5);
  for (int c = 0; c < 2; ++c) {
    const auto& a = got.cams[static_cast<std::size_t>(c)];
    const auto& b = want.cams[static_cast<std::size_t>(c)];
    EXPECT_EQ(a.calib.fx, b.calib.fx);
    EXPECT_EQ(a.calib.distortion, b.calib.distortion);
    EXPECT_TRUE(a.calib.T_body_cam.isApprox(b.calib.T_body_cam, 0.0));
    EXPECT_EQ(a.calib.rate_hz, b.calib.rate_hz);
    for (std::size_t i = 0; i < b.frames.size(); ++i) {
      EXPECT_EQ(a.frames[i].t_ns, b.frames[i].t_ns);
      const Image x = recording::load_frame_gray(got, c, a.frames[i]);
      const Image y = recording::load_frame_gray(want, c, b.frames[i]);
      ASSERT_EQ(std::vector<std::uint8_t>(x.data(), x.data() + 48),
                std::vector<std::uint8_t>(y.data(), y.data() + 48));
    }
  }
  ASSERT_EQ(got.cams[1].frames.size(), want.cams[1].frames.size() + blobs.size());
  for (std::size_t k = 0; k < blobs.size(); ++k) {
    const auto& f = got.cams[1].frames[want.cams[1].frames.size() + k];
    EXPECT_EQ(recording::load_frame_encoded(got, 1, f), blobs[k]) << "blob " << k;
  }
  EXPECT_EQ(got.imu_calib.timeshift_cam_imu_ns, 1'250'000);
  EXPECT_EQ(got.imu_calib.gyro_noise_density, rig.imu.gyro_noise_density);
  ASSERT_EQ(got.ground_truth.size(), 1u);
  const Eigen::Matrix3d R =
      Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  EXPECT_TRUE(got.ground_truth[0].T_world_body.linear().isApprox(R, 1e-15));
  EXPECT_EQ(got.ground_truth[0].T_world_body.translation(), Eigen::Vector3d(1.5, -2.0, 0.25));
  EXPECT_EQ(got.ground_truth[0].vel_world_m_s, Eigen::Vector3d(0.1, 0.2, 0.3));
}

// Foxglove's CameraCalibration beside each image: radial-tangential as plumb_bob (k3 = 0),
// equidistant as kannala_brandt, K from the intrinsics, R identity and P = [K | 0] (raw images).
TEST(McapRecording, EachImageHasItsCameraCalibrationBesideIt) {
  TempDir dir;
  const fs::path p = dir.path() / "cal.mcap";
  RigCalibration rig = small_rig();
  rig.cams[1].distortion_model = "equidistant";
  rig.cams[1].distortion = {0.1, -0.02, 0.003, -0.0004};
  rig.cams[1].fx = 11.5;
  {
    recording::McapRecordingWriter w(p, rig);
    const std::vector<std::uint8_t> png = {1, 2, 3};
    for (TimeNs t_ns : {kNsPerS, 2 * kNsPerS}) {
      w.write_camera_png(0, t_ns, png);
      w.write_camera_png(1, t_ns, png);
    }
    w.close();
  }
  const auto f = mcap::File::open(p);
  std::map<std::uint16_t, std::string> topic;
  for (const auto& [id, ch] : f->channels()) {
    topic[id] = ch.topic;
    if (ch.topic.ends_with("/calibration")) {
      EXPECT_EQ(f->schemas().at(ch.schema_id).name, "foxglove.CameraCalibration");
    }
  }
  std::map<std::string, std::vector<nlohmann::json>> got;
  for (const mcap::MessageRef& m : f->messages()) {
    const std::vector<std::uint8_t> b = f->read_message(m);
    nlohmann::json j = nlohmann::json::parse(b.begin(), b.end());
    if (topic[m.channel_id].ends_with("/calibration")) {
      const TimeNs t_ns =
          j["timestamp"]["sec"].get<TimeNs>() * kNsPerS + j["timestamp"]["nsec"].get<TimeNs>();
      EXPECT_EQ(static_cast<std::uint64_t>(t_ns), m.log_time_ns);
    }
    got[topic[m.channel_id]].push_back(std::move(j));
  }
  ASSERT_EQ(got["/cam0/calibration"].size(), 2u);
  ASSERT_EQ(got["/cam1/calibration"].size(), 2u);
  const nlohmann::json& c0 = got["/cam0/calibration"][0];
  EXPECT_EQ(c0["frame_id"], "cam0");
  EXPECT_EQ(c0["frame_id"], got["/cam0"][0]["frame_id"]);
  EXPECT_EQ(c0["width"], 8);
  EXPECT_EQ(c0["height"], 6);
  EXPECT_EQ(c0["distortion_model"], "plumb_bob");
  EXPECT_EQ(c0["D"].get<std::vector<double>>(),
            (std::vector<double>{0.01, -0.002, 0.0001, 0.0, 0.0}));
  EXPECT_EQ(c0["K"].get<std::vector<double>>(),
            (std::vector<double>{10.0, 0.0, 4.0, 0.0, 10.0, 3.0, 0.0, 0.0, 1.0}));
  EXPECT_EQ(c0["R"].get<std::vector<double>>(),
            (std::vector<double>{1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0}));
  EXPECT_EQ(c0["P"].get<std::vector<double>>(),
            (std::vector<double>{10.0, 0.0, 4.0, 0.0, 0.0, 10.0, 3.0, 0.0, 0.0, 0.0, 1.0, 0.0}));
  const nlohmann::json& c1 = got["/cam1/calibration"][1];
  EXPECT_EQ(c1["frame_id"], "cam1");
  EXPECT_EQ(c1["distortion_model"], "kannala_brandt");
  EXPECT_EQ(c1["D"].get<std::vector<double>>(), rig.cams[1].distortion);
  EXPECT_EQ(c1["K"][0], 11.5);
  // The reader takes the calibration from the file's metadata and passes over these channels.
  const recording::EurocRecording r = recording::read_recording(p);
  EXPECT_EQ(r.cams[1].calib.distortion_model, "equidistant");
  EXPECT_EQ(r.cams[0].frames.size(), 2u);
}

TEST(McapRecording, TheBundledRecordingConvertsToMcapAndBackUnchanged) {
  TempDir dir;
  const fs::path src = fs::path(WALLAR_TEST_DATA) / "euroc_v1_01_still";
  const recording::EurocRecording rec = recording::read_recording(src);
  const fs::path m = dir.path() / "still.mcap";
  const recording::ConvertCounts c = recording::convert_recording(rec, m, true);
  EXPECT_EQ(c.frames[0], rec.cams[0].frames.size());
  EXPECT_EQ(c.imu, rec.imu.size());
  EXPECT_EQ(c.ground_truth, rec.ground_truth.size());
  const recording::EurocRecording mid = recording::read_recording(m);
  const fs::path back = dir.path() / "back";
  recording::convert_recording(mid, back, false);
  const recording::EurocRecording out = recording::read_recording(back);
  for (int i = 0; i < 2; ++i) {
    const auto& a = rec.cams[static_cast<std::size_t>(i)];
    const auto& b = out.cams[static_cast<std::size_t>(i)];
    ASSERT_EQ(a.frames.size(), b.frames.size());
    for (std::size_t k = 0; k < a.frames.size(); ++k) {
      EXPECT_EQ(a.frames[k].t_ns, b.frames[k].t_ns);
      ASSERT_EQ(file_bytes(a.image_path(a.frames[k])), file_bytes(b.image_path(b.frames[k])));
    }
  }
  EXPECT_EQ(recording::read_text_file(src / "mav0/imu0/data.csv"),
            recording::read_text_file(back / "mav0/imu0/data.csv"));
  ASSERT_EQ(out.ground_truth.size(), rec.ground_truth.size());
  for (std::size_t k = 0; k < rec.ground_truth.size(); ++k) {
    EXPECT_TRUE(out.ground_truth[k].T_world_body.isApprox(rec.ground_truth[k].T_world_body, 1e-12));
  }
  // Refuses to overwrite either way.
  EXPECT_NE(
      input_error_of([&] { recording::convert_recording(rec, m, true); }).find("already exists"),
      std::string::npos);
  EXPECT_NE(input_error_of([&] {
              recording::convert_recording(rec, back, false);
            }).find("already holds a recording"),
            std::string::npos);
}

}  // namespace
}  // namespace wallar::test

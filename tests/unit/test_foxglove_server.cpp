// SPDX-License-Identifier: Apache-2.0
/// @file test_foxglove_server.cpp
/// @brief The live server against Foxglove's own client (@foxglove/ws-protocol on ws, run with
/// Node.js from tools/node): serverInfo, the advertisement, subscriptions and messages under
/// their schemas; a client that never reads next to it (the other still served, publish()
/// never waits, the loss counted); bad client input answered with a status or a close; the
/// token; the options' errors.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>
#include <vector>

#include "test_support.hpp"
#include "wallar/drivers/net/foxglove_server.hpp"

namespace wallar::test {
namespace {

using net::FoxgloveServer;
using net::FoxgloveServerOptions;
using nlohmann::json;

const std::string kNodeDir = std::string(WALLAR_SOURCE_DIR) + "/tools/node";
const std::string kClient = std::string(WALLAR_SOURCE_DIR) + "/tests/net/foxglove_ws_client.cjs";

std::string schema_requiring(const std::string& field) {
  return json{
      {"type", "object"}, {"properties", {{field, {{"type", "integer"}}}}}, {"required", {field}}}
      .dump();
}

// Two channels, /a (messages {"n": i}) and /b ({"m": i}).
FoxgloveServerOptions local_options() {
  FoxgloveServerOptions o;
  o.port = 0;
  return o;
}
void add_two_channels(FoxgloveServer& s) {
  ASSERT_EQ(s.add_channel({"/a", "test.A", schema_requiring("n")}), 1u);
  ASSERT_EQ(s.add_channel({"/b", "test.B", schema_requiring("m")}), 2u);
}

// Runs the reference client to its end; returns its stdout and exit status.
struct NodeResult {
  std::string out;
  int status = -1;
};
NodeResult run_client(const std::string& url, const std::string& args) {
  NodeResult r;
  const std::string cmd = "node '" + kClient + "' '" + kNodeDir + "' '" + url + "' " + args;
  FILE* p = popen(cmd.c_str(), "r");
  if (p == nullptr) return r;
  char buf[4096];
  while (std::fgets(buf, sizeof buf, p) != nullptr) r.out += buf;
  r.status = pclose(p);
  return r;
}

bool have_node_client() {
  return std::system("command -v node >/dev/null 2>&1") == 0 &&
         std::filesystem::exists(kNodeDir + "/node_modules/@foxglove/ws-protocol") &&
         std::filesystem::exists(kNodeDir + "/node_modules/ws");
}

// Publishes on both channels every `period` until stopped; the longest publish() it saw.
class Publisher {
 public:
  Publisher(FoxgloveServer& s, std::size_t pad_bytes, std::chrono::microseconds period)
      : thread_([this, &s, pad_bytes, period] {
          const std::string pad(pad_bytes, 'x');
          for (std::int64_t i = 1; !stop_.load(); ++i) {
            const std::string a = json{{"n", i}, {"pad", pad}}.dump();
            const std::string b = json{{"m", i}}.dump();
            const auto t0 = std::chrono::steady_clock::now();
            s.publish(1, i * 1000, a);
            s.publish(2, i * 1000 + 1, b);
            const auto took = std::chrono::steady_clock::now() - t0;
            longest_ = std::max(longest_, took);
            std::this_thread::sleep_for(period);
          }
        }) {}
  ~Publisher() { stop(); }
  std::chrono::nanoseconds stop() {
    stop_.store(true);
    if (thread_.joinable()) thread_.join();
    return longest_;
  }

 private:
  std::atomic<bool> stop_{false};
  std::chrono::nanoseconds longest_{0};
  std::thread thread_;
};

// A WebSocket client by hand, for what a reference client will not do: never read, send
// garbage, send too much.
class RawClient {
 public:
  RawClient(int port, int rcvbuf_bytes = 0, const std::string& query = "") {
    fd_ = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    if (rcvbuf_bytes > 0) ::setsockopt(fd_, SOL_SOCKET, SO_RCVBUF, &rcvbuf_bytes, sizeof(int));
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_port = htons(static_cast<std::uint16_t>(port));
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    connected_ = ::connect(fd_, reinterpret_cast<sockaddr*>(&a), sizeof a) == 0;
    const std::string hello =
        "GET /" + query +
        " HTTP/1.1\r\nHost: 127.0.0.1\r\nUpgrade: websocket\r\n"
        "Connection: Upgrade\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n"
        "Sec-WebSocket-Version: 13\r\n"
        "Sec-WebSocket-Protocol: foxglove.websocket.v1\r\n\r\n";
    send_all(hello);
    std::string head;
    char c;
    while (head.find("\r\n\r\n") == std::string::npos && read_some(&c, 1)) head += c;
    upgraded_ = head.starts_with("HTTP/1.1 101");
  }
  ~RawClient() {
    if (fd_ >= 0) ::close(fd_);
  }
  [[nodiscard]] bool upgraded() const { return connected_ && upgraded_; }

  // A masked text frame (mask key 0: the payload goes as it is).
  void send_text(const std::string& text) {
    std::string f;
    f += static_cast<char>(0x81);
    if (text.size() < 126) {
      f += static_cast<char>(0x80 | text.size());
    } else {
      f += static_cast<char>(0x80 | 127);
      for (int i = 7; i >= 0; --i) f += static_cast<char>((text.size() >> (8 * i)) & 0xff);
    }
    f.append(4, '\0');
    send_all(f + text);
  }
  // The next frame's opcode and payload; opcode -1 on a closed socket or after 10 s.
  std::pair<int, std::string> read_frame() {
    unsigned char h[2];
    if (!read_exact(h, 2)) return {-1, ""};
    std::uint64_t n = h[1] & 0x7f;
    if (n >= 126) {
      unsigned char e[8];
      const int k = n == 126 ? 2 : 8;
      if (!read_exact(e, k)) return {-1, ""};
      n = 0;
      for (int i = 0; i < k; ++i) n = (n << 8) | e[i];
    }
    std::string payload(n, '\0');
    if (n > 0 && !read_exact(payload.data(), n)) return {-1, ""};
    return {h[0] & 0x0f, payload};
  }

 private:
  void send_all(const std::string& s) {
    std::size_t off = 0;
    while (off < s.size()) {
      const ssize_t w = ::send(fd_, s.data() + off, s.size() - off, MSG_NOSIGNAL);
      if (w <= 0) return;
      off += static_cast<std::size_t>(w);
    }
  }
  bool read_some(void* p, std::size_t n) {
    pollfd pfd{fd_, POLLIN, 0};
    if (::poll(&pfd, 1, 10000) != 1) return false;
    return ::recv(fd_, p, n, 0) > 0;
  }
  bool read_exact(void* p, std::size_t n) {
    auto* b = static_cast<char*>(p);
    std::size_t off = 0;
    while (off < n) {
      pollfd pfd{fd_, POLLIN, 0};
      if (::poll(&pfd, 1, 10000) != 1) return false;
      const ssize_t r = ::recv(fd_, b + off, n - off, 0);
      if (r <= 0) return false;
      off += static_cast<std::size_t>(r);
    }
    return true;
  }
  int fd_ = -1;
  bool connected_ = false;
  bool upgraded_ = false;
};

template <typename Pred>
bool wait_for(Pred pred, std::chrono::milliseconds limit = std::chrono::milliseconds(10000)) {
  const auto end = std::chrono::steady_clock::now() + limit;
  while (!pred()) {
    if (std::chrono::steady_clock::now() > end) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return true;
}

TEST(FoxgloveServer, TheReferenceClientGetsServerInfoChannelsAndMessagesUnderTheirSchemas) {
  ASSERT_TRUE(have_node_client()) << "no Node.js or no tools/node/node_modules (run tools/setup)";
  FoxgloveServer server(local_options());
  add_two_channels(server);
  server.start();
  ASSERT_GT(server.port(), 0);
  Publisher pub(server, 0, std::chrono::milliseconds(5));
  const NodeResult r = run_client("ws://127.0.0.1:" + std::to_string(server.port()), "5");
  pub.stop();
  ASSERT_EQ(r.status, 0) << r.out;
  const json j = json::parse(r.out);
  EXPECT_EQ(j["serverInfo"]["name"], "wallar");
  ASSERT_EQ(j["channels"].size(), 2u);
  EXPECT_EQ(j["channels"][0]["topic"], "/a");
  EXPECT_EQ(j["channels"][0]["schemaName"], "test.A");
  EXPECT_EQ(j["channels"][1]["id"], 2);
  EXPECT_GE(j["counts"]["/a"].get<int>(), 5);
  EXPECT_GE(j["counts"]["/b"].get<int>(), 5);
  // The binary header's time is the one published with the payload.
  const json& last = j["last"]["/a"];
  EXPECT_EQ(std::stoll(last["timestamp"].get<std::string>()),
            last["message"]["n"].get<std::int64_t>() * 1000);
  EXPECT_TRUE(wait_for([&] { return server.stats().clients_connected == 0; }));
  const auto st = server.stats();
  EXPECT_EQ(st.clients_total, 1u);
  EXPECT_GE(st.sent, 10u);
  EXPECT_EQ(st.client_errors, 0u);
  EXPECT_EQ(st.subscriptions, 0u);
  EXPECT_FALSE(server.has_subscribers(1));
}

TEST(FoxgloveServer, AClientThatNeverReadsCostsPublishNothingAndTheOtherIsStillServed) {
  ASSERT_TRUE(have_node_client()) << "no Node.js or no tools/node/node_modules (run tools/setup)";
  FoxgloveServer server(local_options());
  add_two_channels(server);
  server.start();
  // Subscribes to /a, then never reads: its socket's buffers fill with the first messages.
  RawClient stalled(server.port(), 4096);
  ASSERT_TRUE(stalled.upgraded());
  stalled.send_text(R"({"op":"subscribe","subscriptions":[{"id":7,"channelId":1}]})");
  ASSERT_TRUE(wait_for([&] { return server.stats().subscriptions == 1; }));
  {
    // 64 KiB messages every 2 ms (32 MB/s) while the reference client takes 40 of each.
    Publisher pub(server, 64 * 1024, std::chrono::milliseconds(2));
    const NodeResult r = run_client("ws://127.0.0.1:" + std::to_string(server.port()), "40");
    ASSERT_EQ(r.status, 0) << r.out;
    EXPECT_GE(json::parse(r.out)["counts"]["/a"].get<int>(), 40);
    // On to 400 messages of /a (26 MB): far more than the stalled client's socket buffers hold.
    EXPECT_TRUE(wait_for([&] { return server.stats().published >= 2 * 400u; },
                         std::chrono::milliseconds(30000)));
    // publish() copies and wakes; it never waits for a socket: a blocked write would hold it
    // for as long as the client does not read, here for ever. (The bound is loose for the
    // scheduling noise of a loaded 2-core machine, qemu and the sanitizers; natively each call
    // takes some 20 us.)
    EXPECT_LT(pub.stop(), std::chrono::milliseconds(500));
  }
  const auto st = server.stats();
  // The stalled client had what the socket buffers hold and lost the rest, counted (with what
  // the reference client missed between its reads).
  EXPECT_GT(st.dropped, 200u);
  EXPECT_LT(st.sent, st.published);
  EXPECT_EQ(st.clients_total, 2u);
}

TEST(FoxgloveServer, BadClientInputGetsAStatusOrACloseAndTheServerServesOn) {
  FoxgloveServerOptions o = local_options();
  o.max_client_message_bytes = 1024;
  FoxgloveServer server(o);
  add_two_channels(server);
  server.start();
  RawClient c(server.port());
  ASSERT_TRUE(c.upgraded());
  auto [op1, info] = c.read_frame();
  ASSERT_EQ(op1, 1);
  EXPECT_EQ(json::parse(info)["op"], "serverInfo");
  auto [op2, adv] = c.read_frame();
  ASSERT_EQ(op2, 1);
  const json a = json::parse(adv);
  ASSERT_EQ(a["op"], "advertise");
  EXPECT_EQ(a["channels"][1]["topic"], "/b");
  EXPECT_EQ(a["channels"][1]["schema"], schema_requiring("m"));

  c.send_text("garbage");
  auto [op3, st1] = c.read_frame();
  ASSERT_EQ(op3, 1);
  EXPECT_EQ(json::parse(st1)["op"], "status");
  EXPECT_EQ(json::parse(st1)["level"], 2);
  c.send_text(R"({"op":"subscribe","subscriptions":[{"id":3,"channelId":99}]})");
  auto [op4, st2] = c.read_frame();
  ASSERT_EQ(op4, 1);
  EXPECT_NE(json::parse(st2)["message"].get<std::string>().find("no channel 99"),
            std::string::npos);

  // Still served: a subscription and its message, in Foxglove's binary layout.
  c.send_text(R"({"op":"subscribe","subscriptions":[{"id":3,"channelId":2}]})");
  ASSERT_TRUE(wait_for([&] { return server.has_subscribers(2); }));
  server.publish(2, 0x0102030405060708, R"({"m":1})");
  auto [op5, data] = c.read_frame();
  ASSERT_EQ(op5, 2);
  ASSERT_EQ(data.size(), 13u + 7u);
  EXPECT_EQ(data[0], 1);
  EXPECT_EQ(std::string(data, 1, 4), std::string("\x03\x00\x00\x00", 4));
  EXPECT_EQ(std::string(data, 5, 8), std::string("\x08\x07\x06\x05\x04\x03\x02\x01", 8));
  EXPECT_EQ(data.substr(13), R"({"m":1})");

  // Over the limit: that client is closed; another connects as before.
  c.send_text(std::string(2000, ' '));
  std::pair<int, std::string> f;
  do f = c.read_frame();
  while (f.first != -1 && f.first != 8);
  EXPECT_TRUE(wait_for([&] { return server.stats().clients_connected == 0; }));
  EXPECT_EQ(server.stats().client_errors, 2u);  // the garbage and the oversized message
  RawClient again(server.port());
  EXPECT_TRUE(again.upgraded());
}

TEST(FoxgloveServer, AChannelWithHistorySendsEveryKeptMessageInOrderAndCountsTheOnesPushedOut) {
  FoxgloveServer server(local_options());
  net::FoxgloveChannel log{"/log", "test.Log", schema_requiring("n")};
  log.history = 8;
  ASSERT_EQ(server.add_channel(log), 1u);
  server.start();
  // Published before anyone subscribed: the 8 newest are kept and sent to a new subscriber.
  for (int i = 1; i <= 12; ++i) server.publish(1, i, json{{"n", i}}.dump());
  RawClient c(server.port());
  ASSERT_TRUE(c.upgraded());
  ASSERT_EQ(c.read_frame().first, 1);  // serverInfo
  ASSERT_EQ(c.read_frame().first, 1);  // advertise
  c.send_text(R"({"op":"subscribe","subscriptions":[{"id":1,"channelId":1}]})");
  auto expect_next = [&](int want) {
    auto [op, data] = c.read_frame();
    ASSERT_EQ(op, 2) << "message n=" << want;
    EXPECT_EQ(json::parse(data.substr(13))["n"], want);
  };
  for (int want = 5; want <= 12; ++want) expect_next(want);
  // A burst (no more than the history) faster than any client reads: each one arrives, none
  // replaced the one before. (Published before the backlog above was sent, it would have
  // pushed the backlog's oldest out: that is the history's bound, seen under qemu.)
  for (int i = 13; i <= 16; ++i) server.publish(1, i, json{{"n", i}}.dump());
  for (int want = 13; want <= 16; ++want) expect_next(want);
  EXPECT_EQ(server.stats().sent, 12u);
  EXPECT_EQ(server.stats().dropped, 0u);  // nobody subscribed while 1-4 were pushed out
  // A client that reads nothing while 200 messages of 64 KiB (13 MB, beyond what the socket
  // buffers hold) come keeps the 8 newest and loses what neither held, counted.
  RawClient slow(server.port(), 4096);
  ASSERT_TRUE(slow.upgraded());
  slow.send_text(R"({"op":"subscribe","subscriptions":[{"id":2,"channelId":1}]})");
  c.send_text(R"({"op":"unsubscribe","subscriptionIds":[1]})");
  ASSERT_TRUE(wait_for([&] { return server.stats().subscriptions == 1; }));
  const std::string pad(64 * 1024, 'x');  // more than the socket buffers hold
  for (int i = 17; i <= 216; ++i) server.publish(1, i, json{{"n", i}, {"pad", pad}}.dump());
  EXPECT_GT(server.stats().dropped, 100u);
  int last = 0;
  for (;;) {
    auto [op, data] = slow.read_frame();
    if (op == 1) continue;  // serverInfo, advertise
    ASSERT_EQ(op, 2);
    const int n = json::parse(data.substr(13))["n"].get<int>();
    EXPECT_GT(n, last);  // in order, with gaps where messages were pushed out
    last = n;
    if (n == 216) break;
  }
}

// One plain HTTP/1.1 GET; the status code and the body ("" and -1 when nothing came).
std::pair<int, std::string> http_get(int port, const std::string& target) {
  const int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_port = htons(static_cast<std::uint16_t>(port));
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  if (::connect(fd, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0) {
    ::close(fd);
    return {-1, ""};
  }
  const std::string req =
      "GET " + target + " HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n\r\n";
  (void)!::send(fd, req.data(), req.size(), MSG_NOSIGNAL);
  std::string got;
  char buf[65536];
  for (;;) {
    pollfd pfd{fd, POLLIN, 0};
    if (::poll(&pfd, 1, 10000) != 1) break;
    const ssize_t r = ::recv(fd, buf, sizeof buf, 0);
    if (r <= 0) break;
    got.append(buf, static_cast<std::size_t>(r));
  }
  ::close(fd);
  const std::size_t body = got.find("\r\n\r\n");
  if (got.size() < 12 || body == std::string::npos) return {-1, ""};
  return {std::stoi(got.substr(9, 3)), got.substr(body + 4)};
}

TEST(FoxgloveServer, ServesItsFilesOverHttpOnTheSamePortAndNothingElse) {
  // A body larger than one 16 KiB piece, sent as the socket takes it.
  static const std::string big = [] {
    std::string b;
    for (int i = 0; b.size() < 100000; ++i) b += std::to_string(i) + ",";
    return b;
  }();
  FoxgloveServerOptions o = local_options();
  o.token = "tok";
  FoxgloveServer server(o);
  add_two_channels(server);
  server.add_http_file({"/", "text/html; charset=utf-8", "<html>page</html>"});
  server.add_http_file({"/big.js", "text/javascript", big});
  server.start();
  EXPECT_EQ(http_get(server.port(), "/?token=tok"),
            std::make_pair(200, std::string("<html>page</html>")));
  EXPECT_EQ(http_get(server.port(), "/big.js?token=tok"), std::make_pair(200, big));
  EXPECT_EQ(http_get(server.port(), "/etc/passwd?token=tok").first, 404);
  EXPECT_EQ(http_get(server.port(), "/").first, 403);  // no token
  EXPECT_EQ(http_get(server.port(), "/big.js?token=nope").first, 403);
  // The WebSocket side beside it, as before.
  RawClient ws(server.port(), 0, "?token=tok");
  ASSERT_TRUE(ws.upgraded());
  EXPECT_EQ(json::parse(ws.read_frame().second)["op"], "serverInfo");
  const auto st = server.stats();
  EXPECT_EQ(st.http_requests, 5u);
  EXPECT_EQ(st.clients_refused, 2u);
}

TEST(FoxgloveServer, WithATokenOnlyAClientThatCarriesItIsServed) {
  ASSERT_TRUE(have_node_client()) << "no Node.js or no tools/node/node_modules (run tools/setup)";
  FoxgloveServerOptions o = local_options();
  o.token = "s3cret-Token_1";
  FoxgloveServer server(o);
  add_two_channels(server);
  server.start();
  const std::string url = "ws://127.0.0.1:" + std::to_string(server.port());
  Publisher pub(server, 0, std::chrono::milliseconds(5));
  const NodeResult refused = run_client(url + "/?token=wrong", "--refused");
  EXPECT_EQ(refused.status, 0) << refused.out;
  const NodeResult none = run_client(url, "--refused");
  EXPECT_EQ(none.status, 0) << none.out;
  const NodeResult served = run_client(url + "/?token=s3cret-Token_1", "2 /b");
  EXPECT_EQ(served.status, 0) << served.out;
  pub.stop();
  EXPECT_EQ(server.stats().clients_refused, 2u);
  EXPECT_EQ(server.stats().clients_total, 1u);
}

TEST(FoxgloveServer, BadOptionsAndABusyPortAreOneLineErrors) {
  auto with = [](auto change) {
    FoxgloveServerOptions o;
    change(o);
    return input_error_of([&] { FoxgloveServer s(o); });
  };
  EXPECT_NE(with([](auto& o) { o.address = "localhost"; }).find("not an IPv4 address"),
            std::string::npos);
  EXPECT_NE(with([](auto& o) { o.port = 70000; }).find("port 70000"), std::string::npos);
  EXPECT_NE(with([](auto& o) { o.token = "a b"; }).find("token"), std::string::npos);
  FoxgloveServer first(local_options());
  first.start();
  FoxgloveServerOptions o = local_options();
  o.port = first.port();
  FoxgloveServer second(o);
  const std::string err = input_error_of([&] { second.start(); });
  EXPECT_NE(err.find("127.0.0.1:" + std::to_string(first.port())), std::string::npos) << err;
  EXPECT_NE(err.find("cannot listen"), std::string::npos) << err;
  EXPECT_EQ(err.find('\n'), std::string::npos);
  first.stop();
  first.stop();  // idempotent
}

}  // namespace
}  // namespace wallar::test

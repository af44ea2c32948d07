// SPDX-License-Identifier: Apache-2.0
/// @file foxglove_server.cpp
/// @brief Foxglove's WebSocket protocol on libwebsockets (see foxglove_server.hpp).
#include "wallar/drivers/net/foxglove_server.hpp"

#include <arpa/inet.h>
#include <libwebsockets.h>
#include <pthread.h>

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <deque>
#include <nlohmann/json.hpp>
#include <utility>

#include "wallar/core/error.hpp"

namespace wallar::net {
namespace {

using nlohmann::json;

constexpr std::uint8_t kMessageData = 1;        // server binary opcode
constexpr std::size_t kDataHeader = 1 + 4 + 8;  // opcode, subscription id, timestamp
constexpr int kStatusWarning = 1;
constexpr int kStatusError = 2;

struct Message {
  TimeNs t_ns = 0;
  std::uint64_t seq = 0;  // 1, 2, ... per channel
  std::string payload;
};

struct Subscription {
  std::uint32_t id = 0;
  std::uint32_t channel = 0;
  std::uint64_t sent_seq = 0;  // the newest message of the channel this client has had
};

struct Client;

// libwebsockets' per-connection data (zeroed by it): a WebSocket client, or an HTTP file
// being sent.
struct Session {
  Client* client;
  const HttpFile* file;
  std::size_t sent;
};

struct Client {
  lws* wsi = nullptr;
  std::deque<std::string> text_out;  // serverInfo, advertise, status: in order, before data
  std::vector<Subscription> subs;
  std::size_t next_sub = 0;  // round robin over the subscriptions
  std::string rx;            // a client message's fragments
  std::vector<unsigned char> tx;
};

void put_le(unsigned char* p, std::uint64_t v, int bytes) {
  for (int i = 0; i < bytes; ++i) p[i] = static_cast<unsigned char>(v >> (8 * i));
}

std::string status_json(int level, const std::string& message) {
  return json{{"op", "status"}, {"level", level}, {"message", message}}.dump();
}

bool is_token_char(char c) {
  return (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '.' ||
         c == '_' || c == '~' || c == '-';
}

// libwebsockets' own error lines on stderr, as wallar's (its lines end in a newline).
void emit_lws_log(int /*level*/, const char* line) {
  std::fprintf(stderr, "wallar: live server (libwebsockets): %s", line);
}

}  // namespace

// Guarded by Impl::mutex but for `info`.
struct ChannelState {
  FoxgloveChannel info;
  // The newest `info.history` messages, oldest first; their sequence numbers are consecutive.
  std::deque<std::shared_ptr<const Message>> kept;
  // Per kept message, the subscriptions sent it (the rest lose it when it leaves `kept`).
  std::deque<int> taken;
  std::uint64_t seq = 0;
  int subscribers = 0;

  [[nodiscard]] std::uint64_t newest_seq() const { return kept.empty() ? 0 : kept.back()->seq; }
  // The index in `kept` of the first message after `sent_seq`, or kept.size().
  [[nodiscard]] std::size_t next_index(std::uint64_t sent_seq) const {
    if (kept.empty() || sent_seq >= kept.back()->seq) return kept.size();
    const std::uint64_t first = kept.front()->seq;
    return sent_seq < first ? 0 : static_cast<std::size_t>(sent_seq + 1 - first);
  }
};

struct FoxgloveServer::Impl {
  FoxgloveServerOptions options;
  std::vector<ChannelState> channels;  // id = index + 1; the list is fixed at start()
  std::vector<HttpFile> files;         // fixed at start()
  mutable std::mutex mutex;            // channels (but their info), stats
  FoxgloveServerStats stats;
  lws_protocols protocols[2] = {};
  lws_context* context = nullptr;
  std::thread thread;
  std::atomic<bool> stopping{false};
  std::atomic<bool> started{false};
  // Service thread only.
  std::vector<Client*> clients;
  std::string server_info;
  std::string advertise;

  static int callback(lws* wsi, lws_callback_reasons reason, void* user, void* in, size_t len);
  int on_filter(lws* wsi);
  void on_established(lws* wsi, Client** slot);
  void on_closed(Client* c);
  int on_receive(Client* c, const void* in, std::size_t len);
  void handle_text(Client* c, const std::string& text);
  int on_writeable(Client* c);
  bool token_ok(lws* wsi) const;
  int on_http(lws* wsi, Session* s, const char* path);
  int on_http_writeable(lws* wsi, Session* s);
  bool pending(const Client* c) const;
  void run();
};

int FoxgloveServer::Impl::callback(lws* wsi, lws_callback_reasons reason, void* user, void* in,
                                   size_t len) {
  auto* impl = static_cast<Impl*>(lws_context_user(lws_get_context(wsi)));
  auto* session = static_cast<Session*>(user);
  Client** slot = session != nullptr ? &session->client : nullptr;
  switch (reason) {
    case LWS_CALLBACK_HTTP:
      return impl->on_http(wsi, session, static_cast<const char*>(in));
    case LWS_CALLBACK_HTTP_WRITEABLE:
      return session != nullptr ? impl->on_http_writeable(wsi, session) : -1;
    case LWS_CALLBACK_FILTER_PROTOCOL_CONNECTION:
      return impl->on_filter(wsi);
    case LWS_CALLBACK_ESTABLISHED:
      impl->on_established(wsi, slot);
      return 0;
    case LWS_CALLBACK_CLOSED:
      if (slot != nullptr && *slot != nullptr) {
        impl->on_closed(*slot);
        *slot = nullptr;
      }
      return 0;
    case LWS_CALLBACK_RECEIVE:
      return (slot != nullptr && *slot != nullptr) ? impl->on_receive(*slot, in, len) : -1;
    case LWS_CALLBACK_SERVER_WRITEABLE:
      return (slot != nullptr && *slot != nullptr) ? impl->on_writeable(*slot) : 0;
    case LWS_CALLBACK_EVENT_WAIT_CANCELLED:
      // publish() or stop() woke the loop: every client with something to send asks for a
      // writable socket.
      for (Client* c : impl->clients) {
        if (impl->pending(c)) lws_callback_on_writable(c->wsi);
      }
      return 0;
    default:
      return lws_callback_http_dummy(wsi, reason, user, in, len);
  }
}

bool FoxgloveServer::Impl::token_ok(lws* wsi) const {
  if (options.token.empty()) return true;
  char buf[256];
  const char* got = lws_get_urlarg_by_name(wsi, "token=", buf, sizeof buf);
  return got != nullptr && options.token == got;
}

int FoxgloveServer::Impl::on_filter(lws* wsi) {
  if (token_ok(wsi)) return 0;
  std::lock_guard lock(mutex);
  ++stats.clients_refused;
  return -1;  // refuses the upgrade: the connection closes
}

int FoxgloveServer::Impl::on_http(lws* wsi, Session* s, const char* path) {
  const std::string_view want = path != nullptr ? path : "";
  const HttpFile* file = nullptr;
  for (const HttpFile& f : files) {
    if (f.path == want) file = &f;
  }
  const bool allowed = token_ok(wsi);
  {
    std::lock_guard lock(mutex);
    ++stats.http_requests;
    if (!allowed) ++stats.clients_refused;
  }
  if (!allowed || file == nullptr || s == nullptr) {
    lws_return_http_status(wsi, allowed ? HTTP_STATUS_NOT_FOUND : HTTP_STATUS_FORBIDDEN, nullptr);
    return lws_http_transaction_completed(wsi) != 0 ? -1 : 0;
  }
  unsigned char headers[LWS_PRE + 512];
  unsigned char* start = headers + LWS_PRE;
  unsigned char* p = start;
  unsigned char* end = headers + sizeof headers - 1;
  if (lws_add_http_common_headers(wsi, HTTP_STATUS_OK, file->content_type.c_str(),
                                  file->body.size(), &p, end) != 0 ||
      lws_add_http_header_by_token(wsi, WSI_TOKEN_HTTP_CACHE_CONTROL,
                                   reinterpret_cast<const unsigned char*>("no-store"), 8, &p,
                                   end) != 0 ||
      lws_finalize_write_http_header(wsi, start, &p, end) != 0) {
    return -1;
  }
  s->file = file;
  s->sent = 0;
  lws_callback_on_writable(wsi);
  return 0;
}

int FoxgloveServer::Impl::on_http_writeable(lws* wsi, Session* s) {
  if (s->file == nullptr) return -1;
  constexpr std::size_t kPiece = 16 * 1024;
  unsigned char buf[LWS_PRE + kPiece];
  const std::string_view body = s->file->body;
  const std::size_t n = std::min(kPiece, body.size() - s->sent);
  std::memcpy(buf + LWS_PRE, body.data() + s->sent, n);
  s->sent += n;
  const bool last = s->sent == body.size();
  if (lws_write(wsi, buf + LWS_PRE, n, last ? LWS_WRITE_HTTP_FINAL : LWS_WRITE_HTTP) !=
      static_cast<int>(n)) {
    return -1;
  }
  if (!last) {
    lws_callback_on_writable(wsi);
    return 0;
  }
  s->file = nullptr;
  return lws_http_transaction_completed(wsi) != 0 ? -1 : 0;
}

void FoxgloveServer::Impl::on_established(lws* wsi, Client** slot) {
  auto* c = new Client;  // deleted in on_closed
  c->wsi = wsi;
  c->text_out.push_back(server_info);
  c->text_out.push_back(advertise);
  *slot = c;
  clients.push_back(c);
  {
    std::lock_guard lock(mutex);
    ++stats.clients_connected;
    ++stats.clients_total;
  }
  lws_callback_on_writable(wsi);
}

void FoxgloveServer::Impl::on_closed(Client* c) {
  {
    std::lock_guard lock(mutex);
    for (const Subscription& s : c->subs) --channels[s.channel - 1].subscribers;
    stats.subscriptions -= c->subs.size();
    --stats.clients_connected;
  }
  clients.erase(std::remove(clients.begin(), clients.end(), c), clients.end());
  delete c;
}

int FoxgloveServer::Impl::on_receive(Client* c, const void* in, std::size_t len) {
  if (c->rx.size() + len > options.max_client_message_bytes) {
    std::lock_guard lock(mutex);
    ++stats.client_errors;
    return -1;  // closes this client only
  }
  c->rx.append(static_cast<const char*>(in), len);
  if (!lws_is_final_fragment(c->wsi) || lws_remaining_packet_payload(c->wsi) > 0) return 0;
  std::string text;
  text.swap(c->rx);
  if (lws_frame_is_binary(c->wsi)) {
    {
      std::lock_guard lock(mutex);
      ++stats.client_errors;
    }
    c->text_out.push_back(status_json(kStatusError,
                                      "binary client messages are not supported "
                                      "(this server advertises no capabilities)"));
  } else {
    handle_text(c, text);
  }
  if (pending(c)) lws_callback_on_writable(c->wsi);
  return 0;
}

void FoxgloveServer::Impl::handle_text(Client* c, const std::string& text) {
  auto error = [&](const std::string& what) {
    {
      std::lock_guard lock(mutex);
      ++stats.client_errors;
    }
    c->text_out.push_back(status_json(kStatusError, what));
  };
  const json j = json::parse(text, nullptr, false);
  if (j.is_discarded() || !j.is_object() || !j.contains("op") || !j["op"].is_string()) {
    error("not a JSON object with an 'op'");
    return;
  }
  const std::string op = j["op"].get<std::string>();
  if (op == "subscribe") {
    if (!j.contains("subscriptions") || !j["subscriptions"].is_array()) {
      error("subscribe: no 'subscriptions' array");
      return;
    }
    for (const json& s : j["subscriptions"]) {
      if (!s.is_object() || !s.contains("id") || !s.contains("channelId") ||
          !s["id"].is_number_unsigned() || !s["channelId"].is_number_unsigned()) {
        error("subscribe: each subscription needs unsigned 'id' and 'channelId'");
        continue;
      }
      const auto id = s["id"].get<std::uint64_t>();
      const auto channel = s["channelId"].get<std::uint64_t>();
      if (id > UINT32_MAX || channel == 0 || channel > channels.size()) {
        c->text_out.push_back(
            status_json(kStatusWarning, "subscribe: no channel " + std::to_string(channel)));
        continue;
      }
      const bool taken = std::any_of(c->subs.begin(), c->subs.end(),
                                     [&](const Subscription& x) { return x.id == id; });
      if (taken) {
        c->text_out.push_back(status_json(
            kStatusWarning, "subscribe: subscription id " + std::to_string(id) + " in use"));
        continue;
      }
      Subscription sub;
      sub.id = static_cast<std::uint32_t>(id);
      sub.channel = static_cast<std::uint32_t>(channel);
      std::lock_guard lock(mutex);
      ChannelState& ch = channels[channel - 1];
      // What the channel keeps now is sent first (a newest-wins channel: its newest message;
      // a log: its recent lines); nothing older counts as dropped.
      sub.sent_seq = ch.kept.empty() ? ch.seq : ch.kept.front()->seq - 1;
      ++ch.subscribers;
      ++stats.subscriptions;
      c->subs.push_back(sub);
    }
  } else if (op == "unsubscribe") {
    if (!j.contains("subscriptionIds") || !j["subscriptionIds"].is_array()) {
      error("unsubscribe: no 'subscriptionIds' array");
      return;
    }
    for (const json& id : j["subscriptionIds"]) {
      if (!id.is_number_unsigned()) continue;
      const auto it = std::find_if(c->subs.begin(), c->subs.end(), [&](const Subscription& x) {
        return x.id == id.get<std::uint64_t>();
      });
      if (it == c->subs.end()) continue;
      {
        std::lock_guard lock(mutex);
        --channels[it->channel - 1].subscribers;
        --stats.subscriptions;
      }
      c->subs.erase(it);
    }
  } else {
    error("unsupported op '" + op + "' (this server advertises no capabilities)");
  }
}

bool FoxgloveServer::Impl::pending(const Client* c) const {
  if (!c->text_out.empty()) return true;
  std::lock_guard lock(mutex);
  for (const Subscription& s : c->subs) {
    if (channels[s.channel - 1].newest_seq() > s.sent_seq) return true;
  }
  return false;
}

int FoxgloveServer::Impl::on_writeable(Client* c) {
  if (!c->text_out.empty()) {
    const std::string& t = c->text_out.front();
    c->tx.resize(LWS_PRE + t.size());
    std::memcpy(c->tx.data() + LWS_PRE, t.data(), t.size());
    c->text_out.pop_front();
    if (lws_write(c->wsi, c->tx.data() + LWS_PRE, c->tx.size() - LWS_PRE, LWS_WRITE_TEXT) < 0)
      return -1;
  } else {
    // The next subscription (round robin) whose channel keeps a message this client has not
    // had: the oldest such (a newest-wins channel keeps one).
    std::shared_ptr<const Message> m;
    Subscription* sub = nullptr;
    {
      std::lock_guard lock(mutex);
      const std::size_t n = c->subs.size();
      for (std::size_t k = 0; k < n && !m; ++k) {
        Subscription& s = c->subs[(c->next_sub + k) % n];
        ChannelState& ch = channels[s.channel - 1];
        const std::size_t i = ch.next_index(s.sent_seq);
        if (i < ch.kept.size()) {
          m = ch.kept[i];
          ++ch.taken[i];
          sub = &s;
          c->next_sub = (c->next_sub + k + 1) % n;
        }
      }
      if (m) {
        sub->sent_seq = m->seq;
        ++stats.sent;
        stats.bytes_sent += m->payload.size();
      }
    }
    if (m) {
      c->tx.resize(LWS_PRE + kDataHeader + m->payload.size());
      unsigned char* p = c->tx.data() + LWS_PRE;
      p[0] = kMessageData;
      put_le(p + 1, sub->id, 4);
      put_le(p + 5, static_cast<std::uint64_t>(m->t_ns), 8);
      std::memcpy(p + kDataHeader, m->payload.data(), m->payload.size());
      if (lws_write(c->wsi, p, kDataHeader + m->payload.size(), LWS_WRITE_BINARY) < 0) return -1;
    }
  }
  if (pending(c)) lws_callback_on_writable(c->wsi);
  return 0;
}

void FoxgloveServer::Impl::run() {
  pthread_setname_np(pthread_self(), "foxglove");
  // stop() sets `stopping` and cancels the wait; lws_context_destroy (on the owner's thread,
  // after the join) then closes the connections: no closing handshake, which a stalled client
  // would never let finish.
  while (!stopping.load()) lws_service(context, 0);
}

// ---------------------------------------------------------------------------------------------

FoxgloveServer::FoxgloveServer(FoxgloveServerOptions options) : impl_(std::make_unique<Impl>()) {
  in_addr a{};
  if (inet_pton(AF_INET, options.address.c_str(), &a) != 1) {
    throw_input_error("live server", 0,
                      "address '" + options.address + "' is not an IPv4 address (as 127.0.0.1)");
  }
  if (options.port < 0 || options.port > 65535) {
    throw_input_error("live server", 0, "port " + std::to_string(options.port) + " is not 0-65535");
  }
  if (!std::all_of(options.token.begin(), options.token.end(), is_token_char)) {
    throw_input_error("live server", 0, "token: only A-Z a-z 0-9 . _ ~ - (it goes in a URL)");
  }
  impl_->options = std::move(options);
}

FoxgloveServer::~FoxgloveServer() { stop(); }

std::uint32_t FoxgloveServer::add_channel(FoxgloveChannel channel) {
  if (impl_->started.load()) throw_input_error("live server", 0, "add_channel after start()");
  if (channel.history == 0) throw_input_error("live server", 0, channel.topic + ": history 0");
  ChannelState s;
  s.info = std::move(channel);
  impl_->channels.push_back(std::move(s));
  return static_cast<std::uint32_t>(impl_->channels.size());
}

void FoxgloveServer::add_http_file(HttpFile file) {
  if (impl_->started.load()) throw_input_error("live server", 0, "add_http_file after start()");
  impl_->files.push_back(std::move(file));
}

void FoxgloveServer::start() {
  Impl& m = *impl_;
  if (m.started.load()) return;
  json info = {{"op", "serverInfo"},
               {"name", m.options.name},
               {"capabilities", json::array()},
               {"supportedEncodings", json::array()},
               {"metadata", json::object()},
               {"sessionId", std::to_string(monotonic_now_ns())}};
  m.server_info = info.dump();
  json channels = json::array();
  for (std::size_t i = 0; i < m.channels.size(); ++i) {
    const FoxgloveChannel& c = m.channels[i].info;
    channels.push_back({{"id", i + 1},
                        {"topic", c.topic},
                        {"encoding", c.encoding},
                        {"schemaName", c.schema_name},
                        {"schema", c.schema},
                        {"schemaEncoding", c.schema_encoding}});
  }
  m.advertise = json{{"op", "advertise"}, {"channels", channels}}.dump();

  // Quiet while the socket is bound (a failure is this function's one-line InputError), then
  // libwebsockets' errors only.
  lws_set_log_level(0, emit_lws_log);
  m.protocols[0] = {};
  m.protocols[0].name = "foxglove.websocket.v1";
  m.protocols[0].callback = &Impl::callback;
  m.protocols[0].per_session_data_size = sizeof(Session);
  m.protocols[0].rx_buffer_size = 0;
  m.protocols[1] = {};  // the list's end

  lws_context_creation_info ci{};
  ci.options = LWS_SERVER_OPTION_EXPLICIT_VHOSTS | LWS_SERVER_OPTION_DISABLE_IPV6;
  ci.user = &m;
  ci.gid = -1;
  ci.uid = -1;
  ci.port = CONTEXT_PORT_NO_LISTEN;
  m.context = lws_create_context(&ci);
  const std::string where = m.options.address + ":" + std::to_string(m.options.port);
  if (m.context == nullptr)
    throw_input_error("live server " + where, 0, "cannot start libwebsockets");
  lws_context_creation_info vi{};
  vi.options = LWS_SERVER_OPTION_DISABLE_IPV6;
  vi.port = m.options.port;
  vi.iface = m.options.address.c_str();
  vi.protocols = m.protocols;
  vi.vhost_name = "wallar";
  lws_vhost* vhost = lws_create_vhost(m.context, &vi);
  if (vhost == nullptr) {
    lws_context_destroy(m.context);
    m.context = nullptr;
    throw_input_error("live server " + where, 0,
                      "cannot listen (address not on this machine, or the port in use)");
  }
  bound_port_.store(lws_get_vhost_listen_port(vhost));
  lws_set_log_level(LLL_ERR, emit_lws_log);
  m.stopping.store(false);
  m.started.store(true);
  m.thread = std::thread([&m] { m.run(); });
}

void FoxgloveServer::stop() {
  Impl& m = *impl_;
  if (!m.started.load()) return;
  m.stopping.store(true);
  lws_cancel_service(m.context);
  m.thread.join();
  lws_context_destroy(m.context);  // closes what is left; CLOSED deletes those clients
  m.context = nullptr;
  m.started.store(false);
  bound_port_.store(0);
}

void FoxgloveServer::publish(std::uint32_t channel, TimeNs t_ns, std::string_view payload) {
  Impl& m = *impl_;
  if (channel == 0 || channel > m.channels.size()) return;
  auto msg = std::make_shared<Message>();
  msg->t_ns = t_ns;
  msg->payload.assign(payload.data(), payload.size());
  {
    std::lock_guard lock(m.mutex);
    ChannelState& ch = m.channels[channel - 1];
    // Each subscription that had not been sent the message this one pushes out has lost it (a
    // stalled client's too, which is never sent anything again).
    if (ch.kept.size() >= ch.info.history) {
      m.stats.dropped += static_cast<std::uint64_t>(std::max(0, ch.subscribers - ch.taken.front()));
      ch.kept.pop_front();
      ch.taken.pop_front();
    }
    msg->seq = ++ch.seq;
    ch.kept.push_back(std::move(msg));
    ch.taken.push_back(0);
    ++m.stats.published;
  }
  if (m.started.load()) lws_cancel_service(m.context);
}

bool FoxgloveServer::has_subscribers(std::uint32_t channel) const {
  const Impl& m = *impl_;
  if (channel == 0 || channel > m.channels.size()) return false;
  std::lock_guard lock(m.mutex);
  return m.channels[channel - 1].subscribers > 0;
}

FoxgloveServerStats FoxgloveServer::stats() const {
  std::lock_guard lock(impl_->mutex);
  return impl_->stats;
}

}  // namespace wallar::net

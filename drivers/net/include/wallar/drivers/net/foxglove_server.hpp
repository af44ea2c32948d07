// SPDX-License-Identifier: Apache-2.0
/// @file foxglove_server.hpp
/// @brief A live server of Foxglove's WebSocket protocol (`foxglove.websocket.v1`) on
/// libwebsockets: Foxglove (or any client of the protocol) connects, receives serverInfo and the
/// advertised channels, subscribes, and gets each channel's newest message.
///
/// The protocol (github.com/foxglove/ws-protocol, docs/spec.md): text frames of JSON, server to
/// client `serverInfo`, `advertise`, `status`; client to server `subscribe`
/// ({subscriptions: [{id, channelId}]}) and `unsubscribe` ({subscriptionIds}); message data as a
/// binary frame: opcode 1, the subscription id (u32 little-endian), the message's time (u64
/// little-endian, ns) and the payload in the channel's encoding.
///
/// Newest wins: each channel holds its newest message only (or its newest few: a log's
/// `history`). A client is sent, per subscription, the oldest kept message it has not had, one
/// WebSocket frame per writable socket; a client that reads slower than the channel is published
/// loses the messages in between, counted as dropped (never queued beyond what the channel
/// keeps: a stalled client costs nothing but the messages it holds a reference to).
///
/// Security: binds to 127.0.0.1 unless an address is given; with a token, a connection must
/// carry it as the URL's `token` argument (ws://HOST:PORT/?token=...) or is refused, and so
/// must an HTTP request for one of the files served beside the protocol (add_http_file: GET
/// only, each file sent in 16 KiB pieces as the socket takes them).
///
/// Threading: the owner constructs it, adds channels, start()s and stop()s it (or destroys it)
/// from one thread. publish() may be called from any thread, also concurrently, but not while
/// start() or stop() runs (the owner stops its publishers first); it copies the
/// payload and wakes the service thread, and never waits on the network (only on a mutex that
/// the service thread holds to swap a pointer). stats() from any thread. The service thread is
/// the server's own (SCHED_OTHER, named "foxglove"); it alone touches sockets. Not for a
/// fixed-rate thread: publish() allocates. The firmware's live publisher thread calls it.
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

#include "wallar/core/time.hpp"

namespace wallar::net {

struct FoxgloveServerOptions {
  std::string address = "127.0.0.1";  //!< the IPv4 address to listen on
  int port = 8765;                    //!< 0: any free port (see FoxgloveServer::port())
  std::string token;                  //!< required as ?token= when not empty
  std::string name = "wallar";        //!< serverInfo's name
  /// The most a client's text message (subscribe, unsubscribe) may hold; a larger one closes
  /// that client.
  std::size_t max_client_message_bytes = 64 * 1024;
};

/// One advertised channel: JSON messages under a JSON Schema (Foxglove's, where it has one).
struct FoxgloveChannel {
  std::string topic;        //!< "/pose"
  std::string schema_name;  //!< "foxglove.PoseInFrame"
  std::string schema;       //!< the JSON Schema's text
  std::string encoding = "json";
  std::string schema_encoding = "jsonschema";
  /// Messages kept for each client: 1 (newest wins: a pose, a map, an image), or more for a
  /// stream where every message counts (log lines): a client that falls further behind loses
  /// the oldest, counted; a new subscriber is sent those kept first.
  std::size_t history = 1;
};

/// A file served over plain HTTP on the same port (`GET /path`; with a token, `?token=` too):
/// a page of our own beside the protocol. `body` is not copied: it must outlive the server
/// (the firmware's viewer files are built into the binary).
struct HttpFile {
  std::string path;          //!< "/", "/viewer.js"
  std::string content_type;  //!< "text/html; charset=utf-8"
  std::string_view body;
};

struct FoxgloveServerStats {
  std::uint64_t clients_connected = 0;  //!< now
  std::uint64_t clients_total = 0;      //!< since start
  std::uint64_t clients_refused = 0;    //!< a missing or wrong token
  std::uint64_t client_errors = 0;      //!< malformed or oversized client messages
  std::uint64_t http_requests = 0;      //!< plain HTTP requests answered (files or 404)
  std::uint64_t subscriptions = 0;      //!< now, over every client
  std::uint64_t published = 0;          //!< publish() calls
  std::uint64_t sent = 0;               //!< message frames written to clients
  std::uint64_t dropped = 0;            //!< newer message replaced one a client had not had
  std::uint64_t bytes_sent = 0;         //!< message payload bytes written
};

class FoxgloveServer {
 public:
  /// Checks the options (an address that is not IPv4 dotted-quad, a port outside 0-65535 or a
  /// token with characters other than [A-Za-z0-9._~-] throw InputError naming the option).
  explicit FoxgloveServer(FoxgloveServerOptions options);
  ~FoxgloveServer();  // stop()s
  FoxgloveServer(const FoxgloveServer&) = delete;
  FoxgloveServer& operator=(const FoxgloveServer&) = delete;

  /// Before start(): a channel and its id (ids from 1, as Foxglove's servers give them).
  std::uint32_t add_channel(FoxgloveChannel channel);
  /// Before start(): a file to serve over HTTP (other paths get 404).
  void add_http_file(HttpFile file);

  /// Listens and starts the service thread. Throws InputError naming ADDRESS:PORT when the
  /// socket cannot be bound (in use, no such address).
  void start();
  /// Closes every connection and joins the service thread. Idempotent.
  void stop();

  /// The port listened on (the kernel's choice when the options said 0); 0 before start().
  [[nodiscard]] int port() const { return bound_port_.load(); }

  /// The newest message on `channel` (an id from add_channel), at `t_ns`. Unknown ids are
  /// ignored (counted nowhere: a programming error the tests catch).
  void publish(std::uint32_t channel, TimeNs t_ns, std::string_view payload);

  /// True when some client subscribes to `channel`: the publisher may skip encoding otherwise.
  [[nodiscard]] bool has_subscribers(std::uint32_t channel) const;

  [[nodiscard]] FoxgloveServerStats stats() const;

  struct Impl;  // the libwebsockets side (public for its C callback; defined in the .cpp)

 private:
  std::unique_ptr<Impl> impl_;
  std::atomic<int> bound_port_{0};
};

}  // namespace wallar::net

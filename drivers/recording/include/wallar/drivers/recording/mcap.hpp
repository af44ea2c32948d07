// SPDX-License-Identifier: Apache-2.0
/// @file mcap.hpp
/// @brief The MCAP container format (https://mcap.dev/spec, major version 0), written and read
/// from its specification: records, chunks (zstd, lz4 or none), message indexes, the summary
/// (schemas, channels, statistics, chunk and metadata indexes, summary offsets) and CRC-32s.
///
/// The writer puts schemas, channels and metadata in the data section before any chunk that
/// uses them, and each chunk is written whole with one write(2) when it closes (at a size or
/// after a span of log time), so a file cut off at any byte (power loss) still reads up to its
/// last complete chunk. The reader scans the data section record by record: it needs no summary,
/// stops at the first incomplete record and says how many bytes it could not use.
///
/// Threading: a McapWriter is used by one thread. A McapFile is immutable after open() except
/// for its one-chunk cache, which a mutex guards: read_message() may be called from any thread.
#pragma once

#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <mutex>
#include <span>
#include <string>
#include <vector>

namespace wallar::recording::mcap {

enum class Compression : std::uint8_t { kNone, kZstd, kLz4 };

/// "", "zstd" or "lz4" (the Chunk record's compression string).
const char* compression_name(Compression c);
/// Parses "none", "zstd" or "lz4"; throws InputError naming `what` otherwise.
Compression parse_compression(const std::string& text, const std::string& what);

struct WriterOptions {
  Compression compression = Compression::kZstd;
  /// A chunk closes when its uncompressed records reach this size...
  std::uint64_t chunk_bytes = 4u << 20;
  /// ... or when its messages span this much log time: the most a crash can lose.
  std::int64_t chunk_span_ns = 1'000'000'000;
  std::string profile;  //!< the Header's profile ("" or a custom "x-..." one)
  std::string library = "wallar";
};

using StringMap = std::map<std::string, std::string>;

/// Writes one MCAP file. Throws InputError naming the file on any I/O failure.
class Writer {
 public:
  Writer(const std::filesystem::path& path, const WriterOptions& options = {});
  ~Writer();  // closes (errors reported on stderr)
  Writer(const Writer&) = delete;
  Writer& operator=(const Writer&) = delete;

  /// Schema `name` in `encoding` ("jsonschema", "protobuf", ...); ids start at 1.
  std::uint16_t add_schema(const std::string& name, const std::string& encoding,
                           std::span<const std::uint8_t> data);
  /// A channel on `topic` (schema_id 0: no schema); ids start at 0.
  std::uint16_t add_channel(std::uint16_t schema_id, const std::string& topic,
                            const std::string& message_encoding, const StringMap& metadata = {});
  /// A Metadata record in the data section (and its index in the summary).
  void add_metadata(const std::string& name, const StringMap& metadata);
  /// One message. log_time_ns orders the file's statistics; messages may come in any order.
  void write_message(std::uint16_t channel_id, std::uint64_t log_time_ns,
                     std::uint64_t publish_time_ns, std::span<const std::uint8_t> data);
  /// Writes the open chunk, the summary and the footer; fsyncs. Further writes are errors.
  void close();

  [[nodiscard]] std::uint64_t bytes_written() const { return offset_; }
  [[nodiscard]] std::uint64_t message_count() const { return message_count_; }

 private:
  struct Chunk;
  struct ChunkIndex;
  void write_bytes(const std::vector<std::uint8_t>& bytes);
  void flush_chunk();
  void check_open() const;
  /// Marks the writer closed and closes the file descriptor (every way out of close()).
  void release() noexcept;

  std::filesystem::path path_;
  WriterOptions options_;
  int fd_ = -1;
  std::uint64_t offset_ = 0;
  std::uint32_t data_crc_ = 0;  // running CRC-32 of the data section (from the leading magic)
  bool closed_ = false;
  bool failed_ = false;  // a write failed: nothing more is written (the file may end torn)
  std::vector<std::vector<std::uint8_t>> schemas_;   // serialized records, for the summary
  std::vector<std::vector<std::uint8_t>> channels_;  // the same
  std::vector<std::vector<std::uint8_t>> metadata_index_;
  std::vector<std::vector<std::uint8_t>> chunk_index_;
  std::map<std::uint16_t, std::uint64_t> channel_counts_;
  std::map<std::uint16_t, std::uint32_t> sequence_;
  std::uint64_t message_count_ = 0;
  std::uint64_t first_time_ns_ = UINT64_MAX;
  std::uint64_t last_time_ns_ = 0;
  std::uint32_t chunk_count_ = 0;
  std::uint32_t metadata_count_ = 0;
  std::unique_ptr<Chunk> chunk_;
};

struct Schema {
  std::uint16_t id = 0;
  std::string name;
  std::string encoding;
  std::vector<std::uint8_t> data;
};

struct Channel {
  std::uint16_t id = 0;
  std::uint16_t schema_id = 0;
  std::string topic;
  std::string message_encoding;
  StringMap metadata;
};

/// Where one message lies: in chunk `chunk` (an index into the file's chunk list) at `offset`
/// of its uncompressed records, or (chunk < 0) at `offset` of the file.
struct MessageRef {
  std::uint16_t channel_id = 0;
  std::uint32_t sequence = 0;
  std::uint64_t log_time_ns = 0;
  std::uint64_t publish_time_ns = 0;
  std::int64_t chunk = -1;
  std::uint64_t offset = 0;  //!< of the message's data
  std::uint64_t size = 0;    //!< of the message's data
};

/// What open() found at the end of the file.
struct ReadReport {
  bool complete = false;         //!< every record read, the footer, trailing magic and CRCs valid
  bool summary_checked = false;  //!< the summary's CRC and statistics matched the data
  std::uint64_t file_bytes = 0;
  std::uint64_t bytes_used = 0;  //!< up to the end of the last complete record
  std::uint64_t chunks = 0;
  std::string stop_reason;  //!< why reading stopped early ("" when complete)
};

/// An MCAP file opened for reading: its schemas, channels, metadata and an index of every
/// message, in file order.
class File {
 public:
  /// Reads the data section. A file cut short reads up to its last complete record, one with
  /// a damaged chunk (bad CRC, does not decompress: what power loss leaves when a chunk's
  /// length reached the disk and its data did not) up to that chunk; the report says where
  /// and why. A file that is not MCAP, or whose records contradict themselves (a field past
  /// its record, a message on an unknown channel), throws InputError "PATH: byte OFFSET: what".
  static std::unique_ptr<File> open(const std::filesystem::path& path);
  ~File();

  [[nodiscard]] const std::filesystem::path& path() const { return path_; }
  [[nodiscard]] const std::map<std::uint16_t, Schema>& schemas() const { return schemas_; }
  [[nodiscard]] const std::map<std::uint16_t, Channel>& channels() const { return channels_; }
  [[nodiscard]] const std::vector<std::pair<std::string, StringMap>>& metadata() const {
    return metadata_;
  }
  [[nodiscard]] const std::vector<MessageRef>& messages() const { return messages_; }
  [[nodiscard]] const ReadReport& report() const { return report_; }

  /// The data of one message (decompresses its chunk, cached for the next call).
  std::vector<std::uint8_t> read_message(const MessageRef& ref) const;

 private:
  struct ChunkLocation {
    std::uint64_t records_offset = 0;  // in the file
    std::uint64_t compressed_size = 0;
    std::uint64_t uncompressed_size = 0;
    std::uint32_t crc = 0;
    Compression compression = Compression::kNone;
  };
  File() = default;
  std::vector<std::uint8_t> load_chunk(std::size_t index) const;
  std::vector<std::uint8_t> unpack_chunk(const ChunkLocation& loc,
                                         const std::vector<std::uint8_t>& packed) const;
  /// Decompresses and CRC-checks; "" or what is wrong.
  static std::string try_unpack(const ChunkLocation& loc, const std::vector<std::uint8_t>& packed,
                                std::vector<std::uint8_t>& out);

  std::filesystem::path path_;
  int fd_ = -1;
  std::map<std::uint16_t, Schema> schemas_;
  std::map<std::uint16_t, Channel> channels_;
  std::vector<std::pair<std::string, StringMap>> metadata_;
  std::vector<MessageRef> messages_;
  std::vector<ChunkLocation> chunks_;
  ReadReport report_;
  mutable std::mutex cache_mutex_;
  mutable std::int64_t cached_chunk_ = -1;
  mutable std::vector<std::uint8_t> cached_;
};

/// True when the file at `path` starts with MCAP's magic bytes.
bool is_mcap_file(const std::filesystem::path& path);

}  // namespace wallar::recording::mcap

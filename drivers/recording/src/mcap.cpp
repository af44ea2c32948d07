// SPDX-License-Identifier: Apache-2.0
/// @file mcap.cpp
/// @brief MCAP writer and reader, from the format's specification (see mcap.hpp).
#include "wallar/drivers/recording/mcap.hpp"

#include <fcntl.h>
#include <lz4frame.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zlib.h>
#include <zstd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>

#include "wallar/core/error.hpp"

namespace wallar::recording::mcap {
namespace {

constexpr std::uint8_t kMagic[8] = {0x89, 'M', 'C', 'A', 'P', 0x30, '\r', '\n'};
constexpr std::size_t kRecordHeader = 9;  // opcode + uint64 length
constexpr std::size_t kFooterRecord = kRecordHeader + 20;
// The largest chunk read (uncompressed): writers use a few MiB; more is damage, not data.
constexpr std::uint64_t kMaxChunkBytes = 256ull << 20;

enum Op : std::uint8_t {
  kHeader = 0x01,
  kFooter = 0x02,
  kSchema = 0x03,
  kChannel = 0x04,
  kMessage = 0x05,
  kChunk = 0x06,
  kMessageIndex = 0x07,
  kChunkIndex = 0x08,
  kAttachment = 0x09,
  kStatistics = 0x0B,
  kMetadata = 0x0C,
  kMetadataIndex = 0x0D,
  kSummaryOffset = 0x0E,
  kDataEnd = 0x0F,
};

std::uint32_t crc32_update(std::uint32_t crc, const std::uint8_t* data, std::size_t n) {
  // zlib's crc32 is the CRC-32 (IEEE 802.3) that MCAP specifies; it takes uInt lengths.
  while (n > 0) {
    const auto step = static_cast<uInt>(std::min<std::size_t>(n, 1u << 30));
    crc = static_cast<std::uint32_t>(::crc32(crc, data, step));
    data += step;
    n -= step;
  }
  return crc;
}

// Little-endian serialization of MCAP's field types into a growing buffer.
struct Out {
  std::vector<std::uint8_t> b;
  void u8(std::uint8_t v) { b.push_back(v); }
  void u16(std::uint16_t v) { le(v, 2); }
  void u32(std::uint32_t v) { le(v, 4); }
  void u64(std::uint64_t v) { le(v, 8); }
  void le(std::uint64_t v, int n) {
    for (int i = 0; i < n; ++i) b.push_back(static_cast<std::uint8_t>(v >> (8 * i)));
  }
  void raw(const void* p, std::size_t n) {
    const auto* c = static_cast<const std::uint8_t*>(p);
    b.insert(b.end(), c, c + n);
  }
  void str(const std::string& s) {
    u32(static_cast<std::uint32_t>(s.size()));
    raw(s.data(), s.size());
  }
  void map(const StringMap& m) {
    Out body;
    for (const auto& [k, v] : m) {
      body.str(k);
      body.str(v);
    }
    u32(static_cast<std::uint32_t>(body.b.size()));
    raw(body.b.data(), body.b.size());
  }
  // Appends a whole record: opcode, content length, content.
  void record(std::uint8_t op, const Out& content) {
    u8(op);
    u64(content.b.size());
    raw(content.b.data(), content.b.size());
  }
};

// Bounds-checked reading of one record's content; errors name the file offset of the field.
struct In {
  const std::uint8_t* p = nullptr;
  std::size_t n = 0;
  std::size_t pos = 0;
  std::uint64_t base = 0;  // file offset of p[0] (for messages; chunks: the chunk's)
  const std::string* path = nullptr;
  const char* what = "";

  [[noreturn]] void fail(const std::string& msg) const {
    throw_input_error(*path, 0, "byte " + std::to_string(base + pos) + ": " + what + ": " + msg);
  }
  void need(std::size_t k) const {
    if (k > n - pos) fail("field runs past the end of the record");
  }
  std::uint64_t le(int k) {
    need(static_cast<std::size_t>(k));
    std::uint64_t v = 0;
    for (int i = 0; i < k; ++i) v |= static_cast<std::uint64_t>(p[pos + i]) << (8 * i);
    pos += static_cast<std::size_t>(k);
    return v;
  }
  std::uint8_t u8() { return static_cast<std::uint8_t>(le(1)); }
  std::uint16_t u16() { return static_cast<std::uint16_t>(le(2)); }
  std::uint32_t u32() { return static_cast<std::uint32_t>(le(4)); }
  std::uint64_t u64() { return le(8); }
  std::string str() {
    const std::uint32_t len = u32();
    need(len);
    std::string s(reinterpret_cast<const char*>(p + pos), len);
    pos += len;
    return s;
  }
  std::vector<std::uint8_t> bytes(std::uint64_t len) {
    if (len > n - pos) fail("field runs past the end of the record");
    std::vector<std::uint8_t> v(p + pos, p + pos + len);
    pos += static_cast<std::size_t>(len);
    return v;
  }
  StringMap map() {
    const std::uint32_t len = u32();
    need(len);
    In sub{p + pos, len, 0, base + pos, path, what};
    StringMap m;
    while (sub.pos < sub.n) {
      std::string k = sub.str();
      m[std::move(k)] = sub.str();
    }
    pos += len;
    return m;
  }
};

void write_all(int fd, const std::uint8_t* data, std::size_t n, const std::string& path) {
  while (n > 0) {
    const ssize_t w = ::write(fd, data, n);
    if (w < 0) {
      if (errno == EINTR) continue;
      throw_input_error(path, 0, std::string("cannot write: ") + std::strerror(errno));
    }
    data += w;
    n -= static_cast<std::size_t>(w);
  }
}

void read_at(int fd, std::uint64_t offset, std::uint8_t* data, std::size_t n,
             const std::string& path) {
  while (n > 0) {
    const ssize_t r = ::pread(fd, data, n, static_cast<off_t>(offset));
    if (r < 0 && errno == EINTR) continue;
    if (r <= 0) {
      throw_input_error(path, 0,
                        "byte " + std::to_string(offset) +
                            ": cannot read: " + (r < 0 ? std::strerror(errno) : "end of file"));
    }
    data += r;
    n -= static_cast<std::size_t>(r);
    offset += static_cast<std::uint64_t>(r);
  }
}

std::vector<std::uint8_t> compress(Compression c, const std::vector<std::uint8_t>& in,
                                   const std::string& path) {
  std::vector<std::uint8_t> out;
  if (c == Compression::kZstd) {
    out.resize(ZSTD_compressBound(in.size()));
    // Level 1: the recorder also encodes images; zstd's fastest level keeps most of the gain.
    const std::size_t r = ZSTD_compress(out.data(), out.size(), in.data(), in.size(), 1);
    if (ZSTD_isError(r)) throw_input_error(path, 0, std::string("zstd: ") + ZSTD_getErrorName(r));
    out.resize(r);
  } else if (c == Compression::kLz4) {
    out.resize(LZ4F_compressFrameBound(in.size(), nullptr));
    const std::size_t r = LZ4F_compressFrame(out.data(), out.size(), in.data(), in.size(), nullptr);
    if (LZ4F_isError(r)) throw_input_error(path, 0, std::string("lz4: ") + LZ4F_getErrorName(r));
    out.resize(r);
  } else {
    out = in;
  }
  return out;
}

// Decompresses a chunk's records to exactly `size` bytes; false when the data does not.
bool decompress(Compression c, const std::vector<std::uint8_t>& in, std::uint64_t size,
                std::vector<std::uint8_t>& out) {
  if (c == Compression::kNone) {
    if (in.size() != size) return false;
    out = in;
    return true;
  }
  if (c == Compression::kZstd) {
    // The frame says its size: a mismatch is damage, found before allocating for it.
    const unsigned long long frame = ZSTD_getFrameContentSize(in.data(), in.size());
    if (frame == ZSTD_CONTENTSIZE_ERROR || (frame != ZSTD_CONTENTSIZE_UNKNOWN && frame != size)) {
      return false;
    }
  }
  out.resize(static_cast<std::size_t>(size));
  if (c == Compression::kZstd) {
    const std::size_t r = ZSTD_decompress(out.data(), out.size(), in.data(), in.size());
    return !ZSTD_isError(r) && r == size;
  }
  LZ4F_dctx* ctx = nullptr;
  if (LZ4F_isError(LZ4F_createDecompressionContext(&ctx, LZ4F_VERSION))) return false;
  std::size_t in_pos = 0;
  std::size_t out_pos = 0;
  bool ok = true;
  while (ok) {
    std::size_t dst = out.size() - out_pos;
    std::size_t src = in.size() - in_pos;
    const std::size_t r =
        LZ4F_decompress(ctx, out.data() + out_pos, &dst, in.data() + in_pos, &src, nullptr);
    if (LZ4F_isError(r)) ok = false;
    in_pos += src;
    out_pos += dst;
    if (r == 0) break;                     // frame complete
    if (src == 0 && dst == 0) ok = false;  // no progress: truncated or too large
  }
  LZ4F_freeDecompressionContext(ctx);
  return ok && out_pos == size && in_pos == in.size();
}

}  // namespace

const char* compression_name(Compression c) {
  switch (c) {
    case Compression::kZstd:
      return "zstd";
    case Compression::kLz4:
      return "lz4";
    case Compression::kNone:
      break;
  }
  return "";
}

Compression parse_compression(const std::string& text, const std::string& what) {
  if (text == "zstd") return Compression::kZstd;
  if (text == "lz4") return Compression::kLz4;
  if (text == "none" || text.empty()) return Compression::kNone;
  throw InputError(what + ": unknown compression '" + text + "' (zstd, lz4 or none)");
}

// ---------------------------------------------------------------------------------------------
// Writer

struct Writer::Chunk {
  Out records;
  std::uint64_t start_ns = UINT64_MAX;
  std::uint64_t end_ns = 0;
  std::map<std::uint16_t, std::vector<std::pair<std::uint64_t, std::uint64_t>>> index;
};

Writer::Writer(const std::filesystem::path& path, const WriterOptions& options)
    : path_(path), options_(options) {
  fd_ = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd_ < 0)
    throw_input_error(path.string(), 0, std::string("cannot create: ") + std::strerror(errno));
  Out head;
  head.raw(kMagic, sizeof kMagic);
  Out header;
  header.str(options_.profile);
  header.str(options_.library);
  head.record(kHeader, header);
  try {
    write_bytes(head.b);
  } catch (const InputError&) {
    release();  // no destructor runs after a throwing constructor
    throw;
  }
}

void Writer::release() noexcept {
  closed_ = true;
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
}

Writer::~Writer() {
  try {
    close();
  } catch (const InputError& e) {
    std::fprintf(stderr, "wallar: closing %s\n", e.what());
  }
}

void Writer::check_open() const {
  if (failed_) {
    throw_input_error(path_.string(), 0,
                      "an earlier write failed; the file keeps what was written before it");
  }
  if (closed_) throw_input_error(path_.string(), 0, "MCAP file already closed");
}

void Writer::write_bytes(const std::vector<std::uint8_t>& bytes) {
  try {
    write_all(fd_, bytes.data(), bytes.size(), path_.string());
  } catch (const InputError&) {
    // A partial record may now end the file; writing on (the same chunk again at close) would
    // put a whole record after a torn one. Stop here: readers read up to the torn record.
    failed_ = true;
    throw;
  }
  data_crc_ = crc32_update(data_crc_, bytes.data(), bytes.size());
  offset_ += bytes.size();
}

std::uint16_t Writer::add_schema(const std::string& name, const std::string& encoding,
                                 std::span<const std::uint8_t> data) {
  check_open();
  const auto id = static_cast<std::uint16_t>(schemas_.size() + 1);
  Out c;
  c.u16(id);
  c.str(name);
  c.str(encoding);
  c.u32(static_cast<std::uint32_t>(data.size()));
  c.raw(data.data(), data.size());
  Out rec;
  rec.record(kSchema, c);
  write_bytes(rec.b);
  schemas_.push_back(std::move(rec.b));
  return id;
}

std::uint16_t Writer::add_channel(std::uint16_t schema_id, const std::string& topic,
                                  const std::string& message_encoding, const StringMap& metadata) {
  check_open();
  if (schema_id > schemas_.size()) {
    throw_input_error(path_.string(), 0,
                      "channel " + topic + ": no schema " + std::to_string(schema_id));
  }
  const auto id = static_cast<std::uint16_t>(channels_.size());
  Out c;
  c.u16(id);
  c.u16(schema_id);
  c.str(topic);
  c.str(message_encoding);
  c.map(metadata);
  Out rec;
  rec.record(kChannel, c);
  write_bytes(rec.b);
  channels_.push_back(std::move(rec.b));
  channel_counts_[id] = 0;
  return id;
}

void Writer::add_metadata(const std::string& name, const StringMap& metadata) {
  check_open();
  Out c;
  c.str(name);
  c.map(metadata);
  Out rec;
  rec.record(kMetadata, c);
  Out index;
  index.u64(offset_);
  index.u64(rec.b.size());
  index.str(name);
  Out index_rec;
  index_rec.record(kMetadataIndex, index);
  write_bytes(rec.b);
  metadata_index_.push_back(std::move(index_rec.b));
  ++metadata_count_;
}

void Writer::write_message(std::uint16_t channel_id, std::uint64_t log_time_ns,
                           std::uint64_t publish_time_ns, std::span<const std::uint8_t> data) {
  check_open();
  if (channel_id >= channels_.size()) {
    throw_input_error(path_.string(), 0,
                      "message on unknown channel " + std::to_string(channel_id));
  }
  if (!chunk_) chunk_ = std::make_unique<Chunk>();
  Chunk& ch = *chunk_;
  ch.index[channel_id].emplace_back(log_time_ns, ch.records.b.size());
  Out m;
  m.u16(channel_id);
  m.u32(sequence_[channel_id]++);
  m.u64(log_time_ns);
  m.u64(publish_time_ns);
  m.raw(data.data(), data.size());
  ch.records.record(kMessage, m);
  ch.start_ns = std::min(ch.start_ns, log_time_ns);
  ch.end_ns = std::max(ch.end_ns, log_time_ns);
  first_time_ns_ = std::min(first_time_ns_, log_time_ns);
  last_time_ns_ = std::max(last_time_ns_, log_time_ns);
  ++channel_counts_[channel_id];
  ++message_count_;
  if (ch.records.b.size() >= options_.chunk_bytes ||
      ch.end_ns - ch.start_ns >= static_cast<std::uint64_t>(options_.chunk_span_ns)) {
    flush_chunk();
  }
}

void Writer::flush_chunk() {
  if (!chunk_ || chunk_->records.b.empty()) return;
  Chunk& ch = *chunk_;
  const std::vector<std::uint8_t>& raw = ch.records.b;
  const std::vector<std::uint8_t> packed = compress(options_.compression, raw, path_.string());
  Out c;
  c.u64(ch.start_ns);
  c.u64(ch.end_ns);
  c.u64(raw.size());
  c.u32(crc32_update(0, raw.data(), raw.size()));
  c.str(compression_name(options_.compression));
  c.u64(packed.size());
  c.raw(packed.data(), packed.size());
  Out out;
  out.record(kChunk, c);
  const std::uint64_t chunk_start = offset_;
  const std::uint64_t chunk_length = out.b.size();
  // The message indexes follow the chunk, one per channel in it.
  std::map<std::uint16_t, std::uint64_t> index_offsets;
  for (const auto& [channel, entries] : ch.index) {
    index_offsets[channel] = chunk_start + out.b.size();
    Out idx;
    idx.u16(channel);
    idx.u32(static_cast<std::uint32_t>(entries.size() * 16));
    for (const auto& [t, off] : entries) {
      idx.u64(t);
      idx.u64(off);
    }
    out.record(kMessageIndex, idx);
  }
  const std::uint64_t index_length = out.b.size() - chunk_length;
  write_bytes(out.b);  // one write: the chunk and its indexes land together or not at all
  Out ci;
  ci.u64(ch.start_ns);
  ci.u64(ch.end_ns);
  ci.u64(chunk_start);
  ci.u64(chunk_length);
  Out offsets;
  for (const auto& [channel, off] : index_offsets) {
    offsets.u16(channel);
    offsets.u64(off);
  }
  ci.u32(static_cast<std::uint32_t>(offsets.b.size()));
  ci.raw(offsets.b.data(), offsets.b.size());
  ci.u64(index_length);
  ci.str(compression_name(options_.compression));
  ci.u64(packed.size());
  ci.u64(raw.size());
  Out ci_rec;
  ci_rec.record(kChunkIndex, ci);
  chunk_index_.push_back(std::move(ci_rec.b));
  ++chunk_count_;
  chunk_.reset();
}

void Writer::close() {
  if (closed_) return;
  if (failed_) {
    release();
    return;
  }
  try {
    flush_chunk();
  } catch (const InputError&) {
    release();
    throw;
  }
  closed_ = true;
  Out tail;
  {
    Out de;
    de.u32(data_crc_);  // every byte before the Data End record, the leading magic included
    tail.record(kDataEnd, de);
  }
  const std::uint64_t summary_start = offset_ + tail.b.size();
  std::vector<std::tuple<std::uint8_t, std::uint64_t, std::uint64_t>> groups;
  auto group = [&](std::uint8_t op, const std::vector<std::vector<std::uint8_t>>& records) {
    if (records.empty()) return;
    const std::uint64_t start = offset_ + tail.b.size();
    for (const auto& r : records) tail.raw(r.data(), r.size());
    groups.emplace_back(op, start, offset_ + tail.b.size() - start);
  };
  group(kSchema, schemas_);
  group(kChannel, channels_);
  group(kChunkIndex, chunk_index_);
  group(kMetadataIndex, metadata_index_);
  {
    Out st;
    st.u64(message_count_);
    st.u16(static_cast<std::uint16_t>(schemas_.size()));
    st.u32(static_cast<std::uint32_t>(channels_.size()));
    st.u32(0);  // attachments
    st.u32(metadata_count_);
    st.u32(chunk_count_);
    st.u64(message_count_ > 0 ? first_time_ns_ : 0);
    st.u64(message_count_ > 0 ? last_time_ns_ : 0);
    Out counts;
    for (const auto& [channel, n] : channel_counts_) {
      counts.u16(channel);
      counts.u64(n);
    }
    st.u32(static_cast<std::uint32_t>(counts.b.size()));
    st.raw(counts.b.data(), counts.b.size());
    Out rec;
    rec.record(kStatistics, st);
    group(kStatistics, {rec.b});
  }
  const std::uint64_t summary_offset_start = offset_ + tail.b.size();
  for (const auto& [op, start, length] : groups) {
    Out so;
    so.u8(op);
    so.u64(start);
    so.u64(length);
    tail.record(kSummaryOffset, so);
  }
  // Footer: its CRC covers the summary, the summary offsets and the footer up to the CRC.
  tail.u8(kFooter);
  tail.u64(20);
  tail.u64(summary_start);
  tail.u64(summary_offset_start);
  const std::size_t summary_pos = static_cast<std::size_t>(summary_start - offset_);
  tail.u32(crc32_update(0, tail.b.data() + summary_pos, tail.b.size() - summary_pos));
  tail.raw(kMagic, sizeof kMagic);
  try {
    write_all(fd_, tail.b.data(), tail.b.size(), path_.string());
  } catch (const InputError&) {
    release();
    throw;
  }
  offset_ += tail.b.size();
  const bool synced = ::fsync(fd_) == 0;
  const int saved = errno;
  release();
  if (!synced) throw_input_error(path_.string(), 0, std::string("fsync: ") + std::strerror(saved));
}

// ---------------------------------------------------------------------------------------------
// Reader

bool is_mcap_file(const std::filesystem::path& path) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return false;
  std::uint8_t head[sizeof kMagic] = {};
  const ssize_t r = ::pread(fd, head, sizeof head, 0);
  ::close(fd);
  return r == static_cast<ssize_t>(sizeof head) && std::memcmp(head, kMagic, sizeof head) == 0;
}

File::~File() {
  if (fd_ >= 0) ::close(fd_);
}

std::string File::try_unpack(const ChunkLocation& loc, const std::vector<std::uint8_t>& packed,
                             std::vector<std::uint8_t>& out) {
  if (!decompress(loc.compression, packed, loc.uncompressed_size, out)) {
    return std::string("it does not decompress (") + compression_name(loc.compression) +
           ") to its " + std::to_string(loc.uncompressed_size) + " bytes";
  }
  if (loc.crc != 0 && crc32_update(0, out.data(), out.size()) != loc.crc) {
    return "its records do not match its CRC";
  }
  return {};
}

std::vector<std::uint8_t> File::unpack_chunk(const ChunkLocation& loc,
                                             const std::vector<std::uint8_t>& packed) const {
  std::vector<std::uint8_t> out;
  const std::string problem = try_unpack(loc, packed, out);
  if (!problem.empty()) {
    throw_input_error(path_.string(), 0,
                      "byte " + std::to_string(loc.records_offset) + ": damaged chunk: " + problem);
  }
  return out;
}

std::vector<std::uint8_t> File::load_chunk(std::size_t index) const {
  const ChunkLocation& loc = chunks_[index];
  std::vector<std::uint8_t> packed(static_cast<std::size_t>(loc.compressed_size));
  read_at(fd_, loc.records_offset, packed.data(), packed.size(), path_.string());
  return unpack_chunk(loc, packed);
}

std::vector<std::uint8_t> File::read_message(const MessageRef& ref) const {
  std::vector<std::uint8_t> out(static_cast<std::size_t>(ref.size));
  if (ref.chunk < 0) {
    read_at(fd_, ref.offset, out.data(), out.size(), path_.string());
    return out;
  }
  const std::lock_guard<std::mutex> lock(cache_mutex_);
  if (cached_chunk_ != ref.chunk) {
    cached_ = load_chunk(static_cast<std::size_t>(ref.chunk));
    cached_chunk_ = ref.chunk;
  }
  std::memcpy(out.data(), cached_.data() + ref.offset, out.size());
  return out;
}

std::unique_ptr<File> File::open(const std::filesystem::path& path) {
  std::unique_ptr<File> f(new File);
  f->path_ = path;
  const std::string name = path.string();
  f->fd_ = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (f->fd_ < 0) throw_input_error(name, 0, std::string("cannot open: ") + std::strerror(errno));
  struct stat st {};
  if (::fstat(f->fd_, &st) != 0) throw_input_error(name, 0, "cannot stat");
  const auto size = static_cast<std::uint64_t>(st.st_size);
  f->report_.file_bytes = size;
  std::uint8_t magic[sizeof kMagic] = {};
  if (size < sizeof kMagic) throw_input_error(name, 0, "not an MCAP file (shorter than its magic)");
  read_at(f->fd_, 0, magic, sizeof magic, name);
  if (std::memcmp(magic, kMagic, sizeof magic) != 0) {
    throw_input_error(name, 0, "not an MCAP file (no magic bytes 0x89 MCAP0 at its start)");
  }
  std::uint32_t crc = crc32_update(0, magic, sizeof magic);
  std::uint64_t pos = sizeof kMagic;
  f->report_.bytes_used = pos;
  bool first = true;
  bool data_end = false;
  bool data_damaged = false;
  std::vector<std::uint8_t> content;

  // Parses the Schema, Channel and Message records of the data section or of one chunk.
  auto take = [&](std::uint8_t op, In& in, std::int64_t chunk) {
    switch (op) {
      case kSchema: {
        Schema s;
        s.id = in.u16();
        s.name = in.str();
        s.encoding = in.str();
        s.data = in.bytes(in.u32());
        if (s.id != 0) f->schemas_.try_emplace(s.id, std::move(s));
        break;
      }
      case kChannel: {
        Channel c;
        c.id = in.u16();
        c.schema_id = in.u16();
        c.topic = in.str();
        c.message_encoding = in.str();
        c.metadata = in.map();
        if (c.schema_id != 0 && f->schemas_.count(c.schema_id) == 0) {
          in.fail("channel '" + c.topic + "' names schema " + std::to_string(c.schema_id) +
                  ", not defined before it");
        }
        f->channels_.try_emplace(c.id, std::move(c));
        break;
      }
      case kMessage: {
        MessageRef m;
        m.channel_id = in.u16();
        m.sequence = in.u32();
        m.log_time_ns = in.u64();
        m.publish_time_ns = in.u64();
        if (f->channels_.count(m.channel_id) == 0) {
          in.fail("message on channel " + std::to_string(m.channel_id) + ", not defined before it");
        }
        m.chunk = chunk;
        m.offset = in.base + in.pos;
        m.size = in.n - in.pos;
        f->messages_.push_back(m);
        break;
      }
      default:
        break;
    }
  };

  while (!data_end) {
    if (size - pos < kRecordHeader) {
      f->report_.stop_reason = pos == size ? "the file ends without its Data End and footer"
                                           : "the file ends inside a record header";
      break;
    }
    std::uint8_t head[kRecordHeader];
    read_at(f->fd_, pos, head, sizeof head, name);
    const std::uint8_t op = head[0];
    std::uint64_t len = 0;
    for (int i = 0; i < 8; ++i) len |= static_cast<std::uint64_t>(head[1 + i]) << (8 * i);
    if (len > size - pos - kRecordHeader) {
      char msg[160];
      std::snprintf(msg, sizeof msg,
                    "the file ends inside a record (opcode 0x%02x at byte %llu, %llu bytes "
                    "long, %llu in the file)",
                    op, static_cast<unsigned long long>(pos), static_cast<unsigned long long>(len),
                    static_cast<unsigned long long>(size - pos - kRecordHeader));
      f->report_.stop_reason = msg;
      break;
    }
    if (first && op != kHeader) {
      throw_input_error(name, 0, "byte 8: the first record is not a Header (opcode 0x01)");
    }
    first = false;
    if (op == kDataEnd || op == kFooter) {
      data_end = true;
      if (op == kDataEnd && len >= 4) {
        std::uint8_t c[4];
        read_at(f->fd_, pos + kRecordHeader, c, 4, name);
        const std::uint32_t expected = static_cast<std::uint32_t>(c[0]) | (c[1] << 8) |
                                       (c[2] << 16) | (static_cast<std::uint32_t>(c[3]) << 24);
        if (expected != 0 && expected != crc) {
          // Every chunk passed its own CRC: what is damaged lies outside them (a message index).
          data_damaged = true;
          f->report_.stop_reason = "byte " + std::to_string(pos) +
                                   ": data section CRC mismatch (a record outside the chunks is "
                                   "damaged; every chunk's own CRC held)";
        }
      }
      pos += kRecordHeader + len;
      f->report_.bytes_used = pos;
      break;
    }
    content.resize(static_cast<std::size_t>(len));
    read_at(f->fd_, pos + kRecordHeader, content.data(), content.size(), name);
    crc = crc32_update(crc, head, sizeof head);
    crc = crc32_update(crc, content.data(), content.size());
    In in{content.data(), content.size(), 0, pos + kRecordHeader, &name, "record"};
    if (op == kChunk) {
      in.what = "chunk";
      ChunkLocation loc;
      in.u64();  // message start time
      in.u64();  // message end time
      loc.uncompressed_size = in.u64();
      loc.crc = in.u32();
      const std::string compression = in.str();
      if (compression == "zstd") {
        loc.compression = Compression::kZstd;
      } else if (compression == "lz4") {
        loc.compression = Compression::kLz4;
      } else if (!compression.empty()) {
        in.fail("unknown compression '" + compression + "'");
      }
      loc.compressed_size = in.u64();
      loc.records_offset = in.base + in.pos;
      const std::vector<std::uint8_t> packed = in.bytes(loc.compressed_size);
      if (loc.uncompressed_size > kMaxChunkBytes) {
        in.fail("uncompressed size " + std::to_string(loc.uncompressed_size) +
                " is over the 256 MiB a chunk may hold here");
      }
      std::vector<std::uint8_t> records;
      if (const std::string problem = try_unpack(loc, packed, records); !problem.empty()) {
        // Power loss can leave a chunk whose length landed but whose data did not (zeros):
        // everything before it is good, so read up to it rather than refuse the file.
        f->report_.stop_reason =
            "a damaged chunk at byte " + std::to_string(pos) + " (" + problem + ")";
        break;
      }
      const auto index = static_cast<std::int64_t>(f->chunks_.size());
      f->chunks_.push_back(loc);
      std::size_t at = 0;
      while (at < records.size()) {
        In r{records.data(), records.size(), at, 0, &name, "record in the chunk"};
        r.base = 0;
        const std::uint8_t inner = r.u8();
        const std::uint64_t inner_len = r.u64();
        if (inner_len > records.size() - r.pos) {
          throw_input_error(name, 0,
                            "byte " + std::to_string(loc.records_offset) +
                                ": a record in the chunk runs past its end");
        }
        In body{records.data() + r.pos, static_cast<std::size_t>(inner_len), 0, r.pos, &name,
                "record in the chunk"};
        take(inner, body, index);
        at = r.pos + static_cast<std::size_t>(inner_len);
      }
      {
        const std::lock_guard<std::mutex> lock(f->cache_mutex_);
        f->cached_ = std::move(records);
        f->cached_chunk_ = index;
      }
      ++f->report_.chunks;
    } else if (op == kMetadata) {
      in.what = "metadata";
      std::string n = in.str();
      f->metadata_.emplace_back(std::move(n), in.map());
    } else {
      take(op, in, -1);
    }
    pos += kRecordHeader + len;
    f->report_.bytes_used = pos;
  }
  if (!data_end) return f;

  // The footer, the summary's CRC and its statistics against what the data section held.
  if (size < pos + kFooterRecord + sizeof kMagic) {
    f->report_.stop_reason = "the file ends before its footer";
    return f;
  }
  std::vector<std::uint8_t> tail(kFooterRecord + sizeof kMagic);
  const std::uint64_t footer_pos = size - tail.size();
  read_at(f->fd_, footer_pos, tail.data(), tail.size(), name);
  if (std::memcmp(tail.data() + kFooterRecord, kMagic, sizeof kMagic) != 0 || tail[0] != kFooter) {
    f->report_.stop_reason = "no footer and trailing magic at the end of the file";
    return f;
  }
  In footer{tail.data() + kRecordHeader, 20, 0, footer_pos + kRecordHeader, &name, "footer"};
  const std::uint64_t summary_start = footer.u64();
  const std::uint64_t summary_offset_start = footer.u64();
  const std::uint32_t summary_crc = footer.u32();
  f->report_.complete = !data_damaged;
  if (summary_start == 0) return f;
  if (summary_start < pos || summary_start > footer_pos) {
    throw_input_error(name, 0,
                      "footer: summary start " + std::to_string(summary_start) +
                          " lies outside the summary section");
  }
  std::vector<std::uint8_t> summary(
      static_cast<std::size_t>(footer_pos + kRecordHeader + 16 - summary_start));
  read_at(f->fd_, summary_start, summary.data(), summary.size(), name);
  if (summary_crc != 0 && crc32_update(0, summary.data(), summary.size()) != summary_crc) {
    throw_input_error(name, 0,
                      "byte " + std::to_string(summary_start) +
                          ": summary CRC mismatch (the summary is damaged)");
  }
  if (summary_offset_start != 0 &&
      (summary_offset_start < summary_start || summary_offset_start > footer_pos)) {
    throw_input_error(name, 0,
                      "footer: summary offset start " + std::to_string(summary_offset_start) +
                          " lies outside the summary section");
  }
  const std::uint64_t summary_end =
      (summary_offset_start != 0 ? summary_offset_start : footer_pos) - summary_start;
  std::size_t at = 0;
  while (at + kRecordHeader <= summary_end) {
    In r{summary.data(),  static_cast<std::size_t>(summary_end), at, summary_start, &name,
         "summary record"};
    const std::uint8_t op = r.u8();
    const std::uint64_t len = r.u64();
    r.need(static_cast<std::size_t>(std::min<std::uint64_t>(len, SIZE_MAX)));
    if (op == kStatistics) {
      In s{summary.data() + r.pos,
           static_cast<std::size_t>(len),
           0,
           summary_start + r.pos,
           &name,
           "statistics"};
      const std::uint64_t count = s.u64();
      if (count != f->messages_.size()) {
        s.fail("says " + std::to_string(count) + " messages, the data section holds " +
               std::to_string(f->messages_.size()));
      }
      f->report_.summary_checked = true;
    }
    at = r.pos + static_cast<std::size_t>(len);
  }
  return f;
}

}  // namespace wallar::recording::mcap

#include "io/oni_file.h"

#include <algorithm>
#include <cstring>
#include <fstream>
#include <system_error>
#include <utility>

#include "io/error.h"

namespace vb::io {
namespace {

// The layout OpenNI2's recorder writes (little-endian): a 24-byte file header, then records,
// each a 28-byte header (magic "NIR\0", type, node id, fields size counting the header,
// payload size, undo position), its fields and its payload.
constexpr std::size_t kFileHeaderBytes = 24;
constexpr std::size_t kRecordHeaderBytes = 28;
constexpr std::uint32_t kRecordMagic = 0x0052494E;  // "NIR\0"
constexpr std::uint32_t kMaxOniRecords = 1'000'000;  // 9 hours of 30 fps
constexpr std::uint32_t kMaxNameBytes = 256;

enum RecordType : std::uint32_t {
  kNodeAdded_1_0_0_4 = 0x02,
  kIntProperty = 0x03,
  kRealProperty = 0x04,
  kStringProperty = 0x05,
  kGeneralProperty = 0x06,
  kNodeRemoved = 0x07,
  kNodeDataBegin = 0x08,
  kNodeStateReady = 0x09,
  kNewData = 0x0A,
  kEnd = 0x0B,
  kNodeAdded_1_0_0_5 = 0x0C,
  kNodeAdded = 0x0D,
  kSeekTable = 0x0E,
};

// A bounded little-endian view of one record's fields.
class Fields {
 public:
  Fields(const std::string& bytes, std::string* problem) : bytes_(bytes), problem_(problem) {}

  bool U32(std::uint32_t* v) { return Take(v, 4); }
  bool U64(std::uint64_t* v) { return Take(v, 8); }
  bool Name(std::string* name) {
    std::uint32_t n = 0;
    if (!U32(&n)) return false;
    if (n == 0 || n > kMaxNameBytes || n > bytes_.size() - at_) {
      return Fail("a name of " + std::to_string(n) + " bytes (at most " +
                  std::to_string(std::min<std::size_t>(kMaxNameBytes, bytes_.size() - at_)) +
                  " here)");
    }
    if (bytes_[at_ + n - 1] != '\0') return Fail("a name without its terminating zero");
    name->assign(bytes_, at_, n - 1);
    at_ += n;
    return true;
  }
  /// A property's data: its size word, then that many bytes, all inside the fields.
  bool Data(std::string* data) {
    std::uint32_t n = 0;
    if (!U32(&n)) return false;
    if (n > bytes_.size() - at_) {
      return Fail("property data of " + std::to_string(n) + " bytes, " +
                  std::to_string(bytes_.size() - at_) + " left in the record");
    }
    data->assign(bytes_, at_, n);
    at_ += n;
    return true;
  }
  bool Fail(std::string what) {
    if (problem_->empty()) *problem_ = std::move(what);
    return false;
  }

 private:
  template <typename T>
  bool Take(T* v, std::size_t n) {
    if (bytes_.size() - at_ < n) return Fail("the record's fields end early");
    std::memcpy(v, bytes_.data() + at_, n);
    at_ += n;
    return true;
  }

  const std::string& bytes_;
  std::string* problem_;
  std::size_t at_ = 0;
};

std::uint32_t ReadU32(const char* p) {
  std::uint32_t v;
  std::memcpy(&v, p, 4);
  return v;
}

std::string CodecName(std::uint32_t codec) {
  std::string name(4, '?');
  for (int i = 0; i < 4; ++i) {
    const auto c = static_cast<char>((codec >> (8 * i)) & 0xff);
    if (c >= 0x20 && c < 0x7f) name[static_cast<std::size_t>(i)] = c;
  }
  return name;
}

}  // namespace

bool IsOniUri(const std::string& uri) {
  return uri.size() >= 4 && uri.compare(uri.size() - 4, 4, ".oni") == 0;
}

OniSummary CheckOniFile(const std::filesystem::path& path, const ReadLimits& limits) {
  const std::string source = path.string();
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec))
    throw InputError(source + ": not a recording file (no such regular file)");
  const std::uint64_t size = std::filesystem::file_size(path, ec);
  if (ec) throw InputError(source + ": cannot read its size: " + ec.message());
  CheckLimit(source, "bytes", static_cast<std::int64_t>(size),
             static_cast<std::int64_t>(limits.max_file_bytes), "--max-file-mib");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(source + ": cannot be opened");
  auto fail = [&](std::uint64_t at, const std::string& what) -> InputError {
    return InputError(source + ": at byte " + std::to_string(at) + ": " + what);
  };

  OniSummary summary;
  char header[kFileHeaderBytes];
  if (size < kFileHeaderBytes || !in.read(header, sizeof header))
    throw fail(0, "too short for an OpenNI recording's header");
  if (std::memcmp(header, "NI10", 4) != 0)
    throw fail(0, "not an OpenNI recording (no \"NI10\" at its start)");
  summary.version_major = static_cast<std::uint8_t>(header[4]);
  summary.version_minor = static_cast<std::uint8_t>(header[5]);
  // Files before 1.0.1 lay records out otherwise (24-byte headers, 32-bit positions); OpenNI2
  // reads them, so a walk of this layout would check other bytes than it reads: refused.
  const auto maintenance = static_cast<std::uint16_t>(static_cast<std::uint8_t>(header[6]) |
                                                      static_cast<std::uint8_t>(header[7]) << 8);
  if (summary.version_major != 1 || summary.version_minor != 0 || maintenance != 1) {
    throw fail(4, "recording format " + std::to_string(summary.version_major) + "." +
                      std::to_string(summary.version_minor) + "." + std::to_string(maintenance) +
                      " (only 1.0.1, what OpenNI2 writes, is read)");
  }
  // OpenNI2 sizes a table of streams from this before it reads a record.
  const std::uint32_t max_node_id = ReadU32(header + 20);
  if (max_node_id > kMaxOniNodes) {
    throw fail(20, "a largest stream id of " + std::to_string(max_node_id) + " (at most " +
                       std::to_string(kMaxOniNodes) + ")");
  }

  // Data records by (node, offset), and the seek tables and node-added pointers to them,
  // checked once every record is known.
  std::vector<std::pair<std::uint32_t, std::uint64_t>> data_records;
  struct SeekTable {
    std::uint32_t node;
    std::uint64_t at, payload_at, payload;
  };
  std::vector<SeekTable> seek_tables;
  std::vector<std::pair<std::uint32_t, std::uint64_t>> seek_pointers;  // node, record offset

  auto node_of = [&](std::uint32_t id) -> OniNode* {
    for (OniNode& n : summary.nodes)
      if (n.id == id) return &n;
    return nullptr;
  };

  std::uint64_t at = kFileHeaderBytes;
  bool ended = false;
  std::string fields_bytes;
  while (!ended) {
    if (size - at < kRecordHeaderBytes) throw fail(at, "the file ends before its end record");
    if (summary.records >= kMaxOniRecords) {
      throw fail(at, "more than " + std::to_string(kMaxOniRecords) + " records");
    }
    char rh[kRecordHeaderBytes];
    in.seekg(static_cast<std::streamoff>(at));
    if (!in.read(rh, sizeof rh)) throw fail(at, "cannot be read");
    const std::uint32_t magic = ReadU32(rh), type = ReadU32(rh + 4), node = ReadU32(rh + 8),
                        fields = ReadU32(rh + 12), payload = ReadU32(rh + 16);
    if (magic != kRecordMagic) throw fail(at, "no record starts here (bad magic)");
    if (type < kNodeAdded_1_0_0_4 || type > kSeekTable)
      throw fail(at, "unknown record type " + std::to_string(type));
    if (fields < kRecordHeaderBytes || fields > kMaxOniFieldsBytes) {
      throw fail(at, "record fields of " + std::to_string(fields) + " bytes (from " +
                         std::to_string(kRecordHeaderBytes) + " to " +
                         std::to_string(kMaxOniFieldsBytes) + ")");
    }
    if (payload > kMaxOniPayloadBytes) {
      throw fail(at, "a record payload of " + std::to_string(payload) +
                         " bytes, more than the limit of " + std::to_string(kMaxOniPayloadBytes));
    }
    if (std::uint64_t{fields} + payload > size - at) {
      throw fail(at, "a record of " + std::to_string(std::uint64_t{fields} + payload) +
                         " bytes, past the end of the file");
    }
    fields_bytes.resize(fields - kRecordHeaderBytes);
    if (!in.read(fields_bytes.data(), static_cast<std::streamsize>(fields_bytes.size())))
      throw fail(at, "cannot be read");
    std::string problem;
    Fields f(fields_bytes, &problem);
    if (type != kEnd && node > max_node_id) {
      throw fail(at, "a record for stream " + std::to_string(node) +
                         ", above the header's largest stream id " + std::to_string(max_node_id));
    }
    OniNode* owner = node_of(node);
    const bool adds = type == kNodeAdded || type == kNodeAdded_1_0_0_4 || type == kNodeAdded_1_0_0_5;
    if (!adds && type != kEnd && owner == nullptr)
      throw fail(at, "a record for node " + std::to_string(node) + ", which was never added");

    bool ok = true;
    switch (type) {
      case kNodeAdded_1_0_0_4:
      case kNodeAdded_1_0_0_5:
      case kNodeAdded: {
        if (owner != nullptr) throw fail(at, "node " + std::to_string(node) + " added twice");
        if (summary.nodes.size() >= kMaxOniNodes)
          throw fail(at, "more than " + std::to_string(kMaxOniNodes) + " streams");
        OniNode n;
        n.id = node;
        std::uint32_t codec = 0;
        ok = f.Name(&n.name) && f.U32(&n.type) && f.U32(&codec);
        n.codec = CodecName(codec);
        if (ok && type == kNodeAdded) {
          std::uint64_t min_ts = 0, max_ts = 0, seek = 0;
          ok = f.U32(&n.frames) && f.U64(&min_ts) && f.U64(&max_ts) && f.U64(&seek);
          if (ok && seek != 0) seek_pointers.emplace_back(node, seek);
        }
        if (ok && (n.type < 1 || n.type > 4))
          ok = f.Fail("a stream of unknown type " + std::to_string(n.type));
        summary.nodes.push_back(std::move(n));
        break;
      }
      case kIntProperty:
      case kRealProperty:
      case kStringProperty:
      case kGeneralProperty: {
        std::string name, data;
        ok = f.Name(&name) && f.Data(&data);
        if (!ok) break;
        if ((type == kIntProperty || type == kRealProperty) && data.size() != 8 &&
            data.size() != 4) {
          ok = f.Fail("property " + name + " holds " + std::to_string(data.size()) +
                      " bytes (a number holds 4 or 8)");
          break;
        }
        if (type == kIntProperty && name == "oniRequiredFrameSize") {
          std::int64_t v = 0;
          if (data.size() == 8) {
            std::memcpy(&v, data.data(), 8);
          } else {
            std::int32_t v32;
            std::memcpy(&v32, data.data(), 4);
            v = v32;
          }
          if (v <= 0 || v > kMaxOniPayloadBytes) {
            ok = f.Fail("oniRequiredFrameSize " + std::to_string(v) + " (from 1 to " +
                        std::to_string(kMaxOniPayloadBytes) + ")");
          }
          owner->required_frame_bytes = v;
        } else if (type == kGeneralProperty &&
                   (name == "xnMapOutputMode" || name == "xnSupportedMapOutputModes")) {
          if (data.size() % 12 != 0) {
            ok = f.Fail(name + " of " + std::to_string(data.size()) +
                        " bytes (whole modes of 12 bytes)");
            break;
          }
          for (std::size_t i = 0; ok && i < data.size(); i += 12) {
            const auto w = static_cast<std::int32_t>(ReadU32(data.data() + i));
            const auto h = static_cast<std::int32_t>(ReadU32(data.data() + i + 4));
            const auto fps = static_cast<std::int32_t>(ReadU32(data.data() + i + 8));
            if (w < 1 || h < 1 || w > kMaxOniImageSide || h > kMaxOniImageSide || fps < 0 ||
                fps > 1000) {
              ok = f.Fail(name + " " + std::to_string(w) + " x " + std::to_string(h) + " at " +
                          std::to_string(fps) + " fps (sides from 1 to " +
                          std::to_string(kMaxOniImageSide) + ", at most 1000 fps)");
            } else if (name == "xnMapOutputMode") {
              owner->width = w;
              owner->height = h;
              owner->fps = fps;
            }
          }
        }
        break;
      }
      case kNodeDataBegin: {
        std::uint32_t frames = 0;
        std::uint64_t max_ts = 0;
        ok = f.U32(&frames) && f.U64(&max_ts);
        break;
      }
      case kNewData: {
        std::uint64_t timestamp = 0;
        std::uint32_t frame = 0;
        ok = f.U64(&timestamp) && f.U32(&frame);
        if (ok && payload == 0) ok = f.Fail("a frame without data");
        if (ok && owner->required_frame_bytes > 0 && owner->codec == "NONE" &&
            payload != owner->required_frame_bytes) {
          ok = f.Fail("an uncompressed frame of " + std::to_string(payload) + " bytes, not " +
                      std::to_string(owner->required_frame_bytes));
        }
        if (ok) {
          data_records.emplace_back(node, at);
          ++owner->data_records;
        }
        break;
      }
      case kSeekTable:
        if (payload % 20 != 0) {
          ok = f.Fail("a seek table of " + std::to_string(payload) +
                      " bytes (whole entries of 20 bytes)");
        }
        seek_tables.push_back({node, at, at + fields, payload});
        break;
      case kEnd:
        ended = true;
        break;
      default:  // kNodeRemoved, kNodeStateReady: no fields of their own
        break;
    }
    if (!ok) throw fail(at, problem);
    ++summary.records;
    at += std::uint64_t{fields} + payload;
  }

  // Every seek table entry points at a data record of its own node (or is OpenNI's leading
  // zero entry), and every node's seek table pointer at a seek table of that node.
  std::sort(data_records.begin(), data_records.end());
  std::string entries;
  for (const SeekTable& t : seek_tables) {
    entries.resize(t.payload);
    in.seekg(static_cast<std::streamoff>(t.payload_at));
    if (!in.read(entries.data(), static_cast<std::streamsize>(entries.size())))
      throw fail(t.payload_at, "cannot be read");
    for (std::size_t i = 0; i < entries.size(); i += 20) {
      std::uint64_t offset;
      std::memcpy(&offset, entries.data() + i + 12, 8);
      if (offset == 0) continue;
      if (!std::binary_search(data_records.begin(), data_records.end(),
                              std::make_pair(t.node, offset))) {
        throw fail(t.payload_at + i, "a seek table entry pointing at byte " +
                                         std::to_string(offset) + ", not a frame of node " +
                                         std::to_string(t.node));
      }
    }
  }
  for (const auto& pointer : seek_pointers) {
    const bool found =
        std::any_of(seek_tables.begin(), seek_tables.end(), [&](const SeekTable& t) {
          return t.node == pointer.first && t.at == pointer.second;
        });
    if (!found) {
      throw InputError(source + ": node " + std::to_string(pointer.first) +
                       "'s seek table is said to be at byte " + std::to_string(pointer.second) +
                       ", where there is none");
    }
  }
  return summary;
}

}  // namespace vb::io

#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "io/read_limits.h"

namespace vb::io {

/// What a structurally sound OpenNI2 recording (.oni) holds, per stream ("node").
struct OniNode {
  std::uint32_t id = 0;
  std::string name;        ///< e.g. "Depth"
  std::uint32_t type = 0;  ///< 1 device, 2 depth, 3 image, 4 IR
  std::string codec;       ///< four characters, e.g. "16zT", "NONE", "JPEG"
  std::uint32_t frames = 0;       ///< as declared by the node (the recorder fills it in)
  std::uint32_t data_records = 0; ///< frames actually present
  int width = 0, height = 0, fps = 0;  ///< its xnMapOutputMode, 0 when absent
  std::int64_t required_frame_bytes = 0;  ///< its oniRequiredFrameSize, 0 when absent
};

struct OniSummary {
  std::uint8_t version_major = 0, version_minor = 0;
  std::uint64_t records = 0;
  std::vector<OniNode> nodes;
};

/// Bounds on a recording beyond the file size (ReadLimits::max_file_bytes): what OpenNI2's
/// player allocates from (a frame buffer of oniRequiredFrameSize, a property's data, a
/// stream's resolution) is checked here before OpenNI2 opens the file.
inline constexpr std::uint32_t kMaxOniNodes = 16;
inline constexpr std::uint32_t kMaxOniFieldsBytes = 64 * 1024;        ///< a record's header fields
inline constexpr std::uint32_t kMaxOniPayloadBytes = 16 * 1024 * 1024;  ///< one frame's data
inline constexpr int kMaxOniImageSide = 4096;                         ///< pixels

/// Walks every record of the .oni file @p path before OpenNI2's player reads it, OpenNI2
/// trusting what the file says: the file header ("NI10", format 1.0.1, the largest stream id
/// at most kMaxOniNodes), each record's magic, type, node,
/// field and payload sizes (inside the file and within the bounds above), every string and
/// property inside its record, each node added once, streams' resolutions and frame sizes,
/// seek tables pointing at data records of their own node, and an end record. Bytes after
/// the end record are ignored (OpenNI2's recorder leaves zeros there).
/// @throws InputError "PATH: at byte OFFSET: what is wrong" for the first problem, or naming
///   the limit exceeded.
OniSummary CheckOniFile(const std::filesystem::path& path,
                        const ReadLimits& limits = DefaultReadLimits());

/// True when @p uri names a recording (ends in ".oni").
bool IsOniUri(const std::string& uri);

}  // namespace vb::io

#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

namespace vb::io {

/// A versioned, checksummed binary file of named sections (arrays of doubles, 32-bit ints or
/// bytes, with a row count), for artifacts computed offline and loaded at start, such as the
/// template model. Layout, little-endian:
/// ```
/// "VBARCHV1"  kind (u16 length + bytes)  kind_version u32  section count u32
/// per section: name (u16 length + bytes), type u8 (1 f64, 2 i32, 3 u8), rows u32,
///              count u64 (elements), XXH3-64 of the payload, payload
/// XXH3-64 of everything before it
/// ```
/// Reading checks the whole-file checksum before it trusts any length, and every length
/// against the bytes that are there, so a truncated, corrupt or foreign file is refused with
/// a message naming the file and what is wrong, never a crash or a huge allocation.
class ArchiveWriter {
 public:
  ArchiveWriter(std::string kind, std::uint32_t kind_version)
      : kind_(std::move(kind)), kind_version_(kind_version) {}

  /// Stores @p values column-major with its row count, as Eigen does.
  void Put(const std::string& name, const Eigen::MatrixXd& values);
  void Put(const std::string& name, const Eigen::MatrixXi& values);
  void PutInts(const std::string& name, const std::vector<int>& values);
  void PutString(const std::string& name, const std::string& value);
  /// A list of int lists, stored as offsets and values.
  void PutJagged(const std::string& name, const std::vector<std::vector<int>>& lists);
  void PutStrings(const std::string& name, const std::vector<std::string>& values);

  /// Writes the file (to a temporary, then renamed).
  /// @throws std::runtime_error when it cannot be written.
  void Save(const std::filesystem::path& path) const;

 private:
  struct Section {
    std::uint8_t type;
    std::uint32_t rows;
    std::uint64_t count;
    std::string payload;
  };
  std::string kind_;
  std::uint32_t kind_version_;
  std::vector<std::pair<std::string, Section>> sections_;
};

class ArchiveReader {
 public:
  /// Reads and verifies @p path, which must be an archive of @p kind at @p kind_version.
  /// @throws InputError naming the file: unreadable, over @p max_bytes, not an archive,
  ///   another kind or version, checksum mismatch, truncated or malformed sections.
  ArchiveReader(const std::filesystem::path& path, const std::string& kind,
                std::uint32_t kind_version, std::uint64_t max_bytes = 1ull << 30);

  /// The named section as a matrix with @p rows rows (or the stored row count when -1).
  /// @throws InputError when it is missing or of another type or shape.
  Eigen::MatrixXd Doubles(const std::string& name, int rows = -1) const;
  Eigen::MatrixXi Ints(const std::string& name, int rows = -1) const;
  std::vector<int> IntList(const std::string& name) const;
  std::string String(const std::string& name) const;
  std::vector<std::vector<int>> Jagged(const std::string& name) const;
  std::vector<std::string> Strings(const std::string& name) const;

  bool Has(const std::string& name) const { return sections_.count(name) > 0; }
  const std::string& source() const { return source_; }
  /// @throws InputError "file: section 'name': what".
  [[noreturn]] void Fail(const std::string& name, const std::string& what) const;

 private:
  struct Section {
    std::uint8_t type = 0;
    std::uint32_t rows = 0;
    std::uint64_t count = 0;
    std::size_t offset = 0;  // into data_
  };
  const Section& Find(const std::string& name, std::uint8_t type) const;
  template <typename Matrix>
  Matrix Read(const std::string& name, std::uint8_t type, int rows) const;

  std::string source_;
  std::string data_;
  std::map<std::string, Section> sections_;
};

}  // namespace vb::io

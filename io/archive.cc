#include "io/archive.h"

#include <xxhash.h>

#include <bit>
#include <cstring>
#include <fstream>
#include <stdexcept>

#include "io/error.h"

namespace vb::io {
namespace {

constexpr char kMagic[8] = {'V', 'B', 'A', 'R', 'C', 'H', 'V', '1'};
constexpr std::uint8_t kF64 = 1, kI32 = 2, kU8 = 3;

template <typename T>
void Append(std::string* out, T value) {
  char bytes[sizeof(T)];
  std::memcpy(bytes, &value, sizeof(T));  // this build is little-endian (checked below)
  out->append(bytes, sizeof(T));
}

void AppendName(std::string* out, const std::string& name) {
  if (name.size() > 0xFFFF) throw std::invalid_argument("archive: name too long");
  Append<std::uint16_t>(out, static_cast<std::uint16_t>(name.size()));
  out->append(name);
}

static_assert(std::endian::native == std::endian::little, "archives are little-endian");

// Bounds-checked cursor over the file's bytes.
class Cursor {
 public:
  Cursor(const std::string& data, std::size_t end, const std::string& source)
      : data_(data), end_(end), source_(source) {}
  template <typename T>
  T Read(const char* what) {
    Need(sizeof(T), what);
    T value;
    std::memcpy(&value, data_.data() + at_, sizeof(T));
    at_ += sizeof(T);
    return value;
  }
  std::string Name(const char* what) {
    const auto n = Read<std::uint16_t>(what);
    Need(n, what);
    std::string s = data_.substr(at_, n);
    at_ += n;
    return s;
  }
  void Need(std::uint64_t n, const char* what) const {
    if (n > end_ - at_)
      throw InputError(source_ + ": truncated or malformed archive (reading " + what + " at byte " +
                       std::to_string(at_) + ")");
  }
  void Skip(std::uint64_t n, const char* what) {
    Need(n, what);
    at_ += n;
  }
  std::size_t at() const { return at_; }
  bool done() const { return at_ == end_; }

 private:
  const std::string& data_;
  std::size_t end_;
  std::size_t at_ = 0;
  const std::string& source_;
};

}  // namespace

void ArchiveWriter::Put(const std::string& name, const Eigen::MatrixXd& values) {
  Section s{kF64, static_cast<std::uint32_t>(values.rows()),
            static_cast<std::uint64_t>(values.size()), {}};
  s.payload.assign(reinterpret_cast<const char*>(values.data()),
                   static_cast<std::size_t>(values.size()) * sizeof(double));
  sections_.emplace_back(name, std::move(s));
}

void ArchiveWriter::Put(const std::string& name, const Eigen::MatrixXi& values) {
  Section s{kI32, static_cast<std::uint32_t>(values.rows()),
            static_cast<std::uint64_t>(values.size()), {}};
  s.payload.assign(reinterpret_cast<const char*>(values.data()),
                   static_cast<std::size_t>(values.size()) * sizeof(int));
  sections_.emplace_back(name, std::move(s));
}

void ArchiveWriter::PutInts(const std::string& name, const std::vector<int>& values) {
  Section s{kI32, 1, values.size(), {}};
  s.payload.assign(reinterpret_cast<const char*>(values.data()), values.size() * sizeof(int));
  sections_.emplace_back(name, std::move(s));
}

void ArchiveWriter::PutString(const std::string& name, const std::string& value) {
  sections_.emplace_back(name, Section{kU8, 1, value.size(), value});
}

void ArchiveWriter::PutJagged(const std::string& name,
                              const std::vector<std::vector<int>>& lists) {
  std::vector<int> offsets{0}, flat;
  for (const std::vector<int>& list : lists) {
    flat.insert(flat.end(), list.begin(), list.end());
    offsets.push_back(static_cast<int>(flat.size()));
  }
  PutInts(name + ".offsets", offsets);
  PutInts(name + ".values", flat);
}

void ArchiveWriter::PutStrings(const std::string& name, const std::vector<std::string>& values) {
  std::vector<int> offsets{0};
  std::string flat;
  for (const std::string& v : values) {
    flat += v;
    offsets.push_back(static_cast<int>(flat.size()));
  }
  PutInts(name + ".offsets", offsets);
  PutString(name + ".chars", flat);
}

void ArchiveWriter::Save(const std::filesystem::path& path) const {
  std::string out(kMagic, sizeof(kMagic));
  AppendName(&out, kind_);
  Append<std::uint32_t>(&out, kind_version_);
  Append<std::uint32_t>(&out, static_cast<std::uint32_t>(sections_.size()));
  for (const auto& [name, s] : sections_) {
    AppendName(&out, name);
    Append<std::uint8_t>(&out, s.type);
    Append<std::uint32_t>(&out, s.rows);
    Append<std::uint64_t>(&out, s.count);
    Append<std::uint64_t>(&out, XXH3_64bits(s.payload.data(), s.payload.size()));
    out += s.payload;
  }
  Append<std::uint64_t>(&out, XXH3_64bits(out.data(), out.size()));
  const std::filesystem::path tmp = path.string() + ".tmp";
  {
    std::ofstream file(tmp, std::ios::binary);
    if (!file) throw std::runtime_error(tmp.string() + ": cannot open for writing");
    file.write(out.data(), static_cast<std::streamsize>(out.size()));
    if (!file) throw std::runtime_error(tmp.string() + ": write failed");
  }
  std::filesystem::rename(tmp, path);
}

ArchiveReader::ArchiveReader(const std::filesystem::path& path, const std::string& kind,
                             std::uint32_t kind_version, std::uint64_t max_bytes)
    : source_(path.string()) {
  std::error_code ec;
  const std::uint64_t size = std::filesystem::file_size(path, ec);
  if (ec) throw InputError(source_ + ": cannot read (" + ec.message() + ")");
  if (size > max_bytes)
    throw InputError(source_ + ": " + std::to_string(size) + " bytes is over the limit of " +
                     std::to_string(max_bytes));
  std::ifstream file(path, std::ios::binary);
  if (!file) throw InputError(source_ + ": cannot open");
  data_.resize(size);
  file.read(data_.data(), static_cast<std::streamsize>(size));
  if (!file) throw InputError(source_ + ": read failed");
  if (size < sizeof(kMagic) + 8 || std::memcmp(data_.data(), kMagic, sizeof(kMagic)) != 0)
    throw InputError(source_ + ": not a VirtualButcher archive (bad magic)");
  std::uint64_t stored;
  std::memcpy(&stored, data_.data() + size - 8, 8);
  if (XXH3_64bits(data_.data(), size - 8) != stored)
    throw InputError(source_ + ": checksum mismatch: the file is corrupt or truncated");

  Cursor c(data_, size - 8, source_);
  c.Skip(sizeof(kMagic), "magic");
  const std::string found_kind = c.Name("kind");
  const auto found_version = c.Read<std::uint32_t>("kind version");
  if (found_kind != kind)
    throw InputError(source_ + ": is a '" + found_kind + "' archive, expected '" + kind + "'");
  if (found_version != kind_version)
    throw InputError(source_ + ": " + kind + " version " + std::to_string(found_version) +
                     " is not supported; this build reads version " + std::to_string(kind_version));
  const auto count = c.Read<std::uint32_t>("section count");
  for (std::uint32_t i = 0; i < count; ++i) {
    const std::string name = c.Name("section name");
    Section s;
    s.type = c.Read<std::uint8_t>("section type");
    s.rows = c.Read<std::uint32_t>("section rows");
    s.count = c.Read<std::uint64_t>("section count");
    const auto hash = c.Read<std::uint64_t>("section checksum");
    const std::uint64_t width = s.type == kF64 ? 8 : s.type == kI32 ? 4 : s.type == kU8 ? 1 : 0;
    if (width == 0) Fail(name, "unknown element type " + std::to_string(s.type));
    if (s.count > (size / width)) Fail(name, "claims more elements than the file holds");
    s.offset = c.at();
    c.Skip(s.count * width, "section payload");
    if (XXH3_64bits(data_.data() + s.offset, s.count * width) != hash)
      Fail(name, "checksum mismatch");
    if (!sections_.emplace(name, s).second) Fail(name, "appears twice");
  }
  if (!c.done()) throw InputError(source_ + ": unexpected bytes after the last section");
}

void ArchiveReader::Fail(const std::string& name, const std::string& what) const {
  throw InputError(source_ + ": section '" + name + "': " + what);
}

const ArchiveReader::Section& ArchiveReader::Find(const std::string& name,
                                                  std::uint8_t type) const {
  const auto it = sections_.find(name);
  if (it == sections_.end()) Fail(name, "missing");
  if (it->second.type != type) Fail(name, "has another element type");
  return it->second;
}

template <typename Matrix>
Matrix ArchiveReader::Read(const std::string& name, std::uint8_t type, int rows) const {
  const Section& s = Find(name, type);
  const std::uint32_t r = rows < 0 ? s.rows : static_cast<std::uint32_t>(rows);
  if (s.rows != r || (r == 0 ? s.count != 0 : s.count % r != 0))
    Fail(name, "has " + std::to_string(s.rows) + " rows, expected " + std::to_string(r));
  const Eigen::Index cols = r == 0 ? 0 : static_cast<Eigen::Index>(s.count / r);
  Matrix m(r, cols);
  if (s.count > 0)  // an empty matrix has no data pointer to copy to
    std::memcpy(m.data(), data_.data() + s.offset, s.count * sizeof(typename Matrix::Scalar));
  return m;
}

Eigen::MatrixXd ArchiveReader::Doubles(const std::string& name, int rows) const {
  return Read<Eigen::MatrixXd>(name, kF64, rows);
}

Eigen::MatrixXi ArchiveReader::Ints(const std::string& name, int rows) const {
  return Read<Eigen::MatrixXi>(name, kI32, rows);
}

std::vector<int> ArchiveReader::IntList(const std::string& name) const {
  const Section& s = Find(name, kI32);
  std::vector<int> v(s.count);
  if (s.count > 0) std::memcpy(v.data(), data_.data() + s.offset, s.count * sizeof(int));
  return v;
}

std::string ArchiveReader::String(const std::string& name) const {
  const Section& s = Find(name, kU8);
  return data_.substr(s.offset, s.count);
}

std::vector<std::vector<int>> ArchiveReader::Jagged(const std::string& name) const {
  const std::vector<int> offsets = IntList(name + ".offsets");
  const std::vector<int> values = IntList(name + ".values");
  if (offsets.empty() || offsets.front() != 0 ||
      offsets.back() != static_cast<int>(values.size()))
    Fail(name, "offsets do not match the values");
  std::vector<std::vector<int>> lists;
  for (std::size_t i = 0; i + 1 < offsets.size(); ++i) {
    if (offsets[i + 1] < offsets[i]) Fail(name, "offsets decrease");
    lists.emplace_back(values.begin() + offsets[i], values.begin() + offsets[i + 1]);
  }
  return lists;
}

std::vector<std::string> ArchiveReader::Strings(const std::string& name) const {
  const std::vector<int> offsets = IntList(name + ".offsets");
  const std::string chars = String(name + ".chars");
  if (offsets.empty() || offsets.front() != 0 || offsets.back() != static_cast<int>(chars.size()))
    Fail(name, "offsets do not match the characters");
  std::vector<std::string> out;
  for (std::size_t i = 0; i + 1 < offsets.size(); ++i) {
    if (offsets[i + 1] < offsets[i]) Fail(name, "offsets decrease");
    out.push_back(chars.substr(static_cast<std::size_t>(offsets[i]),
                               static_cast<std::size_t>(offsets[i + 1] - offsets[i])));
  }
  return out;
}

}  // namespace vb::io

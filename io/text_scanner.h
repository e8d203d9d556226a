#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

namespace vb::io::internal {

/// Reads a whole file into memory after checking its size against @p max_bytes.
/// @throws InputError naming the file when it cannot be read or is too large.
std::string ReadFileBounded(const std::filesystem::path& path, std::uint64_t max_bytes);

/// Walks a text buffer line by line, splitting each line into whitespace-separated tokens.
/// Blank lines and lines starting with the comment character are skipped. Every parse error
/// is thrown as InputError with "file:line: message".
class LineScanner {
 public:
  LineScanner(std::string_view text, std::string source, char comment = '#');

  /// Advances to the next line that has tokens; false at the end of the text.
  bool NextLine();
  int line_number() const { return line_number_; }
  const std::vector<std::string_view>& tokens() const { return tokens_; }

  /// Parses token @p i as a finite double; @p what names the value in the error.
  double Double(std::size_t i, std::string_view what) const;
  /// As Double, but "nan" and "inf" are returned, not refused: for values the caller checks
  /// itself (normals, which ReadMesh and ReadCloud validate and drop).
  double DoubleOrNonFinite(std::size_t i, std::string_view what) const;
  /// Parses token @p i (or a prefix of it up to @p stop) as a signed integer.
  std::int64_t Int(std::size_t i, std::string_view what) const;
  /// Parses a string (part of a token) as a signed integer.
  std::int64_t IntFrom(std::string_view text, std::string_view what) const;

  /// Throws InputError "source:line: message".
  [[noreturn]] void Fail(const std::string& message) const;

 private:
  std::string_view text_;
  std::string source_;
  char comment_;
  std::size_t pos_ = 0;
  int line_number_ = 0;
  std::vector<std::string_view> tokens_;
};

}  // namespace vb::io::internal

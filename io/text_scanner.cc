#include "io/text_scanner.h"

#include <cctype>
#include <charconv>
#include <cmath>
#include <fstream>

#include "io/error.h"
#include "io/read_limits.h"

namespace vb::io::internal {

std::string ReadFileBounded(const std::filesystem::path& path, std::uint64_t max_bytes) {
  std::error_code ec;
  const auto size = std::filesystem::file_size(path, ec);
  if (ec) {
    throw InputError(path.string() + ": cannot read: " + ec.message());
  }
  if (size > max_bytes) {
    throw InputError(path.string() + ": file is " + std::to_string(size) +
                     " bytes, more than the limit of " + std::to_string(max_bytes));
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    throw InputError(path.string() + ": cannot open for reading");
  }
  std::string text(size, '\0');
  in.read(text.data(), static_cast<std::streamsize>(size));
  if (static_cast<std::uint64_t>(in.gcount()) != size) {
    throw InputError(path.string() + ": short read");
  }
  return text;
}

LineScanner::LineScanner(std::string_view text, std::string source, char comment)
    : text_(text), source_(std::move(source)), comment_(comment) {}

bool LineScanner::NextLine() {
  while (pos_ < text_.size()) {
    std::size_t end = text_.find('\n', pos_);
    if (end == std::string_view::npos) end = text_.size();
    std::string_view line = text_.substr(pos_, end - pos_);
    pos_ = end + 1;
    ++line_number_;
    tokens_.clear();
    std::size_t i = 0;
    while (i < line.size()) {
      while (i < line.size() && std::isspace(static_cast<unsigned char>(line[i]))) ++i;
      if (i >= line.size()) break;
      if (tokens_.empty() && line[i] == comment_) break;
      std::size_t j = i;
      while (j < line.size() && !std::isspace(static_cast<unsigned char>(line[j]))) ++j;
      tokens_.push_back(line.substr(i, j - i));
      i = j;
    }
    if (!tokens_.empty()) return true;
  }
  tokens_.clear();
  return false;
}

double LineScanner::Double(std::size_t i, std::string_view what) const {
  const double value = DoubleOrNonFinite(i, what);
  if (!std::isfinite(value)) {
    Fail(std::string(what) + ": '" + Excerpt(tokens_[i]) + "' is not finite");
  }
  return value;
}

double LineScanner::DoubleOrNonFinite(std::size_t i, std::string_view what) const {
  if (i >= tokens_.size()) {
    Fail("missing " + std::string(what));
  }
  const std::string_view token = tokens_[i];
  double value = 0.0;
  const auto [ptr, ec] = std::from_chars(token.data(), token.data() + token.size(), value);
  if (ec != std::errc() || ptr != token.data() + token.size()) {
    Fail(std::string(what) + ": '" + Excerpt(token) + "' is not a number");
  }
  return value;
}

std::int64_t LineScanner::Int(std::size_t i, std::string_view what) const {
  if (i >= tokens_.size()) {
    Fail("missing " + std::string(what));
  }
  return IntFrom(tokens_[i], what);
}

std::int64_t LineScanner::IntFrom(std::string_view text, std::string_view what) const {
  std::int64_t value = 0;
  const auto [ptr, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (ec != std::errc() || ptr != text.data() + text.size()) {
    Fail(std::string(what) + ": '" + Excerpt(text) + "' is not an integer");
  }
  return value;
}

void LineScanner::Fail(const std::string& message) const {
  throw InputError(source_ + ":" + std::to_string(line_number_) + ": " + message);
}

}  // namespace vb::io::internal

// libFuzzer target: decoding the project's LCM messages from any bytes, as lcm-listen does
// (the generated decoders, then io::ValidateCutLines). The first byte picks the type. The
// generated decoders may throw std::exception on a negative length (lcm-listen catches and
// counts it); a crash, a leak or an allocation past libFuzzer's limit is a finding.
#include <cstddef>
#include <cstdint>
#include <exception>

#include "io/lcm_publisher.h"
#include "vbutcher/cut_lines_t.hpp"
#include "vbutcher/diagnostic_t.hpp"
#include "vbutcher/status_t.hpp"

namespace {

template <typename Message>
bool Decode(const std::uint8_t* data, std::size_t size, Message* m) {
  try {
    return m->decode(data, 0, static_cast<int>(size)) >= 0;
  } catch (const std::exception&) {
    return false;
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  const std::uint8_t* body = data + 1;
  const std::size_t n = size - 1;
  switch (data[0] % 3) {
    case 0: {
      vbutcher::cut_lines_t m;
      if (Decode(body, n, &m)) (void)vb::io::ValidateCutLines(m);
      break;
    }
    case 1: {
      vbutcher::status_t m;
      (void)Decode(body, n, &m);
      break;
    }
    default: {
      vbutcher::diagnostic_t m;
      (void)Decode(body, n, &m);
      break;
    }
  }
  return 0;
}

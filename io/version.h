#pragma once

namespace vb {

/// The release, from CMakeLists.txt's project(VERSION), e.g. "0.1.0".
const char* Version();
/// The source's git revision at build time (`git describe --always --dirty`), or "unknown"
/// when built outside a git checkout.
const char* GitRevision();

}  // namespace vb

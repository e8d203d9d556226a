#include "tools/lcm_command.h"

#include <chrono>
#include <cstdio>
#include <fstream>
#include <lcm/lcm-cpp.hpp>
#include <nlohmann/json.hpp>
#include <thread>

#include "io/error.h"
#include "io/lcm_publisher.h"

namespace vb::tools {
namespace {

std::int64_t NowMicros() {
  return std::chrono::duration_cast<std::chrono::microseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

// Reads the cuts file `vbutcher morph --cuts` writes into a cut-lines message.
vbutcher::cut_lines_t ReadCuts(const std::filesystem::path& path) {
  std::ifstream in(path);
  if (!in) throw InputError(path.string() + ": cannot open");
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(in);
    if (j.at("format") != "vbutcher-cuts")
      throw InputError(path.string() + ": format is not vbutcher-cuts");
    vbutcher::cut_lines_t m;
    for (const auto& c : j.at("cuts")) {
      vbutcher::cut_t cut;
      cut.name = c.at("name").get<std::string>();
      for (int a = 0; a < 3; ++a) {
        cut.plane_point[a] = c.at("plane").at("point").at(a).get<double>();
        cut.plane_normal[a] = c.at("plane").at("normal").at(a).get<double>();
      }
      cut.fit_rms_m = c.at("fit_rms").get<float>();
      cut.coverage = c.at("coverage").get<float>();
      cut.confidence = c.at("confidence").get<float>();
      for (const auto& p : c.at("line"))
        cut.line.push_back({p.at(0).get<float>(), p.at(1).get<float>(), p.at(2).get<float>()});
      cut.num_points = static_cast<std::int16_t>(std::min<std::size_t>(cut.line.size(), 32767));
      m.cuts.push_back(std::move(cut));
    }
    for (const auto& p : j.at("parts")) {
      vbutcher::part_t part;
      part.name = p.at("name").get<std::string>();
      part.volume_m3 = p.at("volume").get<double>();
      part.area_m2 = p.at("area").get<double>();
      m.parts.push_back(std::move(part));
    }
    m.num_cuts = static_cast<std::int8_t>(std::min<std::size_t>(m.cuts.size(), 127));
    m.num_parts = static_cast<std::int8_t>(std::min<std::size_t>(m.parts.size(), 127));
    return m;
  } catch (const nlohmann::json::exception& e) {
    throw InputError(path.string() + ": " + e.what());
  }
}

// Every message on the daemon's channels, decoded here (not by LCM's typed subscription), so a
// malformed one is counted and reported instead of ending the program. LCM 1.3.1's generated
// decoders threw (std::length_error) on a negative length; io/lcm/harden-generated makes them
// return -1 instead, and the catch stays for whatever another lcm-gen does.
struct Listener {
  const LcmListenOptions* options;
  int received = 0, invalid = 0, out_of_order = 0, malformed = 0, statuses = 0, diagnostics = 0;
  std::int64_t last_sequence = 0;

  template <typename Message>
  bool Decode(const lcm::ReceiveBuffer* buffer, const std::string& channel, Message* m) {
    int used = -1;
    try {
      used = m->decode(buffer->data, 0, static_cast<int>(buffer->data_size));
    } catch (const std::exception& e) {
      std::printf("lcm-listen: %s: malformed message of %u bytes (%s); ignored\n",
                  channel.c_str(), buffer->data_size, e.what());
      ++malformed;
      return false;
    }
    if (used < 0) {
      std::printf("lcm-listen: %s: malformed message of %u bytes; ignored\n", channel.c_str(),
                  buffer->data_size);
      ++malformed;
      return false;
    }
    return true;
  }

  void OnCutLines(const lcm::ReceiveBuffer* buffer, const std::string& channel) {
    vbutcher::cut_lines_t m;
    if (!Decode(buffer, channel, &m)) return;
    const std::string problem = io::ValidateCutLines(m);
    if (!problem.empty()) {
      std::printf("lcm-listen: %s: invalid message: %s\n", channel.c_str(), problem.c_str());
      ++invalid;
      return;
    }
    if (m.sequence <= last_sequence) ++out_of_order;
    last_sequence = m.sequence;
    ++received;
    static const char* kVerdicts[] = {"accepted", "rejected", "unconfirmed", "refused"};
    const char* verdict = m.saw_verdict >= 0 && m.saw_verdict < 4 ? kVerdicts[m.saw_verdict]
                                                                   : "unknown verdict";
    std::printf("lcm-listen: %s seq %lld carcass %s: %d cuts, %d parts, saw verdict %s: %s\n",
                channel.c_str(), static_cast<long long>(m.sequence), m.carcass_id.c_str(),
                m.num_cuts, m.num_parts, verdict, m.status.c_str());
  }

  void OnStatus(const lcm::ReceiveBuffer* buffer, const std::string& channel) {
    vbutcher::status_t m;
    if (!Decode(buffer, channel, &m)) return;
    ++statuses;
    if (!options->print_status) return;
    static const char* kStates[] = {"STARTING", "READY", "BUSY", "DEGRADED", "FAULT"};
    static const char* kHealth[] = {"OK",        "FROZEN",     "MISSING",
                                    "LOW_VALID", "RECOVERING", "STARTING"};
    std::printf("lcm-listen: %s seq %lld state %s version %s: %s\n", channel.c_str(),
                static_cast<long long>(m.sequence),
                m.state >= 0 && m.state < 5 ? kStates[m.state] : "unknown", m.version.c_str(),
                m.state_text.c_str());
    const std::int64_t now = NowMicros();
    static const char* kRig[] = {"NOT_CHECKED", "OK", "MOVED", "NOT_COMPARED"};
    for (const vbutcher::camera_health_t& c : m.cameras) {
      std::printf("lcm-listen:   camera %s serial %s state %s fps %.1f valid %.2f last frame %s; "
                  "rig %s %.2f mm %.3f deg\n",
                  c.name.c_str(), c.serial.c_str(),
                  c.state >= 0 && c.state < 6 ? kHealth[c.state] : "unknown", c.fps,
                  c.valid_ratio,
                  c.last_frame_utime == 0
                      ? "never"
                      : (std::to_string((now - c.last_frame_utime) / 1000) + " ms ago").c_str(),
                  c.rig_check >= 0 && c.rig_check < 4 ? kRig[c.rig_check] : "unknown",
                  c.rig_offset_mm, c.rig_turn_deg);
    }
    std::printf("lcm-listen:   rig check: %s\n", m.rig_check.c_str());
  }

  void OnDiagnostic(const lcm::ReceiveBuffer* buffer, const std::string& channel) {
    vbutcher::diagnostic_t m;
    if (!Decode(buffer, channel, &m)) return;
    ++diagnostics;
    if (!options->print_diagnostics) return;
    static const char* kLevels[] = {"INFO", "WARNING", "ERROR"};
    std::printf("lcm-listen: %s seq %lld %s %s: %s\n", channel.c_str(),
                static_cast<long long>(m.sequence),
                m.level >= 0 && m.level < 3 ? kLevels[m.level] : "unknown", m.source.c_str(),
                m.message.c_str());
  }
};

}  // namespace

int RunLcmPublish(const LcmPublishOptions& options) {
  vbutcher::cut_lines_t message = ReadCuts(options.cuts_path);
  io::ThinCutLines(&message);
  message.carcass_id = options.carcass_id;
  message.template_id = options.template_id;
  message.template_version = 1;
  message.saw_verdict = vbutcher::cut_lines_t::REFUSED;
  message.status = "published by vbutcher lcm-publish";
  io::LcmPublisher publisher(options.url);
  for (int i = 0; i < options.count; ++i) {
    message.utime = NowMicros();
    if (!publisher.Publish(message)) {
      std::fprintf(stderr, "vbutcher: lcm-publish: %s\n", publisher.last_error().c_str());
      return 3;
    }
    vbutcher::status_t status;
    status.utime = message.utime;
    status.state = vbutcher::status_t::READY;
    status.state_text = "lcm-publish";
    status.num_cameras = 0;
    status.can_state = "none";
    status.rig_check = "not checked yet";
    publisher.Publish(status);
    if (i + 1 < options.count)
      std::this_thread::sleep_for(std::chrono::milliseconds(options.period_ms));
  }
  std::printf("lcm-publish: %d cut-lines messages of %d bytes on %s\n", options.count,
              message.getEncodedSize(), options.url.c_str());
  return 0;
}

int RunLcmListen(const LcmListenOptions& options) {
  lcm::LCM lcm(options.url);
  if (!lcm.good()) throw InputError("LCM URL '" + options.url + "': LCM could not start on it");
  Listener listener{&options};
  lcm.subscribe(options.channels.cut_lines, &Listener::OnCutLines, &listener);
  lcm.subscribe(options.channels.status, &Listener::OnStatus, &listener);
  lcm.subscribe(options.channels.diagnostics, &Listener::OnDiagnostic, &listener);
  // A script that starts a publisher after this line is sure nothing it sends is missed.
  std::printf("lcm-listen: listening on %s\n", options.url.c_str());
  std::fflush(stdout);
  const auto deadline =
      std::chrono::steady_clock::now() + std::chrono::duration<double>(options.timeout_s);
  auto done = [&] {
    return listener.received >= options.count && listener.statuses >= options.status_count &&
           listener.diagnostics >= options.diagnostic_count;
  };
  while (!done() && std::chrono::steady_clock::now() < deadline) {
    lcm.handleTimeout(50);
    std::fflush(stdout);
  }
  std::printf(
      "lcm-listen summary: received %d invalid %d out_of_order %d malformed %d status %d "
      "diagnostics %d\n",
      listener.received, listener.invalid, listener.out_of_order, listener.malformed,
      listener.statuses, listener.diagnostics);
  return done() && listener.invalid == 0 && listener.out_of_order == 0 && listener.malformed == 0
             ? 0
             : 3;
}

}  // namespace vb::tools

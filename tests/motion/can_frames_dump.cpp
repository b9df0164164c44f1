// Prints every kind of CAN frame mfcd sends (motion/can_frames.hpp: status, heartbeat, version,
// pick A/B/C), each built by the library's own encoders, for a set of representative reports
// (and releases), as JSON lines for tests/motion/dbc_canmatrix_test.py:
//
//   {"case":"typical","frame":"MFCD_Status","id":384,"dlc":8,"data":"0100...",
//    "signals":{"StatusReady":1,...}}
//
// "frame" is the docs/mfcd.dbc frame the encoder claims to produce, "data" the payload as
// sent (dlc bytes, hex), and "signals" the physical value of every DBC signal of that frame
// as the encoder was asked to send it, taken from the report (not from the frame): mm, deg,
// ms, 0..1 score, counters, version numbers. The Python side decodes "data" with an independent DBC parser and
// compares. Floats print with 9 significant digits, so they read back as the exact float.
// Exit 1 if an encoder refuses a case (all cases are within the signal ranges).
#include "motion/can_frames.hpp"
#include "motion/register_map.hpp"

#include <algorithm>
#include <cstdio>
#include <optional>
#include <random>
#include <string>
#include <utility>
#include <vector>

using namespace mfcd::motion;

namespace {

struct Case {
  std::string name;
  RobotReport report;
  std::uint16_t heartbeat = 0;
  std::uint8_t sequence = 0;
  // The release in MFCD_Version (CanConfig packing): major << 8 | minor, and patch.
  std::uint16_t software_version = 0;
  std::uint16_t software_patch = 0;
};

using Signals = std::vector<std::pair<std::string, double>>;

void print_frame(const std::string& case_name, const char* frame_name, const can_frame& f, const Signals& signals) {
  std::string hex;
  char byte[3];
  for (unsigned i = 0; i < f.len; ++i) {
    std::snprintf(byte, sizeof(byte), "%02x", f.data[i]);
    hex += byte;
  }
  std::printf("{\"case\":\"%s\",\"frame\":\"%s\",\"id\":%u,\"dlc\":%u,\"data\":\"%s\",\"signals\":{", case_name.c_str(),
              frame_name, static_cast<unsigned>(f.can_id), static_cast<unsigned>(f.len), hex.c_str());
  for (std::size_t i = 0; i < signals.size(); ++i)
    std::printf("%s\"%s\":%.9g", i ? "," : "", signals[i].first.c_str(), signals[i].second);
  std::printf("}}\n");
}

double flag(bool b) { return b ? 1.0 : 0.0; }

// One line per frame kind. Returns false when encode_pick refused the case.
bool dump(const Case& c) {
  const RobotReport& r = c.report;
  print_frame(c.name, "MFCD_Status", encode_status(r, kCanDefaultBase),
              {{"StatusReady", flag(r.ready != 0 && r.error_code == 0)},
               {"StatusReserved1_2", 0},  // Modbus BUSY/DONE: never sent on CAN
               {"StatusError", flag(r.error_code != 0)},
               {"StatusPickValid", flag(r.pick_valid != 0)},
               {"StatusVisionOk", flag(r.vision_ok != 0)},
               {"StatusReserved6_15", 0},
               {"JobIdEcho", r.job_id},
               {"ErrorCode", r.error_code},
               {"ObjectsRemaining", r.objects_remaining}});
  print_frame(c.name, "MFCD_Heartbeat", encode_heartbeat(c.heartbeat, r, kCanDefaultBase),
              {{"Heartbeat", c.heartbeat},
               {"CycleTime", r.cycle_time_ms},
               {"RecipeEcho", r.recipe_id},
               {"CandidateCount", std::min<int>(r.candidate_count, 255)},  // saturates in one byte
               {"MapVersion", reg::kMapVersion}});
  print_frame(c.name, "MFCD_Version", encode_version(c.software_version, c.software_patch, kCanDefaultBase),
              {{"SoftwareMajor", c.software_version >> 8},
               {"SoftwareMinor", c.software_version & 0xff},
               {"SoftwarePatch", c.software_patch},
               {"RegisterMapVersion", reg::kMapVersion},
               {"DbcVersion", kCanDbcVersion},
               {"VersionReserved48_63", 0}});
  const auto pick = encode_pick(r, c.sequence, kCanDefaultBase);
  if (!pick) {
    std::fprintf(stderr, "case %s: encode_pick refused a pick inside the signal ranges\n", c.name.c_str());
    return false;
  }
  print_frame(c.name, "MFCD_PickA", (*pick)[0],
              {{"PickSeqA", c.sequence},
               {"PickX", r.pick.x_mm},
               {"PickY", r.pick.y_mm},
               {"CandidateIndex", std::min<int>(r.candidate_index, 255)}});
  print_frame(c.name, "MFCD_PickB", (*pick)[1],
              {{"PickSeqB", c.sequence}, {"PickZ", r.pick.z_mm}, {"PickRx", r.pick.rx_deg}, {"PickRy", r.pick.ry_deg}});
  print_frame(c.name, "MFCD_PickC", (*pick)[2],
              {{"PickSeqC", c.sequence},
               {"PickRz", r.pick.rz_deg},
               {"PickScore", r.score},  // cases keep the score in 0..1, where the encoder does not clamp
               {"PickJobId", r.job_id},
               {"PickValid", flag(r.pick_valid != 0)},
               {"PickRank", r.pick_rank}});
  return true;
}

std::vector<Case> cases() {
  std::vector<Case> out;
  out.push_back({"zeros", RobotReport{}, 0, 0});

  Case typical{"typical", {}, 17, 5, 0x0102, 3};  // release 1.2.3
  RobotReport& t = typical.report;
  t.job_id = 42;
  t.recipe_id = 3;
  t.objects_remaining = 7;
  t.cycle_time_ms = 850;
  t.candidate_index = 2;
  t.candidate_count = 5;
  t.ready = t.vision_ok = t.pick_valid = 1;
  t.pick = {512.25f, -130.5f, 740.125f, 179.5f, -2.25f, 45.0f};
  t.score = 0.8734f;
  t.pick_rank = 2;
  out.push_back(typical);

  // Every daemon error code (daemon/cycle.hpp CycleError) and one outside the table; READY
  // is set in the report, so StatusReady must drop to 0 on CAN.
  for (std::uint16_t code : {1, 2, 3, 4, 5, 6, 7, 8, 999}) {
    Case e{"error" + std::to_string(code), typical.report, static_cast<std::uint16_t>(100 + code),
           static_cast<std::uint8_t>(code)};
    e.report.error_code = code;
    e.report.pick_valid = 0;
    e.report.vision_ok = code == 2 || code == 3 ? 0 : 1;
    out.push_back(e);
  }

  // The largest values each signal holds; counts past one byte saturate at 255.
  Case high{"max", {}, 65535, 255, 0xffff, 0xffff};  // release 255.255.65535
  RobotReport& h = high.report;
  h.job_id = h.recipe_id = h.objects_remaining = h.cycle_time_ms = 65535;
  h.candidate_index = 65535;
  h.candidate_count = 300;
  h.ready = h.vision_ok = h.pick_valid = 1;
  h.pick = {83886.07f, 83886.07f, 83886.07f, 327.67f, 327.67f, 327.67f};
  h.score = 1.0f;
  h.pick_rank = 127;
  out.push_back(high);

  // The most negative values the signed signals hold, and the smallest steps around zero.
  Case low{"min", {}, 1, 128, 0x0100, 0};  // release 1.0.0
  low.report.pick = {-83886.08f, -83886.08f, -83886.08f, -327.68f, -327.68f, -327.68f};
  low.report.candidate_count = 255;
  low.report.candidate_index = 255;
  out.push_back(low);
  Case tiny{"tiny", {}, 2, 1, 0x0001, 1};  // release 0.1.1
  tiny.report.pick = {-0.01f, 0.01f, -0.02f, -0.01f, 0.01f, -0.01f};
  tiny.report.score = 0.0001f;
  tiny.report.job_id = 1;
  out.push_back(tiny);

  // Seeded random reports: a fixed, repeatable sample of the ordinary range.
  std::mt19937 rng(43);
  std::mt19937 release_rng(44);  // own stream: the reports drawn from rng do not depend on it
  std::uniform_real_distribution<float> mm(-3000.0f, 3000.0f), deg(-180.0f, 180.0f), unit(0.0f, 1.0f);
  std::uniform_int_distribution<int> u16(0, 65535), bit(0, 1), code(0, 7);
  for (int i = 0; i < 40; ++i) {
    Case c{"random" + std::to_string(i), {}, static_cast<std::uint16_t>(u16(rng)), static_cast<std::uint8_t>(u16(rng))};
    RobotReport& r = c.report;
    r.job_id = static_cast<std::uint16_t>(u16(rng));
    r.recipe_id = static_cast<std::uint16_t>(u16(rng));
    r.error_code = static_cast<std::uint16_t>(bit(rng) ? 0 : code(rng));
    r.objects_remaining = static_cast<std::uint16_t>(u16(rng) % 100);
    r.cycle_time_ms = static_cast<std::uint16_t>(u16(rng));
    r.candidate_index = static_cast<std::uint16_t>(u16(rng) % 300);
    r.candidate_count = static_cast<std::uint16_t>(u16(rng) % 300);
    r.ready = static_cast<std::uint16_t>(bit(rng));
    r.vision_ok = static_cast<std::uint16_t>(bit(rng));
    r.pick_valid = static_cast<std::uint16_t>(bit(rng));
    r.pick = {mm(rng), mm(rng), mm(rng), deg(rng), deg(rng) / 2, deg(rng)};
    r.score = unit(rng);
    r.pick_rank = static_cast<std::uint16_t>(u16(rng) % 8);
    c.software_version = static_cast<std::uint16_t>(u16(release_rng));
    c.software_patch = static_cast<std::uint16_t>(u16(release_rng));
    out.push_back(c);
  }
  return out;
}

}  // namespace

int main() {
  bool ok = true;
  for (const Case& c : cases()) ok = dump(c) && ok;
  return ok ? 0 : 1;
}

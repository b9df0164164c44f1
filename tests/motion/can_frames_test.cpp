// The CAN encoders against docs/mfcd.dbc: the DBC is parsed here and every signal is
// extracted bit by bit (the slow, obviously-right way), so the document and the code
// cannot drift apart.
#include "motion/can_frames.hpp"
#include "motion/register_map.hpp"

#include <gtest/gtest.h>
#include <linux/can/error.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <random>
#include <sstream>

using namespace mfcd::motion;

namespace {

struct DbcSignal {
  unsigned start = 0, length = 0;
  bool little_endian = true, is_signed = false;
  double factor = 1, offset = 0, min = 0, max = 0;
  std::string unit;
};
struct DbcMessage {
  std::string name;
  unsigned dlc = 0;
  std::map<std::string, DbcSignal> signals;
};

std::map<unsigned, DbcMessage> load_dbc() {
  std::ifstream in(MFC_SOURCE_DIR "/docs/mfcd.dbc");
  if (!in) throw std::runtime_error("cannot open docs/mfcd.dbc");
  // Plain sscanf parsing (std::regex trips GCC 12's -Wmaybe-uninitialized under ASan).
  std::map<unsigned, DbcMessage> out;
  DbcMessage* current = nullptr;
  std::string line;
  int line_no = 0;
  while (std::getline(in, line)) {
    ++line_no;
    const auto bad = [&] {
      return std::runtime_error("docs/mfcd.dbc line " + std::to_string(line_no) + ": bad syntax: " + line);
    };
    if (line.rfind("BO_ ", 0) == 0) {
      unsigned id = 0, dlc = 0;
      char name[64], sender[64];
      int used = 0;
      if (std::sscanf(line.c_str(), "BO_ %u %63[A-Za-z0-9_]: %u %63s%n", &id, name, &dlc, sender, &used) != 4 ||
          static_cast<std::size_t>(used) != line.size())
        throw bad();
      current = &out[id];
      current->name = name;
      current->dlc = dlc;
    } else if (line.rfind(" SG_ ", 0) == 0) {
      DbcSignal s;
      char name[64], order = 0, sign = 0;
      int used = 0;
      if (!current ||
          std::sscanf(line.c_str(), " SG_ %63s : %u|%u@%c%c (%lf,%lf) [%lf|%lf] %n", name, &s.start, &s.length, &order,
                      &sign, &s.factor, &s.offset, &s.min, &s.max, &used) != 9 ||
          (order != '0' && order != '1') || (sign != '+' && sign != '-'))
        throw bad();
      // Then "unit" and the receiver list.
      const std::string rest = line.substr(static_cast<std::size_t>(used));
      const std::size_t close = rest.find('"', 1);
      if (rest.empty() || rest[0] != '"' || close == std::string::npos || close + 2 > rest.size() ||
          rest[close + 1] != ' ')
        throw bad();
      s.unit = rest.substr(1, close - 1);
      s.little_endian = order == '1';
      s.is_signed = sign == '-';
      current->signals[name] = s;
    }
  }
  return out;
}

// Intel (little-endian) signal: bit i of the signal is bit (start + i) of the frame,
// counting bit 0 as the LSB of byte 0.
double extract(const can_frame& f, const DbcSignal& s) {
  std::uint64_t raw = 0;
  for (unsigned i = 0; i < s.length; ++i) {
    const unsigned bit = s.start + i;
    if (f.data[bit / 8] & (1u << (bit % 8))) raw |= std::uint64_t{1} << i;
  }
  double value = static_cast<double>(raw);
  if (s.is_signed && (raw >> (s.length - 1)) & 1) value -= std::ldexp(1.0, static_cast<int>(s.length));
  return value * s.factor + s.offset;
}

class CanDbc : public ::testing::Test {
 protected:
  static void SetUpTestSuite() { dbc = new std::map<unsigned, DbcMessage>(load_dbc()); }
  static void TearDownTestSuite() { delete dbc; }
  static const DbcMessage& message(const can_frame& f) {
    auto it = dbc->find(f.can_id);
    if (it == dbc->end()) throw std::runtime_error("frame id not in the DBC");
    return it->second;
  }
  static double signal(const can_frame& f, const std::string& name) {
    const DbcMessage& m = message(f);
    auto it = m.signals.find(name);
    if (it == m.signals.end()) throw std::runtime_error(m.name + " has no signal " + name);
    return extract(f, it->second);
  }
  static std::map<unsigned, DbcMessage>* dbc;
};
std::map<unsigned, DbcMessage>* CanDbc::dbc = nullptr;

RobotReport random_report(std::mt19937& rng) {
  std::uniform_real_distribution<float> mm(-2000.0f, 2000.0f), deg(-180.0f, 180.0f), unit(0.0f, 1.0f);
  std::uniform_int_distribution<int> u16(0, 65535), bit(0, 1);
  RobotReport r;
  r.job_id = static_cast<std::uint16_t>(u16(rng));
  r.recipe_id = static_cast<std::uint16_t>(u16(rng));
  r.error_code = bit(rng) ? 0 : static_cast<std::uint16_t>(u16(rng));
  r.objects_remaining = static_cast<std::uint16_t>(u16(rng));
  r.cycle_time_ms = static_cast<std::uint16_t>(u16(rng));
  r.candidate_index = static_cast<std::uint16_t>(u16(rng) % 300);
  r.candidate_count = static_cast<std::uint16_t>(u16(rng) % 300);
  r.ready = static_cast<std::uint16_t>(bit(rng));
  r.vision_ok = static_cast<std::uint16_t>(bit(rng));
  r.pick_valid = static_cast<std::uint16_t>(bit(rng));
  r.pick = {mm(rng), mm(rng), mm(rng), deg(rng), deg(rng) / 2, deg(rng)};
  r.score = unit(rng);
  r.pick_rank = static_cast<std::uint16_t>(u16(rng) % 200);
  return r;
}

}  // namespace

TEST_F(CanDbc, DescribesEveryFrameWeSend) {
  ASSERT_EQ(dbc->size(), 6u);
  for (const auto& [id, m] : *dbc) {
    EXPECT_EQ(m.dlc, 8u) << m.name;
    for (const auto& [name, s] : m.signals) {
      EXPECT_TRUE(s.little_endian) << name;
      EXPECT_LE(s.start + s.length, 64u) << name;
    }
  }
  EXPECT_EQ(dbc->at(kCanDefaultBase + kCanStatusOffset).name, "MFCD_Status");
  EXPECT_EQ(dbc->at(kCanDefaultBase + kCanHeartbeatOffset).name, "MFCD_Heartbeat");
  EXPECT_EQ(dbc->at(kCanDefaultBase + kCanVersionOffset).name, "MFCD_Version");
  EXPECT_EQ(dbc->at(kCanDefaultBase + kCanPickAOffset).name, "MFCD_PickA");
  EXPECT_EQ(dbc->at(kCanDefaultBase + kCanPickBOffset).name, "MFCD_PickB");
  EXPECT_EQ(dbc->at(kCanDefaultBase + kCanPickCOffset).name, "MFCD_PickC");
}

TEST_F(CanDbc, StatusAndHeartbeatMatchTheDbc) {
  std::mt19937 rng(11);
  for (int i = 0; i < 2000; ++i) {
    const RobotReport r = random_report(rng);
    const can_frame s = encode_status(r, kCanDefaultBase);
    ASSERT_EQ(signal(s, "StatusReady"), (r.ready && r.error_code == 0) ? 1 : 0);
    ASSERT_EQ(signal(s, "StatusError"), r.error_code != 0 ? 1 : 0);
    ASSERT_EQ(signal(s, "StatusPickValid"), r.pick_valid ? 1 : 0);
    ASSERT_EQ(signal(s, "StatusVisionOk"), r.vision_ok ? 1 : 0);
    // The Modbus BUSY/DONE bits and bits 6..15 are reserved on CAN: always 0, so the four
    // flags at their Modbus bit positions are the whole status word the publisher tracks.
    ASSERT_EQ(signal(s, "StatusReserved1_2"), 0);
    ASSERT_EQ(signal(s, "StatusReserved6_15"), 0);
    const auto bit = [&](const char* name, unsigned mask) { return signal(s, name) != 0 ? mask : 0u; };
    ASSERT_EQ(bit("StatusReady", reg::kReady) | bit("StatusError", reg::kError) |
                  bit("StatusPickValid", reg::kPickValid) | bit("StatusVisionOk", reg::kVisionOk),
              can_status_word(r));
    ASSERT_EQ(signal(s, "JobIdEcho"), r.job_id);
    ASSERT_EQ(signal(s, "ErrorCode"), r.error_code);
    ASSERT_EQ(signal(s, "ObjectsRemaining"), r.objects_remaining);
    const can_frame h = encode_heartbeat(static_cast<std::uint16_t>(i * 7), r, kCanDefaultBase);
    ASSERT_EQ(signal(h, "Heartbeat"), static_cast<std::uint16_t>(i * 7));
    ASSERT_EQ(signal(h, "CycleTime"), r.cycle_time_ms);
    ASSERT_EQ(signal(h, "RecipeEcho"), r.recipe_id);
    ASSERT_EQ(signal(h, "CandidateCount"), std::min<int>(r.candidate_count, 255));
    ASSERT_EQ(signal(h, "MapVersion"), reg::kMapVersion) << "the heartbeat names the Modbus register map version";
  }
}

TEST_F(CanDbc, VersionFrameMatchesTheDbc) {
  // Release 1.2.772 (as the Modbus registers 53..54 hold it: 0x0102, 0x0304), byte by byte:
  // major, minor, patch little-endian, register map version, DBC version, two reserved bytes.
  const can_frame f = encode_version(0x0102, 0x0304, kCanDefaultBase);
  EXPECT_EQ(f.can_id, kCanDefaultBase + kCanVersionOffset);
  ASSERT_EQ(f.len, 8u);
  EXPECT_EQ(f.data[0], 0x01) << "SoftwareMajor";
  EXPECT_EQ(f.data[1], 0x02) << "SoftwareMinor";
  EXPECT_EQ(f.data[2], 0x04) << "SoftwarePatch, low byte";
  EXPECT_EQ(f.data[3], 0x03) << "SoftwarePatch, high byte";
  EXPECT_EQ(f.data[4], reg::kMapVersion) << "RegisterMapVersion";
  EXPECT_EQ(f.data[5], kCanDbcVersion) << "DbcVersion";
  EXPECT_EQ(f.data[6], 0) << "VersionReserved48_63";
  EXPECT_EQ(f.data[7], 0) << "VersionReserved48_63";

  std::mt19937 rng(13);
  std::uniform_int_distribution<int> u16(0, 65535);
  for (int i = 0; i < 2000; ++i) {
    const auto version = static_cast<std::uint16_t>(i < 2 ? i * 0xffff : u16(rng));
    const auto patch = static_cast<std::uint16_t>(i < 2 ? i * 0xffff : u16(rng));
    const can_frame v = encode_version(version, patch, kCanDefaultBase);
    ASSERT_EQ(signal(v, "SoftwareMajor"), version >> 8);
    ASSERT_EQ(signal(v, "SoftwareMinor"), version & 0xff);
    ASSERT_EQ(signal(v, "SoftwarePatch"), patch);
    ASSERT_EQ(signal(v, "RegisterMapVersion"), reg::kMapVersion);
    ASSERT_EQ(signal(v, "DbcVersion"), kCanDbcVersion);
    ASSERT_EQ(signal(v, "VersionReserved48_63"), 0);
    const auto d = decode_version(v, kCanDefaultBase);
    ASSERT_TRUE(d);
    ASSERT_EQ(d->major, version >> 8);
    ASSERT_EQ(d->minor, version & 0xff);
    ASSERT_EQ(d->patch, patch);
    ASSERT_EQ(d->map_version, reg::kMapVersion);
    ASSERT_EQ(d->dbc_version, kCanDbcVersion);
  }
}

TEST(CanFrames, DbcVersionIsTheDbcFilesVersion) {
  std::ifstream in(MFC_SOURCE_DIR "/docs/mfcd.dbc");
  std::string line;
  ASSERT_TRUE(std::getline(in, line));
  unsigned n = 0;
  int used = 0;
  ASSERT_EQ(std::sscanf(line.c_str(), "VERSION \"mfcd robot link %u\"%n", &n, &used), 1) << line;
  ASSERT_EQ(static_cast<std::size_t>(used), line.size()) << line;
  EXPECT_EQ(n, kCanDbcVersion) << "kCanDbcVersion (can_frames.hpp) is sent as DbcVersion: raise both together";
}

TEST(CanFrames, DecodeVersionChecksIdAndLength) {
  can_frame f = encode_version(0x0a0b, 12, kCanDefaultBase);
  EXPECT_FALSE(decode_version(f, kCanDefaultBase + 1)) << "wrong id";
  f.len = 7;
  EXPECT_FALSE(decode_version(f, kCanDefaultBase)) << "short frame";
  f.len = 8;
  const auto d = decode_version(f, kCanDefaultBase);
  ASSERT_TRUE(d);
  EXPECT_EQ(d->major, 10);
  EXPECT_EQ(d->minor, 11);
  EXPECT_EQ(d->patch, 12);
}

TEST_F(CanDbc, PickFramesMatchTheDbc) {
  std::mt19937 rng(12);
  for (int i = 0; i < 5000; ++i) {
    const RobotReport r = random_report(rng);
    const auto seq = static_cast<std::uint8_t>(i);
    const auto frames = encode_pick(r, seq, kCanDefaultBase);
    ASSERT_TRUE(frames);
    const auto& [a, b, c] = *frames;
    ASSERT_EQ(signal(a, "PickSeqA"), seq);
    ASSERT_EQ(signal(b, "PickSeqB"), seq);
    ASSERT_EQ(signal(c, "PickSeqC"), seq);
    // Quantisation: half a step of the signal's factor.
    ASSERT_NEAR(signal(a, "PickX"), r.pick.x_mm, 0.005 + 1e-4);
    ASSERT_NEAR(signal(a, "PickY"), r.pick.y_mm, 0.005 + 1e-4);
    ASSERT_NEAR(signal(b, "PickZ"), r.pick.z_mm, 0.005 + 1e-4);
    ASSERT_NEAR(signal(b, "PickRx"), r.pick.rx_deg, 0.005 + 1e-4);
    ASSERT_NEAR(signal(b, "PickRy"), r.pick.ry_deg, 0.005 + 1e-4);
    ASSERT_NEAR(signal(c, "PickRz"), r.pick.rz_deg, 0.005 + 1e-4);
    ASSERT_NEAR(signal(c, "PickScore"), r.score, 0.00005 + 1e-6);
    ASSERT_EQ(signal(c, "PickJobId"), r.job_id);
    ASSERT_EQ(signal(c, "PickValid"), r.pick_valid ? 1 : 0);
    ASSERT_EQ(signal(c, "PickRank"), std::min<int>(r.pick_rank, 127));
    ASSERT_EQ(signal(a, "CandidateIndex"), std::min<int>(r.candidate_index, 255));
    // And the library's own decoder agrees with the DBC reading.
    const auto p = decode_pick(*frames, kCanDefaultBase);
    ASSERT_TRUE(p);
    ASSERT_NEAR(p->pose.x_mm, signal(a, "PickX"), 1e-3);
    ASSERT_NEAR(p->pose.rz_deg, signal(c, "PickRz"), 1e-4);
    ASSERT_EQ(p->job_id, r.job_id);
    ASSERT_EQ(p->rank, std::min<int>(r.pick_rank, 127));
  }
}

TEST(CanFrames, OutOfRangePickIsNotSent) {
  RobotReport r;
  r.pick.x_mm = 90000.0f;
  EXPECT_FALSE(encode_pick(r, 0, kCanDefaultBase));
  r.pick.x_mm = 83886.07f;
  EXPECT_TRUE(encode_pick(r, 0, kCanDefaultBase));
  r.pick.rz_deg = 400.0f;
  EXPECT_FALSE(encode_pick(r, 0, kCanDefaultBase));
  r.pick.rz_deg = std::nanf("");
  EXPECT_FALSE(encode_pick(r, 0, kCanDefaultBase));
}

TEST(CanFrames, DecodeRejectsMixedSequences) {
  RobotReport r;
  r.pick = {1, 2, 3, 4, 5, 6};
  auto first = *encode_pick(r, 7, kCanDefaultBase);
  const auto second = *encode_pick(r, 8, kCanDefaultBase);
  first[2] = second[2];
  EXPECT_FALSE(decode_pick(first, kCanDefaultBase));
  EXPECT_FALSE(decode_pick(second, kCanDefaultBase + 1)) << "wrong ids";
  EXPECT_TRUE(decode_pick(second, kCanDefaultBase));
}

TEST(CanFrames, IdBaseMovesAllFrames) {
  RobotReport r;
  EXPECT_EQ(encode_status(r, 0x300).can_id, 0x300u);
  EXPECT_EQ(encode_heartbeat(0, r, 0x300).can_id, 0x301u);
  EXPECT_EQ(encode_version(0, 0, 0x300).can_id, 0x302u);
  EXPECT_EQ((*encode_pick(r, 0, 0x300))[2].can_id, 0x312u);
}

TEST(CanFrames, ErrorFrameClassification) {
  can_frame f{};
  f.can_id = CAN_ERR_FLAG | CAN_ERR_BUSOFF;
  EXPECT_EQ(classify_error_frame(f), CanErrorKind::BusOff);
  f.can_id = CAN_ERR_FLAG | CAN_ERR_RESTARTED;
  EXPECT_EQ(classify_error_frame(f), CanErrorKind::Restarted);
  f.can_id = CAN_ERR_FLAG | CAN_ERR_CRTL;
  f.data[1] = CAN_ERR_CRTL_TX_PASSIVE;
  EXPECT_EQ(classify_error_frame(f), CanErrorKind::ErrorPassive);
  f.data[1] = CAN_ERR_CRTL_RX_OVERFLOW;
  EXPECT_EQ(classify_error_frame(f), CanErrorKind::Other);
  f.can_id = CAN_ERR_BUSOFF;  // not an error frame: a data frame with that id
  EXPECT_EQ(classify_error_frame(f), CanErrorKind::Other);
}

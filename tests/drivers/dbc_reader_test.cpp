// The DBC reader (drivers/imu/dbc_database.hpp, dbc_codec.hpp; issue #27 item 1) against a DBC
// reader nobody here wrote: canmatrix (Debian python3-canmatrix) decodes the same random frames of
// the same file (Intel and Motorola signals of odd lengths, signed and unsigned, a 42-bit field,
// 29-bit identifiers, a multiplexed message, IEEE float signals, CAN FD lengths up to 64 bytes)
// and must find the same raw values for the same signals. Expected properties of the file come
// from its text. Bad DBC input is refused naming the file and line.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <cstring>
#include <fstream>
#include <map>
#include <random>
#include <set>
#include <sstream>
#include <string>

#include "drivers/imu/dbc_codec.hpp"
#include "drivers/imu/dbc_database.hpp"
#include "tests/support/run_command.hpp"

namespace imucal::drivers::imu {
namespace {

const std::string kCases = std::string(IMUCAL_SOURCE_DIR) + "/tests/data/dbc/reader_cases.dbc";

std::pair<int, std::string> run_dbc_reader(const std::string& cmd) {
  const test_support::CommandResult r = test_support::run_command(cmd);
  return {r.code, r.out};
}

TEST(DbcReader, ReadsMessagesAndSignalsAsTheFileStatesThem) {
  const DbcDatabase db = read_dbc(kCases);
  EXPECT_EQ(db.version, "imucal dbc reader cases");
  EXPECT_EQ(db.nodes, (std::vector<std::string>{"IMU", "STATION"}));
  ASSERT_EQ(db.messages.size(), 5u);
  const DbcMessage* ext = db.message("MOTOROLA_EXT");
  ASSERT_NE(ext, nullptr);
  EXPECT_TRUE(ext->extended);
  EXPECT_EQ(ext->id, 0x18FF1000u);  // 2566852608 with bit 31 (extended) cleared
  EXPECT_FALSE(ext->fd);
  EXPECT_EQ(db.message(0x18FF1000u, true), ext);
  EXPECT_EQ(db.message(0x18FF1000u, false), nullptr);
  const DbcSignal* rate = ext->signal("RateX");
  ASSERT_NE(rate, nullptr);
  EXPECT_EQ(rate->start_bit, 15);
  EXPECT_EQ(rate->length, 16);
  EXPECT_EQ(rate->order, DbcSignal::ByteOrder::kMotorola);
  EXPECT_TRUE(rate->is_signed);
  EXPECT_DOUBLE_EQ(rate->factor, 0.01);
  EXPECT_DOUBLE_EQ(rate->minimum, -327.68);
  EXPECT_EQ(rate->unit, "deg/s");
  const DbcSignal* odd = db.message("INTEL_MIX")->signal("SignedOdd");
  EXPECT_DOUBLE_EQ(odd->offset, -2.0);
  EXPECT_EQ(odd->order, DbcSignal::ByteOrder::kIntel);
  const DbcMessage* mux = db.message("MUX_STATUS");
  ASSERT_NE(mux->multiplexor(), nullptr);
  EXPECT_EQ(mux->multiplexor()->name, "Page");
  EXPECT_EQ(*mux->signal("Temperature")->multiplex_value, 1);
  EXPECT_EQ(mux->signal("Page")->value_names.at(1), "temperature");
  const DbcMessage* floats = db.message("FLOATS");
  EXPECT_TRUE(floats->fd);  // 12 bytes, and VFrameFormat StandardCAN_FD
  EXPECT_EQ(floats->length, 12);
  EXPECT_EQ(floats->signal("SpecificForce")->type, DbcSignal::ValueType::kFloat32);
  EXPECT_EQ(floats->signal("Rate")->type, DbcSignal::ValueType::kFloat64);
  const DbcMessage* fd = db.message("FD_LONG");
  EXPECT_TRUE(fd->extended);
  EXPECT_EQ(fd->id, 0x201u);
  EXPECT_EQ(fd->length, 64);
}

// A Motorola signal walks from its most significant bit down its byte, then on from bit 7 of the
// next byte: RateX (start 15, 16 bits) is byte 1 then byte 2, most significant first.
TEST(DbcReader, MotorolaAndIntelFieldsSitWhereTheFormatSays) {
  const DbcDatabase db = read_dbc(kCases);
  const DbcSignal& rate = *db.message("MOTOROLA_EXT")->signal("RateX");
  uint8_t data[8] = {0, 0x12, 0x34, 0, 0, 0, 0, 0};
  EXPECT_EQ(dbc_extract_raw(rate, data, 8), 0x1234u);
  data[1] = 0xFF;
  data[2] = 0x38;  // 0xFF38 = -200 as 16-bit two's complement
  EXPECT_DOUBLE_EQ(dbc_physical(rate, dbc_extract_raw(rate, data, 8)), -2.0);
  const DbcSignal& odd = *db.message("INTEL_MIX")->signal("SignedOdd");
  uint8_t intel[8] = {0, 0x01, 0x10, 0, 0, 0, 0, 0};  // bits 8 and 20: the lowest and the sign bit
  EXPECT_EQ(dbc_extract_raw(odd, intel, 8), 0x1001u);
  EXPECT_EQ(dbc_raw_integer(odd, 0x1001u), 1 - 4096);
  EXPECT_DOUBLE_EQ(dbc_physical(odd, 0x1001u), 0.5 * (1 - 4096) - 2.0);
}

TEST(DbcReader, InsertThenExtractGivesTheValueBackAndLeavesTheOtherBits) {
  const DbcDatabase db = read_dbc(kCases);
  std::mt19937_64 rng(3);
  for (const DbcMessage& m : db.messages)
    for (const DbcSignal& s : m.signals)
      for (int k = 0; k < 50; ++k) {
        std::vector<uint8_t> data(static_cast<size_t>(m.length));
        for (auto& b : data) b = static_cast<uint8_t>(rng());
        const std::vector<uint8_t> before = data;
        const uint64_t mask = s.length == 64 ? ~uint64_t{0} : (uint64_t{1} << s.length) - 1;
        const uint64_t v = rng() & mask;
        dbc_insert_raw(s, v, data.data(), data.size());
        EXPECT_EQ(dbc_extract_raw(s, data.data(), data.size()), v) << s.name;
        std::set<int> mine;
        for (int b : dbc_signal_bits(s)) mine.insert(b);
        for (int b = 0; b < 8 * m.length; ++b) {
          if (mine.count(b)) continue;
          EXPECT_EQ((data[b / 8] >> (b % 8)) & 1, (before[b / 8] >> (b % 8)) & 1)
              << s.name << " touched bit " << b;
        }
      }
}

/// The signals a frame carries: all but the multiplexed ones whose value the multiplexor lacks.
std::map<std::string, std::string> decode_ours_dbc_reader(const DbcMessage& m, const uint8_t* data) {
  std::map<std::string, std::string> out;
  const DbcSignal* mux = m.multiplexor();
  const int64_t page =
      mux ? dbc_raw_integer(*mux, dbc_extract_raw(*mux, data, static_cast<size_t>(m.length))) : 0;
  for (const DbcSignal& s : m.signals) {
    if (s.multiplex_value && *s.multiplex_value != page) continue;
    const uint64_t raw = dbc_extract_raw(s, data, static_cast<size_t>(m.length));
    char text[64];
    if (s.type == DbcSignal::ValueType::kInteger)
      std::snprintf(text, sizeof text, "%lld", static_cast<long long>(dbc_raw_integer(s, raw)));
    else
      std::snprintf(text, sizeof text, "%.17g", dbc_physical(s, raw));
    out[s.name] = text;
  }
  return out;
}

TEST(DbcReader, DecodesRandomFramesAsCanmatrixDoes) {
  const std::string py = "/usr/bin/python3";
  ASSERT_EQ(run_dbc_reader(py + " -c 'import canmatrix.formats' >/dev/null 2>&1; echo $?").second, "0\n")
      << "required tool missing: install the Debian package python3-canmatrix";
  const DbcDatabase db = read_dbc(kCases);
  std::mt19937_64 rng(11);
  struct Sent {
    const DbcMessage* m;
    std::vector<uint8_t> data;
  };
  std::vector<Sent> frames;
  for (int k = 0; k < 400; ++k) {
    const DbcMessage& m = db.messages[static_cast<size_t>(k) % db.messages.size()];
    Sent f{&m, std::vector<uint8_t>(static_cast<size_t>(m.length))};
    for (auto& b : f.data) b = static_cast<uint8_t>(rng());
    if (m.multiplexor()) dbc_insert_raw(*m.multiplexor(), rng() % 4, f.data.data(), f.data.size());
    if (m.name == "FLOATS") {  // finite floats (a NaN's payload is not a decoding question)
      const float sf = static_cast<float>(static_cast<int>(rng() % 20001) - 10000) / 97.0F;
      const double r = static_cast<double>(static_cast<int>(rng() % 20001) - 10000) / 3.0;
      std::memcpy(f.data.data(), &sf, 4);
      std::memcpy(f.data.data() + 4, &r, 8);
    }
    frames.push_back(std::move(f));
  }
  const std::string path = "/tmp/imucal-dbc-frames-" + std::to_string(::getpid()) + ".txt";
  {
    std::ofstream out(path);
    for (const Sent& f : frames) {
      char id[16];
      std::snprintf(id, sizeof id, f.m->extended ? "%08X " : "%03X ", f.m->id);
      out << id;
      for (uint8_t b : f.data) {
        char h[4];
        std::snprintf(h, sizeof h, "%02X", b);
        out << h;
      }
      out << '\n';
    }
  }
  const std::string script =
      std::string(IMUCAL_SOURCE_DIR) + "/tests/drivers/python/dbc_decode_frames.py";
  const auto [rc, out] = run_dbc_reader(py + " " + script + " " + kCases + " " + path + " 2>/dev/null");
  ::unlink(path.c_str());
  ASSERT_EQ(rc, 0) << out;
  std::vector<std::map<std::string, std::string>> theirs(frames.size());
  std::istringstream in(out);
  size_t index;
  std::string name, value;
  while (in >> index >> name >> value) theirs.at(index)[name] = value;
  int compared = 0;
  for (size_t i = 0; i < frames.size(); ++i) {
    const auto ours = decode_ours_dbc_reader(*frames[i].m, frames[i].data.data());
    EXPECT_EQ(ours, theirs[i]) << "frame " << i << " (" << frames[i].m->name << ")";
    compared += static_cast<int>(ours.size());
  }
  EXPECT_GT(compared, 1400);  // 400 frames of 2-5 signals each: nothing was skipped
}

void expect_refused(const std::string& dbc, int line, const std::string& what) {
  try {
    parse_dbc(dbc, "bad.dbc");
    ADD_FAILURE() << "accepted: " << what;
  } catch (const std::invalid_argument& e) {
    const std::string msg = e.what();
    EXPECT_EQ(msg.rfind("bad.dbc:" + std::to_string(line) + ": ", 0), 0u) << msg;
    EXPECT_NE(msg.find(what), std::string::npos) << msg;
  }
}

TEST(DbcReader, BadInputIsRefusedNamingTheFileAndLine) {
  const std::string head = "VERSION \"\"\nBU_: A\n";  // lines 1-2
  expect_refused(
      head +
          "BO_ 1 M: 8 A\n SG_ a : 0|8@1+ (1,0) [0|0] \"\" A\n SG_ b : 4|8@1+ (1,0) [0|0] \"\" A\n",
      5, "signal b overlaps signal a (line 4) at bit 4");
  expect_refused(head + "BO_ 1 M: 8 A\n SG_ a : 60|8@1+ (1,0) [0|0] \"\" A\n", 4,
                 "reaches beyond the 8 bytes");
  expect_refused(head + "BO_ 1 M: 8 A\n SG_ a : 0|8@1+ (0,0) [0|0] \"\" A\n", 4, "factor 0");
  expect_refused(head + "BO_ 1 M: 8 A\nBO_ 1 N: 8 A\n", 4, "identifier 1 is already message M");
  expect_refused(head + "BO_ 1 M: 9 A\n", 3, "length 9 is no CAN length");
  expect_refused(head + "BO_ 2048 M: 8 A\n", 3, "does not fit 11 bits");
  expect_refused(head + "BO_ 1 M: 8 A\n SG_ a : 0|0@1+ (1,0) [0|0] \"\" A\n", 4, "length 0");
  expect_refused(head + "BO_ 1 M: 8 A\n SG_ a : 0|8@2+ (1,0) [0|0] \"\" A\n", 4, "byte order 2");
  expect_refused(head + " SG_ a : 0|8@1+ (1,0) [0|0] \"\" A\n", 3, "SG_ before any BO_");
  expect_refused(head + "BO_ 1 M: 8 A\n SG_ a : 0|8@1+ (1,0 [0|0] \"\" A\n", 4, "expected ')'");
  expect_refused(head + "CM_ \"never closed;\n\n", 3, "quoted string is not closed");
  expect_refused(head + "CM_ BO_ 1 \"no semicolon\"\n", 3, "no closing ';'");
  expect_refused(head + "FOO_ 1;\n", 3, "unknown statement 'FOO_'");
  expect_refused(head + "BO_ 1 M: 8 A\n SG_ a m1 : 0|8@1+ (1,0) [0|0] \"\" A\n", 4,
                 "has no multiplexor");
  expect_refused(head +
                     "BO_ 1 M: 8 A\n SG_ s M : 0|4@1+ (1,0) [0|0] \"\" A\n SG_ a m1M : 4|4@1+ "
                     "(1,0) [0|0] \"\" A\n",
                 5, "extended multiplexing");
  expect_refused(
      head + "BO_ 1 M: 8 A\n SG_ a : 0|16@1- (1,0) [0|0] \"\" A\nSIG_VALTYPE_ 1 a : 1;\n", 5,
      "32-bit float but 16 bits long");
  expect_refused(
      head +
          "BO_ 1 M: 8 A\n SG_ a : 0|8@1+ (1,0) [0|0] \"\" A\n SG_ a : 8|8@1+ (1,0) [0|0] \"\" A\n",
      5, "signal a is defined twice");
  // Multiplexed signals may share bits when their multiplexor values differ.
  EXPECT_NO_THROW(parse_dbc(head + "BO_ 1 M: 8 A\n SG_ s M : 0|4@1+ (1,0) [0|0] \"\" A\n"
                                   " SG_ a m0 : 8|8@1+ (1,0) [0|0] \"\" A\n"
                                   " SG_ b m1 : 8|8@1+ (1,0) [0|0] \"\" A\n",
                            "ok.dbc"));
  try {
    read_dbc("/nonexistent/imu.dbc");
    ADD_FAILURE();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/imu.dbc: cannot read"), std::string::npos);
  }
}

// The shipped protocol's DBC reads with this reader too (issue #27: it becomes a protocol file).
TEST(DbcReader, TheShippedImuDbcReads) {
  const DbcDatabase db = read_dbc(std::string(IMUCAL_SOURCE_DIR) + "/drivers/imu/imu.dbc");
  ASSERT_EQ(db.messages.size(), 4u);
  EXPECT_EQ(db.message("IMU_STATUS")->id, 0x103u);
  EXPECT_EQ(db.message("IMU_AXIS_X")->signal("DeltaThetaX")->length, 30);
  EXPECT_EQ(db.message("IMU_STATUS")->signal("Temperature")->value_names.at(-32768), "unknown");
}

}  // namespace
}  // namespace imucal::drivers::imu

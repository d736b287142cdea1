#include "mosaicloc/io/registers.hpp"

#include <cstdint>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "mosaicloc/io/plc_link.hpp"

namespace mosaicloc::io {
namespace {

TEST(RegisterMapTest, DefaultIsTheDesignMap) {
  const RegisterMap map;
  std::string why;
  ASSERT_TRUE(map.Check(&why)) << why;
  EXPECT_EQ(map.left_ticks.address, 0);
  EXPECT_EQ(map.right_ticks.address, 2);
  EXPECT_EQ(map.fix_request.address, 5);
  EXPECT_EQ(map.fix_x.address, 100);
  EXPECT_EQ(map.heartbeat.address, 109);
  EXPECT_EQ(map.fix_x.Describe(), "fix_x (registers 100-101)");
}

TEST(RegisterMapTest, RejectsOverlapsWidthsScalesAndAddresses) {
  std::string why;
  RegisterMap overlap;
  overlap.fix_y.address = 101;
  EXPECT_FALSE(overlap.Check(&why));
  EXPECT_EQ(why, "fix_x (registers 100-101) overlaps fix_y (registers 101-102)");

  RegisterMap width;
  width.fix_status.width_bits = 8;
  EXPECT_FALSE(width.Check(&why));
  EXPECT_EQ(why, "fix_status: width_bits must be 16 or 32, not 8");

  RegisterMap scale;
  scale.fix_request.scale = 2.0;
  EXPECT_FALSE(scale.Check(&why));
  EXPECT_EQ(why, "fix_request: scale must be 1 (it is a plain integer)");

  RegisterMap address;
  address.heartbeat.address = 65535;
  address.heartbeat.width_bits = 32;
  EXPECT_FALSE(address.Check(&why));
  EXPECT_NE(why.find("heartbeat: address 65535"), std::string::npos) << why;
}

// Only the kind's counters are read and checked: a tricycle's drive and steering registers
// may sit where a differential drive's left and right would.
TEST(RegisterMapTest, ATricycleHasItsOwnCounters) {
  RegisterMap map;
  map.kind = core::DriveKind::kTricycle;
  std::string why;
  EXPECT_TRUE(map.Check(&why)) << why;
  ASSERT_EQ(map.Inputs().size(), 5U);
  EXPECT_EQ(map.Inputs()[0]->name, "drive_ticks");
  EXPECT_EQ(map.Inputs()[1]->name, "steering_ticks");
  const core::EncoderCounts counts{1, 2, 3, -4};
  EXPECT_EQ(map.CounterValues(counts), (std::vector<std::int32_t>{3, -4}));
  map.steering_ticks.address = 4;  // onto plc_heartbeat
  EXPECT_FALSE(map.Check(&why));
  EXPECT_NE(why.find("steering_ticks"), std::string::npos) << why;
  map.kind = core::DriveKind::kDifferential;  // then the steering register is not read
  EXPECT_TRUE(map.Check(&why)) << why;
  EXPECT_EQ(map.CounterValues(counts), (std::vector<std::int32_t>{1, 2}));
}

// A mecanum vehicle's four counters: the front wheels where a differential drive's are, the
// rear ones after the PLC's request registers.
TEST(RegisterMapTest, AMecanumVehicleHasFourCounters) {
  RegisterMap map;
  map.kind = core::DriveKind::kMecanum;
  std::string why;
  EXPECT_TRUE(map.Check(&why)) << why;
  ASSERT_EQ(map.Inputs().size(), 7U);
  EXPECT_EQ(map.Inputs()[0]->Describe(), "front_left_ticks (registers 0-1)");
  EXPECT_EQ(map.Inputs()[1]->Describe(), "front_right_ticks (registers 2-3)");
  EXPECT_EQ(map.Inputs()[2]->Describe(), "rear_left_ticks (registers 8-9)");
  EXPECT_EQ(map.Inputs()[3]->Describe(), "rear_right_ticks (registers 10-11)");
  const core::EncoderCounts counts{1, 2, 3, 4, -5, 6};
  EXPECT_EQ(map.CounterValues(counts), (std::vector<std::int32_t>{1, 2, -5, 6}));
  map.rear_right_ticks.address = 5;  // onto fix_request
  EXPECT_FALSE(map.Check(&why));
  EXPECT_NE(why.find("rear_right_ticks"), std::string::npos) << why;
  // Their reading groups into one request over registers 0-11.
  const std::vector<RegisterSpan> spans = GroupIntoSpans(RegisterMap{.kind = core::DriveKind::kMecanum}.Inputs(), 8);
  ASSERT_EQ(spans.size(), 1U);
  EXPECT_EQ(spans[0].address, 0);
  EXPECT_EQ(spans[0].count, 12);
}

TEST(RegisterCodecTest, BothWordOrdersRoundTripAndMatchTheWire) {
  RegisterField field{"x", 0, 32, true, 1.0, WordOrder::kHighFirst};
  std::uint16_t words[2] = {};
  ASSERT_TRUE(EncodeCount(field, -2, words));
  EXPECT_EQ(words[0], 0xFFFF);
  EXPECT_EQ(words[1], 0xFFFE);
  EXPECT_EQ(DecodeCount(field, words), -2);

  ASSERT_TRUE(EncodeCount(field, 0x12345678, words));
  EXPECT_EQ(words[0], 0x1234);
  EXPECT_EQ(words[1], 0x5678);
  field.word_order = WordOrder::kLowFirst;
  ASSERT_TRUE(EncodeCount(field, 0x12345678, words));
  EXPECT_EQ(words[0], 0x5678);
  EXPECT_EQ(words[1], 0x1234);
  EXPECT_EQ(DecodeCount(field, words), 0x12345678);
}

TEST(RegisterCodecTest, HighBitIsNotSignExtendedIntoUnsignedValues) {
  // MODBUS_GET_INT32_FROM_INT16 shifts a signed int; ours must not.
  EXPECT_EQ(JoinWords(0x8000, 0x0001), 0x80000001U);
  const RegisterField unsigned32{"u", 0, 32, false, 1.0};
  const std::uint16_t words[2] = {0xFFFF, 0xFFFF};
  EXPECT_EQ(DecodeCount(unsigned32, words), 4294967295LL);
  const RegisterField signed16{"s", 0, 16, true, 1.0};
  EXPECT_EQ(DecodeCount(signed16, words), -1);
  const RegisterField unsigned16{"u", 0, 16, false, 1.0};
  EXPECT_EQ(DecodeCount(unsigned16, words), 65535);
}

TEST(RegisterCodecTest, OutOfRangeIsClampedAndReported) {
  const RegisterField field{"x", 0, 16, true, 1.0};
  std::uint16_t word = 0;
  EXPECT_FALSE(EncodeCount(field, 40000, &word));
  EXPECT_EQ(DecodeCount(field, &word), 32767);
  EXPECT_FALSE(EncodeCount(field, -40000, &word));
  EXPECT_EQ(DecodeCount(field, &word), -32768);
}

TEST(RegisterCodecTest, OutputsUseTheScales) {
  const RegisterMap map;
  PlcOutputs outputs;
  outputs.x_mm = 1234.567;
  outputs.y_mm = -0.015;
  outputs.yaw_rad = -3.1415926;
  outputs.status = 1;
  outputs.quality = 987;
  outputs.request_echo = 70000;  // wraps like a 16-bit PLC counter
  outputs.heartbeat = 65536 + 9;
  outputs.mode = 2;
  std::uint16_t words[11] = {};  // registers 100-110
  ASSERT_TRUE(EncodeOutputs(map, outputs, 100, words));
  EXPECT_EQ(DecodeCount(map.fix_x, words + 0), 123457);
  EXPECT_EQ(DecodeCount(map.fix_y, words + 2), -2);  // -1.5 counts rounds away from zero
  EXPECT_EQ(DecodeCount(map.fix_yaw, words + 4), -3141593);
  EXPECT_EQ(words[6], 1);
  EXPECT_EQ(words[7], 987);
  EXPECT_EQ(words[8], 70000 - 65536);
  EXPECT_EQ(words[9], 9);
  EXPECT_EQ(words[10], 2);

  outputs.x_mm = 3.0e7;  // 30 km does not fit 0.01 mm in int32
  EXPECT_FALSE(EncodeOutputs(map, outputs, 100, words));
  EXPECT_EQ(DecodeCount(map.fix_x, words), 2147483647);
}

TEST(RegisterSpanTest, GroupsNeighboursAndNamesThem) {
  const RegisterMap map;
  const auto reads = GroupIntoSpans(map.Inputs(), 8);
  ASSERT_EQ(reads.size(), 1U);
  EXPECT_EQ(reads[0].address, 0);
  EXPECT_EQ(reads[0].count, 7);
  EXPECT_EQ(reads[0].Describe(),
            "holding registers 0-6 (left_ticks, right_ticks, plc_heartbeat, fix_request, relocalize_request)");

  RegisterMap apart;
  apart.fix_request.address = 40;
  apart.relocalize_request.address = 41;
  const auto split = GroupIntoSpans(apart.Inputs(), 8);
  ASSERT_EQ(split.size(), 2U);
  EXPECT_EQ(split[1].Describe(), "holding registers 40-41 (fix_request, relocalize_request)");
  // Writes never cover a gap: a register between two fields belongs to somebody else.
  RegisterMap gap;
  gap.heartbeat.address = 111;
  EXPECT_EQ(GroupIntoSpans(gap.Outputs(), 0).size(), 2U);
}

TEST(CounterUnwrapperTest, SixteenBitCountersContinueThroughTheWrap) {
  CounterUnwrapper unwrap(16);
  EXPECT_EQ(unwrap.Update(65530), 65530);
  EXPECT_EQ(unwrap.Update(4), 65540);      // forward through the wrap
  EXPECT_EQ(unwrap.Update(65534), 65534);  // and back
  EXPECT_EQ(unwrap.Update(40000), 40000);
  EXPECT_EQ(unwrap.Update(7000), 72536);  // a step of more than half the range is taken forward
  unwrap.Reset();
  EXPECT_EQ(unwrap.Update(7), 7);
}

TEST(HeartbeatMonitorTest, StaleWhenFrozenFreshWhenMoving) {
  using core::Timestamp;
  HeartbeatMonitor monitor(std::chrono::milliseconds(500));
  const auto at = [](int ms) { return Timestamp::FromNanoseconds(std::int64_t{ms} * 1'000'000); };
  EXPECT_TRUE(monitor.stale(at(0)));  // never seen
  EXPECT_FALSE(monitor.Update(at(0), 1));
  EXPECT_FALSE(monitor.Update(at(400), 1));
  EXPECT_TRUE(monitor.Update(at(600), 1));
  EXPECT_FALSE(monitor.Update(at(610), 2));
  HeartbeatMonitor disabled(core::Duration::zero());
  EXPECT_FALSE(disabled.Update(at(0), 1));
  EXPECT_FALSE(disabled.stale(at(100000)));
}

}  // namespace
}  // namespace mosaicloc::io

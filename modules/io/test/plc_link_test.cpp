// The PLC link against real Modbus peers on loopback: a plain libmodbus server standing in
// for the PLC (client role), and a plain libmodbus client standing in for a PLC that writes
// (server role). The independent peers (pymodbus, mbpoll) are in tests/plc.

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/select.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <mutex>
#include <thread>
#include <vector>

#include <gtest/gtest.h>
#include <modbus/modbus.h>

#include "mosaicloc/io/plc_link.hpp"
#include "mosaicloc/test/test_support.hpp"

namespace mosaicloc::io {
namespace {

using namespace std::chrono_literals;

// A free TCP port on loopback (the kernel's choice).

// A PLC: a libmodbus TCP server with 200 holding registers, answering in a thread,
// optionally late.
class TestPlc {
 public:
  explicit TestPlc(int port) : context_(modbus_new_tcp("127.0.0.1", port)), mapping_(modbus_mapping_new(0, 0, 200, 0)) {
    listen_ = modbus_tcp_listen(context_, 4);
    EXPECT_GE(listen_, 0) << modbus_strerror(errno);
    thread_ = std::thread([this] { Serve(); });
  }
  ~TestPlc() {
    stop_ = true;
    thread_.join();
    for (int s : clients_) close(s);
    close(listen_);
    modbus_set_socket(context_, -1);
    modbus_mapping_free(mapping_);
    modbus_free(context_);
  }
  void Set(int address, std::uint16_t value) {
    const std::lock_guard lock(mutex_);
    mapping_->tab_registers[address] = value;
  }
  std::uint16_t Get(int address) {
    const std::lock_guard lock(mutex_);
    return mapping_->tab_registers[address];
  }
  void DelayReplies(std::chrono::milliseconds delay) { delay_ms_ = static_cast<int>(delay.count()); }
  /// Answers with bytes that are no Modbus reply (a PLC whose firmware went wrong, a device
  /// that is not a PLC on the PLC's address).
  void GarbleReplies(bool garble) { garble_ = garble; }
  int requests() const { return requests_; }

 private:
  void Serve() {
    std::uint8_t query[MODBUS_TCP_MAX_ADU_LENGTH];
    while (!stop_) {
      fd_set readable;
      FD_ZERO(&readable);
      FD_SET(listen_, &readable);
      int highest = listen_;
      for (int s : clients_) {
        FD_SET(s, &readable);
        highest = std::max(highest, s);
      }
      timeval timeout{0, 20000};
      if (select(highest + 1, &readable, nullptr, nullptr, &timeout) <= 0) continue;
      if (FD_ISSET(listen_, &readable)) {
        int l = listen_;
        const int s = modbus_tcp_accept(context_, &l);
        if (s >= 0) clients_.push_back(s);
      }
      for (auto it = clients_.begin(); it != clients_.end();) {
        if (!FD_ISSET(*it, &readable)) {
          ++it;
          continue;
        }
        modbus_set_socket(context_, *it);
        const int n = modbus_receive(context_, query);
        if (n < 0) {
          close(*it);
          it = clients_.erase(it);
          continue;
        }
        if (n > 0) {
          ++requests_;
          if (delay_ms_ > 0) std::this_thread::sleep_for(std::chrono::milliseconds(delay_ms_));
          if (garble_) {
            // The request's transaction id, then a protocol id, length and function code no
            // reply has, and noise.
            const std::uint8_t junk[] = {query[0], query[1], 0x47, 0x45, 0x00, 0x09, 0xff, 0x83, 0x54, 0x0d, 0x0a, 0x00, 0x7f};
            [[maybe_unused]] const ssize_t sent = write(*it, junk, sizeof(junk));
            ++it;
            continue;
          }
          const std::lock_guard lock(mutex_);
          modbus_reply(context_, query, n, mapping_);
        }
        ++it;
      }
    }
  }
  modbus_t* context_;
  modbus_mapping_t* mapping_;
  int listen_ = -1;
  std::vector<int> clients_;
  std::mutex mutex_;
  std::atomic<bool> stop_{false};
  std::atomic<int> delay_ms_{0};
  std::atomic<bool> garble_{false};
  std::atomic<int> requests_{0};
  std::thread thread_;
};

PlcLinkOptions ClientOptions(int port) {
  PlcLinkOptions options;
  options.port = port;
  options.response_timeout_ms = 100.0;
  options.reconnect_min_ms = 20.0;
  options.reconnect_max_ms = 200.0;
  return options;
}

void SetTicks(TestPlc& plc, int address, std::uint32_t value, WordOrder order) {
  plc.Set(address, order == WordOrder::kHighFirst ? HighWord(value) : LowWord(value));
  plc.Set(address + 1, order == WordOrder::kHighFirst ? LowWord(value) : HighWord(value));
}

class ClientWordOrder : public testing::TestWithParam<WordOrder> {};

TEST_P(ClientWordOrder, ReadsInputsAndWritesFixesAsThePlcSeesThem) {
  const WordOrder order = GetParam();
  const int port = test::FreeLoopbackPort();
  TestPlc plc(port);
  SetTicks(plc, 0, 0xFFFFFFF0U, order);  // -16 as int32: a counter just before the wrap
  SetTicks(plc, 2, 123456789U, order);
  plc.Set(4, 77);
  plc.Set(5, 3);
  plc.Set(6, 2);
  PlcLinkOptions options = ClientOptions(port);
  for (RegisterField* field : {&options.registers.left_ticks, &options.registers.right_ticks,
                               &options.registers.fix_x, &options.registers.fix_y, &options.registers.fix_yaw}) {
    field->word_order = order;
  }
  const auto link = OpenPlcLink(options);
  const auto before = MonotonicNow();
  const auto inputs = link->Read();
  ASSERT_TRUE(inputs.ok()) << inputs.error();
  EXPECT_EQ(inputs.value().counts.left_ticks, -16);
  EXPECT_EQ(inputs.value().counts.right_ticks, 123456789);
  EXPECT_EQ(inputs.value().plc_heartbeat, 77U);
  EXPECT_EQ(inputs.value().fix_request, 3U);
  EXPECT_EQ(inputs.value().relocalize_request, 2U);
  EXPECT_GE(inputs.value().time, before);
  EXPECT_LE(inputs.value().time, MonotonicNow());

  PlcOutputs outputs{1234.56, -7.89, -0.5, 1, 950, 3, 42, 2};
  ASSERT_TRUE(link->Write(outputs).ok());
  const auto word32 = [&](int address) {
    return static_cast<std::int32_t>(order == WordOrder::kHighFirst ? JoinWords(plc.Get(address), plc.Get(address + 1))
                                                                    : JoinWords(plc.Get(address + 1), plc.Get(address)));
  };
  EXPECT_EQ(word32(100), 123456);
  EXPECT_EQ(word32(102), -789);
  EXPECT_EQ(word32(104), -500000);
  EXPECT_EQ(plc.Get(106), 1);
  EXPECT_EQ(plc.Get(107), 950);
  EXPECT_EQ(plc.Get(108), 3);
  EXPECT_EQ(plc.Get(109), 42);
  EXPECT_EQ(plc.Get(110), 2);
  EXPECT_EQ(link->stats().reads, 1);
  EXPECT_EQ(link->stats().writes, 1);
}

INSTANTIATE_TEST_SUITE_P(Orders, ClientWordOrder, testing::Values(WordOrder::kHighFirst, WordOrder::kLowFirst));

TEST(CountersChangedAt, MiddleOfTheLastCounterPeriodSinceThePreviousRead) {
  using namespace std::chrono_literals;
  const core::Timestamp t0 = core::Timestamp::FromSeconds(100.0);
  // Polls every 5 ms, counters every 10 ms: the middle between the reads.
  EXPECT_EQ(CountersChangedAt(t0, t0 + 5ms, 10ms), t0 + 2500us);
  // A poll 30 ms late: the counters changed in the 10 ms before it, not 15 ms before.
  EXPECT_EQ(CountersChangedAt(t0, t0 + 30ms, 10ms), t0 + 25ms);
  // Period unknown: the middle between the reads.
  EXPECT_EQ(CountersChangedAt(t0, t0 + 30ms, 0ms), t0 + 15ms);
}

// Reads until the PLC answers (the link reconnects after its backoff), for at most half a second.
std::optional<PlcInputs> ReadWhenAnswered(PlcLink& link) {
  for (int i = 0; i < 50; ++i) {
    if (auto r = link.Read(); r.ok()) return r.value();
    std::this_thread::sleep_for(10ms);
  }
  return std::nullopt;
}

// Served: reads until the PLC's last write has been noted (the server notes a write just
// after it has answered it), for at most half a second.
std::optional<PlcInputs> ReadWhenWritten(PlcLink& link) {
  for (int i = 0; i < 500; ++i) {
    if (auto r = link.Read(); r.ok() && r.value().fresh) return r.value();
    std::this_thread::sleep_for(1ms);
  }
  return std::nullopt;
}

TEST(PlcClientTest, NoPlcIsAFailureNotACrashAndRetriesWithBackoff) {
  const int port = test::FreeLoopbackPort();
  PlcLinkOptions options = ClientOptions(port);
  options.reconnect_min_ms = 300.0;
  options.reconnect_max_ms = 300.0;
  const auto link = OpenPlcLink(options);
  const auto first = link->Read();
  ASSERT_FALSE(first.ok());
  EXPECT_NE(first.error().find("cannot connect to Modbus TCP client of 127.0.0.1:" + std::to_string(port)),
            std::string::npos)
      << first.error();
  const auto second = link->Read();  // within the backoff: no new attempt
  ASSERT_FALSE(second.ok());
  EXPECT_NE(second.error().find("next attempt in"), std::string::npos) << second.error();
  EXPECT_EQ(link->stats().connect_failures, 1);

  // The PLC comes up: the link connects once the backoff has passed.
  TestPlc plc(port);
  plc.Set(4, 5);
  std::this_thread::sleep_for(350ms);
  const auto third = link->Read();
  ASSERT_TRUE(third.ok()) << third.error();
  EXPECT_EQ(third.value().plc_heartbeat, 5U);
  EXPECT_EQ(link->stats().connects, 1);
}

TEST(PlcClientTest, PlcRestartIsSurvived) {
  const int port = test::FreeLoopbackPort();
  const auto link = OpenPlcLink(ClientOptions(port));
  {
    TestPlc plc(port);
    plc.Set(4, 1);
    ASSERT_TRUE(link->Read().ok());
  }
  // The PLC is gone: failures, counted, no throw.
  const auto down = link->Read();
  ASSERT_FALSE(down.ok());
  EXPECT_NE(down.error().find("holding registers 0-6 (left_ticks, right_ticks, plc_heartbeat, fix_request, relocalize_request)"),
            std::string::npos)
      << down.error();
  EXPECT_EQ(link->stats().read_errors, 1);
  EXPECT_FALSE(link->stats().connected);
  TestPlc plc(port);
  plc.Set(4, 2);
  const std::optional<PlcInputs> read = ReadWhenAnswered(*link);
  ASSERT_TRUE(read.has_value());
  EXPECT_EQ(read->plc_heartbeat, 2U);
  EXPECT_EQ(link->stats().connects, 2);
}

TEST(PlcClientTest, LateReplyDoesNotPoisonTheNextRead) {
  const int port = test::FreeLoopbackPort();
  TestPlc plc(port);
  const auto link = OpenPlcLink(ClientOptions(port));  // 100 ms timeout
  plc.Set(4, 10);
  ASSERT_TRUE(link->Read().ok());
  plc.DelayReplies(250ms);
  const auto late = link->Read();
  ASSERT_FALSE(late.ok());
  EXPECT_NE(late.error().find("timed out"), std::string::npos) << late.error();
  EXPECT_EQ(link->stats().timeouts, 1);
  // The late answer (heartbeat 10) must not be taken for the answer to the next request.
  plc.DelayReplies(0ms);
  plc.Set(4, 11);
  const std::optional<PlcInputs> read = ReadWhenAnswered(*link);
  ASSERT_TRUE(read.has_value());
  EXPECT_EQ(read->plc_heartbeat, 11U);
}

TEST(PlcClientTest, GarbageForAnAnswerIsAFailureAndTheNextAnswerIsRead) {
  const int port = test::FreeLoopbackPort();
  TestPlc plc(port);
  const auto link = OpenPlcLink(ClientOptions(port));
  plc.Set(4, 20);
  ASSERT_TRUE(link->Read().ok());
  plc.GarbleReplies(true);
  for (int i = 0; i < 3; ++i) {
    const auto garbled = link->Read();
    ASSERT_FALSE(garbled.ok());
    EXPECT_NE(garbled.error().find("holding registers 0-6"), std::string::npos) << garbled.error();
  }
  EXPECT_GE(link->stats().read_errors + link->stats().timeouts, 3);
  // Whatever the garbage left in the connection is not taken for the next answer.
  plc.GarbleReplies(false);
  plc.Set(4, 21);
  const std::optional<PlcInputs> read = ReadWhenAnswered(*link);
  ASSERT_TRUE(read.has_value());
  EXPECT_EQ(read->plc_heartbeat, 21U);
}

TEST(PlcClientTest, RegistersThePlcLacksAreNamedInTheError) {
  const int port = test::FreeLoopbackPort();
  TestPlc plc(port);  // 200 registers
  PlcLinkOptions options = ClientOptions(port);
  options.registers.fix_x.address = 500;
  const auto link = OpenPlcLink(options);
  const auto written = link->Write(PlcOutputs{});
  ASSERT_FALSE(written.ok());
  EXPECT_NE(written.error().find("fix_x"), std::string::npos) << written.error();
  EXPECT_NE(written.error().find("Illegal data address"), std::string::npos) << written.error();
  EXPECT_EQ(link->stats().write_errors, 1);
  EXPECT_TRUE(link->Read().ok());  // an exception reply does not break the connection
}

TEST(PlcServerTest, PlcWritesInputsAndReadsFixes) {
  const int port = test::FreeLoopbackPort();
  PlcLinkOptions options = ClientOptions(port);
  options.role = "server";
  const auto link = OpenPlcLink(options);
  const auto none = link->Read();
  ASSERT_FALSE(none.ok());
  EXPECT_EQ(none.error(), "the PLC has not written the encoder registers yet");

  modbus_t* plc = modbus_new_tcp("127.0.0.1", port);
  ASSERT_EQ(modbus_connect(plc), 0) << modbus_strerror(errno);
  const std::uint32_t left = 0x80000001U;
  const std::uint16_t inputs[6] = {HighWord(left), LowWord(left), 0, 1000, 9, 4};
  const auto before = MonotonicNow();
  ASSERT_EQ(modbus_write_registers(plc, 0, 6, inputs), 6);
  const std::optional<PlcInputs> read = ReadWhenWritten(*link);
  ASSERT_TRUE(read);
  EXPECT_EQ(read->counts.left_ticks, static_cast<std::int32_t>(left));
  EXPECT_EQ(read->counts.right_ticks, 1000);
  EXPECT_EQ(read->plc_heartbeat, 9U);
  EXPECT_EQ(read->fix_request, 4U);
  EXPECT_GE(read->time, before);
  EXPECT_FALSE(link->Read().value().fresh);  // nothing written since

  // Writing only the heartbeat is not a new encoder sample.
  ASSERT_EQ(modbus_write_register(plc, 4, 10), 1);
  EXPECT_FALSE(link->Read().value().fresh);

  ASSERT_TRUE(link->Write(PlcOutputs{-1.0, 2.5, 0.25, 2, 500, 4, 7, 3}).ok());
  std::uint16_t fix[11] = {};
  ASSERT_EQ(modbus_read_registers(plc, 100, 11, fix), 11);
  EXPECT_EQ(static_cast<std::int32_t>(JoinWords(fix[0], fix[1])), -100);
  EXPECT_EQ(static_cast<std::int32_t>(JoinWords(fix[2], fix[3])), 250);
  EXPECT_EQ(static_cast<std::int32_t>(JoinWords(fix[4], fix[5])), 250000);
  EXPECT_EQ(fix[6], 2);
  EXPECT_EQ(fix[8], 4);
  EXPECT_EQ(fix[9], 7);
  EXPECT_EQ(fix[10], 3);
  // Outside the table: an exception for the PLC, nothing changes here.
  EXPECT_EQ(modbus_write_register(plc, 150, 1), -1);
  EXPECT_TRUE(link->stats().connected);
  EXPECT_EQ(link->stats().connects, 1);
  modbus_close(plc);
  modbus_free(plc);
}

// A tricycle's PLC writes its drive wheel counter and its steering encoder (registers 0-1 and
// 2-3 by default; here the steering is a 16-bit signed register of its own at 7): the counter
// is unwrapped as a wheel's, the angle's count taken as read.
TEST(PlcServerTest, TricycleDriveCounterAndSteeringRegister) {
  const int port = test::FreeLoopbackPort();
  PlcLinkOptions options = ClientOptions(port);
  options.role = "server";
  options.registers.kind = core::DriveKind::kTricycle;
  options.registers.steering_ticks.address = 7;
  options.registers.steering_ticks.width_bits = 16;
  const auto link = OpenPlcLink(options);
  modbus_t* plc = modbus_new_tcp("127.0.0.1", port);
  ASSERT_EQ(modbus_connect(plc), 0) << modbus_strerror(errno);
  const std::uint32_t drive = 0x7FFFFFF0U;
  const std::uint16_t counter[2] = {HighWord(drive), LowWord(drive)};
  ASSERT_EQ(modbus_write_register(plc, 7, static_cast<std::uint16_t>(-1234)), 1);
  ASSERT_EQ(modbus_write_registers(plc, 0, 2, counter), 2);
  std::optional<PlcInputs> read = ReadWhenWritten(*link);
  ASSERT_TRUE(read);
  EXPECT_EQ(read->counts.drive_ticks, static_cast<std::int32_t>(drive));
  EXPECT_EQ(read->counts.steering_ticks, -1234);
  EXPECT_EQ(read->counts.left_ticks, 0);  // not a differential drive's
  // Past the int32 maximum the counter wraps as odometry takes it; the steering stays absolute.
  const std::uint32_t later = drive + 0x20U;
  const std::uint16_t wrapped[2] = {HighWord(later), LowWord(later)};
  ASSERT_EQ(modbus_write_register(plc, 7, 1500), 1);
  ASSERT_EQ(modbus_write_registers(plc, 0, 2, wrapped), 2);
  read = ReadWhenWritten(*link);
  ASSERT_TRUE(read);
  EXPECT_EQ(read->counts.drive_ticks, static_cast<std::int32_t>(later));
  EXPECT_EQ(read->counts.steering_ticks, 1500);
  modbus_close(plc);
  modbus_free(plc);
}

TEST(PlcServerTest, PortInUseIsAClearError) {
  const int port = test::FreeLoopbackPort();
  TestPlc other(port);
  PlcLinkOptions options = ClientOptions(port);
  options.role = "server";
  try {
    OpenPlcLink(options);
    FAIL() << "expected an error";
  } catch (const core::Error& e) {
    EXPECT_NE(std::string(e.what()).find("cannot serve as Modbus TCP server of 127.0.0.1:" + std::to_string(port)),
              std::string::npos)
        << e.what();
  }
}

TEST(PlcLinkOptionsTest, BadOptionsAreNamed) {
  PlcLinkOptions options;
  options.transport = "udp";
  EXPECT_THROW(OpenPlcLink(options), core::Error);
  options.transport = "rtu";
  options.parity = "X";
  std::string why;
  EXPECT_FALSE(options.Check(&why));
  EXPECT_EQ(why, "parity must be N, E or O");
  options.parity = "E";
  options.registers.fix_yaw.address = 101;
  EXPECT_FALSE(options.Check(&why));
  EXPECT_EQ(why, "registers: fix_x (registers 100-101) overlaps fix_yaw (registers 101-102)");
}

// Modbus RTU over a pair of linked pseudo-terminals (socat), mosaicloc the client on one
// end and the server on the other: the serial framing and CRC, without a serial port.
TEST(PlcRtuTest, ClientAndServerOverAPseudoTerminalPair) {
  if (std::system("command -v socat >/dev/null 2>&1") != 0) GTEST_SKIP() << "socat is not installed";
  const auto dir = std::filesystem::temp_directory_path() / ("mosaicloc-rtu-" + std::to_string(getpid()));
  std::filesystem::create_directories(dir);
  const std::string a = (dir / "a").string();
  const std::string b = (dir / "b").string();
  const pid_t socat = fork();
  if (socat == 0) {
    const std::string end_a = "pty,raw,echo=0,link=" + a;
    const std::string end_b = "pty,raw,echo=0,link=" + b;
    execlp("socat", "socat", end_a.c_str(), end_b.c_str(), static_cast<char*>(nullptr));
    _exit(127);
  }
  // socat is stopped however the test ends: a failed assertion returns early, and a socat
  // left running would hold the test's output open until the test driver's timeout.
  struct StopSocat {
    pid_t pid;
    std::filesystem::path dir;
    ~StopSocat() {
      kill(pid, SIGTERM);
      waitpid(pid, nullptr, 0);
      std::filesystem::remove_all(dir);
    }
  } stop_socat{socat, dir};
  for (int i = 0; i < 100 && !(std::filesystem::exists(a) && std::filesystem::exists(b)); ++i) {
    std::this_thread::sleep_for(10ms);
  }
  if (!(std::filesystem::exists(a) && std::filesystem::exists(b))) {
    GTEST_SKIP() << "socat could not create pseudo-terminals here (is /dev/pts mounted?)";
  }
  {
    // Each side's inputs are the other's outputs, so what one writes the other reads.
    PlcLinkOptions server;
    server.role = "server";
    server.transport = "rtu";
    server.device = a;
    server.baud = 115200;
    RegisterMap& s = server.registers;
    s.left_ticks.address = 100;
    s.right_ticks.address = 102;
    s.plc_heartbeat.address = 106;
    s.fix_request.address = 107;
    s.relocalize_request.address = 108;
    s.fix_x.address = 200;
    s.fix_y.address = 202;
    s.fix_yaw.address = 204;
    s.fix_status.address = 206;
    s.fix_quality.address = 207;
    s.fix_request_echo.address = 208;
    s.heartbeat.address = 209;
    PlcLinkOptions client;
    client.transport = "rtu";
    client.device = b;
    client.baud = 115200;
    client.response_timeout_ms = 500.0;
    RegisterMap& c = client.registers;
    c.left_ticks.address = 200;
    c.right_ticks.address = 202;
    c.plc_heartbeat.address = 206;
    c.fix_request.address = 207;
    c.relocalize_request.address = 208;
    const auto served = OpenPlcLink(server);
    const auto polling = OpenPlcLink(client);
    ASSERT_TRUE(polling->Write(PlcOutputs{10.0, 20.0, 0.1, 1, 999, 5, 6}).ok()) << polling->stats().last_error;
    const auto at_server = served->Read();
    ASSERT_TRUE(at_server.ok()) << at_server.error();
    EXPECT_EQ(at_server.value().counts.left_ticks, 1000);
    EXPECT_EQ(at_server.value().counts.right_ticks, 2000);
    EXPECT_EQ(at_server.value().plc_heartbeat, 1U);
    EXPECT_EQ(at_server.value().fix_request, 999U);
    ASSERT_TRUE(served->Write(PlcOutputs{-3.0, 4.0, 0.2, 2, 800, 8, 9}).ok());
    const auto at_client = polling->Read();
    ASSERT_TRUE(at_client.ok()) << at_client.error();
    EXPECT_EQ(at_client.value().counts.left_ticks, -300);
    EXPECT_EQ(at_client.value().counts.right_ticks, 400);
    EXPECT_EQ(at_client.value().plc_heartbeat, 2U);
    EXPECT_EQ(at_client.value().fix_request, 800U);
  }
}

}  // namespace
}  // namespace mosaicloc::io

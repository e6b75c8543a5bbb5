// On a real vcan0 (host, or the qemu VM of run-on-vcan.sh): the client against the emulator,
// and can-utils as the independent peer: candump captures what goes on the wire and the bytes
// are checked against CiA 301/402; cansend injects frames the client must handle.
#include <gtest/gtest.h>
#include <fcntl.h>
#include <signal.h>
#include <sys/wait.h>
#include <termios.h>
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <sstream>
#include <string>
#include <vector>

#include "../cia402_scenarios.hpp"
#include "hil/drv/socketcan.hpp"

namespace hil::drv::test {
namespace {

const CanTransportFactory kVcan = SocketCanTransport::factory("vcan0");

struct Logged {
  std::uint32_t id = 0;
  bool error = false;
  std::vector<int> data;
  std::string text;  // "605#2F60600008000000"
};

void cansend(const std::string& frame);

// candump -L vcan0 on a pseudo-terminal (so its stdout is line-buffered and every frame it
// printed can be seen at once), read by a thread. No sleeps: it is ready once a marker frame
// sent with cansend comes back through it, and stop() waits for a second marker, so every frame
// put on the bus before stop() is in the log whatever the machine's load. Markers (ID 0x7FF, the
// heartbeat of node 127, which nobody here is) are left out of the log.
class Candump {
 public:
  Candump() {
    master_ = ::posix_openpt(O_RDWR | O_NOCTTY);
    if (master_ < 0 || ::grantpt(master_) != 0 || ::unlockpt(master_) != 0) {
      ADD_FAILURE() << "no pseudo-terminal for candump";
      return;
    }
    const std::string slave = ::ptsname(master_);
    pid_ = ::fork();
    if (pid_ == 0) {
      ::setsid();
      const int fd = ::open(slave.c_str(), O_RDWR);
      termios t{};
      ::tcgetattr(fd, &t);
      ::cfmakeraw(&t);
      ::tcsetattr(fd, TCSANOW, &t);
      ::dup2(fd, 1);
      ::execlp("candump", "candump", "-L", "vcan0", static_cast<char*>(nullptr));
      std::_Exit(127);
    }
    reader_ = std::thread([this] {
      char buf[4096];
      for (;;) {
        const ssize_t n = ::read(master_, buf, sizeof buf);
        if (n <= 0) break;  // EIO once candump has exited
        std::lock_guard lock(mutex_);
        text_.append(buf, static_cast<std::size_t>(n));
      }
    });
    EXPECT_TRUE(marker("7FF#AA")) << "candump never showed the start marker";
  }
  ~Candump() { stop(); }
  std::vector<Logged> stop() {
    if (pid_ > 0) {
      EXPECT_TRUE(marker("7FF#BB")) << "candump never showed the end marker";
      ::kill(pid_, SIGINT);
      int status = 0;
      ::waitpid(pid_, &status, 0);
      pid_ = -1;
    }
    if (reader_.joinable()) reader_.join();
    if (master_ >= 0) ::close(master_), master_ = -1;
    std::vector<Logged> out;
    std::istringstream in(text());
    std::string stamp, iface, frame;
    while (in >> stamp >> iface >> frame) {
      if (frame.rfind("7FF#", 0) == 0) continue;
      Logged l;
      l.text = frame;
      const auto hash = frame.find('#');
      l.id = static_cast<std::uint32_t>(std::stoul(frame.substr(0, hash), nullptr, 16));
      l.error = hash == 8 && (l.id & 0x20000000u);
      for (std::size_t i = hash + 1; i + 2 <= frame.size(); i += 2) {
        if (frame[i] == 'R') break;
        l.data.push_back(std::stoi(frame.substr(i, 2), nullptr, 16));
      }
      out.push_back(l);
    }
    return out;
  }

 private:
  std::string text() {
    std::lock_guard lock(mutex_);
    return text_;
  }
  // Sends `frame` (again every 200 ms while candump may not have bound yet) until it shows.
  bool marker(const std::string& frame) {
    const std::string line = " vcan0 " + frame;
    auto sent = Clock::now() - std::chrono::seconds(1);
    return eventually(
        [&] {
          if (text().find(line) != std::string::npos) return true;
          if (Clock::now() - sent > std::chrono::milliseconds(200)) {
            sent = Clock::now();
            cansend(frame);
          }
          return false;
        },
        std::chrono::seconds(60));
  }
  int master_ = -1;
  pid_t pid_ = -1;
  std::thread reader_;
  std::mutex mutex_;
  std::string text_;
};

void cansend(const std::string& frame) {
  const std::string cmd = "cansend vcan0 " + frame;
  ASSERT_EQ(std::system(cmd.c_str()), 0) << cmd;
}

std::size_t find(const std::vector<Logged>& log, const std::string& text, std::size_t from = 0) {
  for (std::size_t i = from; i < log.size(); ++i) {
    if (log[i].text == text) return i;
  }
  return std::string::npos;
}

std::string dump(const std::vector<Logged>& log) {
  std::string s;
  for (std::size_t i = 0; i < log.size() && i < 80; ++i) s += log[i].text + "\n";
  return s;
}

// ---- the client against the emulator on vcan0 (same scenarios as the loopback suite) -------

TEST(Cia402Vcan, BootsToOperationEnabled) { boots_to_operation_enabled(kVcan, 5); }
TEST(Cia402Vcan, CspPositionTracking) { csp_position_tracking(kVcan, 5); }
TEST(Cia402Vcan, HeartbeatLossDetected) { heartbeat_loss_detected(kVcan, 5); }
TEST(Cia402Vcan, SdoAbortNamesObject) { sdo_abort_names_object(kVcan, 5); }
TEST(Cia402Vcan, EmcyEntersFaultAndResets) { emcy_enters_fault_and_resets(kVcan, 5); }
TEST(Cia402Vcan, SdoTimeoutRetryAndLateAnswer) { sdo_timeout_retry_and_late_answer(kVcan, 5); }
// Bus-off through the kernel's error-frame path: the emulator writes frames carrying
// CAN_ERR_FLAG; vcan hands them to sockets whose CAN_RAW_ERR_FILTER asks for that class.
TEST(Cia402Vcan, VariantTwoPdosEachWay) { variant_two_pdos_each_way(kVcan, 5); }
TEST(Cia402Vcan, VariantNoInterpolationPeriod) { variant_no_interpolation_period(kVcan, 5); }
TEST(Cia402Vcan, VariantDelayedModeDisplay) { variant_delayed_mode_display(kVcan, 5); }
TEST(Cia402Vcan, VariantFollowingError) { variant_following_error(kVcan, 5); }
TEST(Cia402Vcan, VariantQuickStopRamp) { variant_quick_stop_ramp(kVcan, 5); }
TEST(Cia402Vcan, ProbeReadsEachVariantWithoutMovingIt) { probe_variants(kVcan, 5); }
TEST(Cia402Vcan, EmcyTextSurvivesTheFault) { emcy_text_survives_the_fault(kVcan, 5); }
TEST(Cia402Vcan, ADeadBenchQuickStopsTheDrive) { drive_watches_the_bench(kVcan, 5, 3, cia402::State::switch_on_disabled); }
TEST(Cia402Vcan, AHungLoopStopsTheDriveAndItsHeartbeat) { a_hung_loop_stops_the_drive(kVcan, 5, true); }
TEST(Cia402Vcan, ADriveThatLeftOperationalIsSwitchedOffBySdo) { a_drive_out_of_operational_is_switched_off(kVcan, 5, false); }
TEST(Cia402Vcan, ADriveThatRefusesSdoIsStoppedByNmt) { a_drive_out_of_operational_is_switched_off(kVcan, 5, true); }
TEST(Cia402Vcan, BusOffPolicyReport) { bus_off_policy(kVcan, 5, BusOffPolicy::report); }
TEST(Cia402Vcan, BusOffPolicyWait) { bus_off_policy(kVcan, 5, BusOffPolicy::wait); }
TEST(Cia402Vcan, BusOffPolicyRecover) { bus_off_policy(kVcan, 5, BusOffPolicy::recover); }

// ---- candump: the bytes on the wire against CiA 301 / CiA 402 ------------------------------

TEST(Cia402Wire, ConfigureAndEnableBytesFollowTheStandard) {
  Candump dump_;
  {
    Rig r(kVcan, test_config(5));
    r.client.configure();
    r.client.activate();
    const auto syncs = r.emulator.syncs_seen();
    EXPECT_TRUE(eventually([&] { return r.emulator.syncs_seen() > syncs + 20; }));  // SYNC/RPDO/TPDO cycles to look at
    r.client.deactivate();
  }
  const auto log = dump_.stop();
  ASSERT_GT(log.size(), 50u) << dump(log);
  // NMT: COB-ID 0x000, [command, node].
  const auto reset = find(log, "000#8205");
  ASSERT_NE(reset, std::string::npos) << dump(log);
  // Boot-up (heartbeat with state 0x00). Frames from different sockets may reach candump out
  // of order (vcan queues per CPU), so replies are looked up anywhere, requests in order.
  ASSERT_NE(find(log, "705#00"), std::string::npos) << dump(log);
  // SDO upload 0x1000 (cs 0x40) and its 4-byte expedited reply (cs 0x43), device type 0x00020192.
  const auto up = find(log, "605#4000100000000000", reset);
  ASSERT_NE(up, std::string::npos) << dump(log);
  EXPECT_NE(find(log, "585#4300100092010200"), std::string::npos);
  // 2-byte download 0x1017 = 50 ms (cs 0x2B), reply 0x60.
  const auto hb = find(log, "605#2B17100032000000");
  ASSERT_NE(hb, std::string::npos) << dump(log);
  EXPECT_NE(find(log, "585#6017100000000000"), std::string::npos);
  // The drive watches the bench (issue 38 item 10): 0x1016:01 = node 127 (bits 16-23), 500 ms
  // (bits 0-15), a 4-byte download (cs 0x23); 0x6007 = 3 (quick stop), 2 bytes (cs 0x2B).
  EXPECT_NE(find(log, "605#23161001F4017F00", hb), std::string::npos) << dump(log);
  EXPECT_NE(find(log, "605#2B07600003000000", hb), std::string::npos) << dump(log);
  // Unused PDOs (issue 38 item 12): the drive's own COB-ID read, written back with bit 31
  // (RPDO2 0x305 -> 0x80000305), and 0x1006 = the SYNC period, 2000 us (4 bytes).
  const auto rpdo2 = find(log, "605#4001140100000000", hb);
  ASSERT_NE(rpdo2, std::string::npos) << dump(log);
  EXPECT_NE(find(log, "605#2301140105030080", rpdo2), std::string::npos) << dump(log);
  EXPECT_NE(find(log, "605#23061000D0070000", hb), std::string::npos) << dump(log);
  // PDO mapping in the CiA 301 order: invalidate RPDO1, clear count, map, count, type, validate.
  std::size_t at = hb;
  // (bytes: command specifier, index low, index high, sub-index, data little-endian)
  for (const char* step :
       {"605#2300140105020080", "605#2F00160000000000", "605#2300160110004060",
        "605#230016022000"
        "7A60",
        "605#2F00160002000000", "605#2F00140201000000", "605#2300140105020000", "605#2300180185010080", "605#2F001A0000000000",
        "605#23001A0110004160", "605#23001A0220006460", "605#2F001A0002000000", "605#2F00180201000000", "605#2300180185010000"}) {
    at = find(log, step, at);
    ASSERT_NE(at, std::string::npos) << "missing " << step << "\n" << dump(log);
  }
  // CSP: 0x6060 = 8 as a 1-byte download (cs 0x2F); 0x6061 reads back 8 (cs 0x4F).
  at = find(log, "605#2F60600008000000", at);
  ASSERT_NE(at, std::string::npos);
  EXPECT_NE(find(log, "585#4F61600008000000"), std::string::npos);
  // NMT start, then heartbeats say operational (0x05).
  const auto start = find(log, "000#0105", at);
  ASSERT_NE(start, std::string::npos);
  EXPECT_NE(find(log, "705#05"), std::string::npos);
  // SYNC: COB-ID 0x080, no data. Each RPDO1 (0x205, 6 bytes) goes out right before a SYNC.
  std::vector<int> controlwords;
  int syncs = 0, tpdos = 0;
  for (std::size_t i = start; i < log.size(); ++i) {
    const auto& l = log[i];
    if (l.id == 0x080) {
      EXPECT_TRUE(l.data.empty()) << l.text;
      ++syncs;
    } else if (l.id == 0x205) {
      ASSERT_EQ(l.data.size(), 6u) << l.text;
      const int cw = l.data[0] | l.data[1] << 8;
      // target position, little-endian: the drive stands at 0.25 rad = 1630 counts
      const std::int32_t target = l.data[2] | l.data[3] << 8 | l.data[4] << 16 | l.data[5] << 24;
      EXPECT_NEAR(target, 1630, 3) << l.text;
      if (controlwords.empty() || controlwords.back() != cw) controlwords.push_back(cw);
      // The client's next frame is the SYNC (the drive's heartbeat may come in between).
      std::size_t j = i + 1;
      while (j < log.size() && log[j].id != 0x080 && log[j].id != 0x205 && log[j].id != 0x605 && log[j].id != 0x000) ++j;
      if (j < log.size()) {
        EXPECT_EQ(log[j].id, 0x080u) << "RPDO not followed by SYNC: " << l.text;
      }
    } else if (l.id == 0x185) {
      ASSERT_EQ(l.data.size(), 6u) << l.text;
      ++tpdos;
      // position actual, little-endian: 0.25 rad at 40960 counts/rev = 1630 counts (0x065E)
      const std::int32_t pos = l.data[2] | l.data[3] << 8 | l.data[4] << 16 | l.data[5] << 24;
      EXPECT_NEAR(pos, 1630, 3) << l.text;
    }
  }
  EXPECT_GT(syncs, 10);
  EXPECT_GT(tpdos, 10);
  // Controlword sequence: disable voltage, shutdown, switch on, enable operation, then disable
  // voltage for deactivate(): a normal end leaves the drive in switch on disabled (CiA 402
  // transition 9), not relying on the drive's heartbeat consumer to get there.
  EXPECT_EQ(controlwords, (std::vector<int>{0x00, 0x06, 0x07, 0x0F, 0x00})) << dump(log);
}

TEST(Cia402Wire, NmtCommandsBytes) {
  Candump dump_;
  {
    Rig r(kVcan, test_config(7));
    using S = canopen::NmtState;
    r.client.nmt(canopen::NmtCommand::enter_pre_operational);
    r.client.nmt(canopen::NmtCommand::stop);
    EXPECT_TRUE(eventually([&] { return r.emulator.nmt_state() == S::stopped; }));
    r.client.nmt(canopen::NmtCommand::start);
    EXPECT_TRUE(eventually([&] { return r.emulator.nmt_state() == S::operational; }));
    r.client.nmt(canopen::NmtCommand::reset_node);  // boot-up, then pre-operational
    EXPECT_TRUE(eventually([&] { return r.emulator.nmt_state() == S::pre_operational; }));
  }
  const auto log = dump_.stop();
  std::size_t at = 0;
  for (const char* f : {"000#8007", "000#0207", "000#0107", "000#8107"}) {
    at = find(log, f, at);
    EXPECT_NE(at, std::string::npos) << "missing " << f << "\n" << dump(log);
    if (at == std::string::npos) break;
  }
  EXPECT_GE(std::count_if(log.begin(), log.end(), [](const Logged& l) { return l.text == "707#00"; }), 2);  // boot-ups
}

TEST(Cia402Wire, SdoReplyCommandSpecifiers) {
  Candump dump_;
  {
    Rig r(kVcan, test_config(5));
    EXPECT_EQ(r.client.sdo_read(0x6041, 0) & 0x4F, 0x40u);  // statusword: switch on disabled
    EXPECT_THROW(r.client.sdo_read(0x2000, 0), SdoAbortError);
    EXPECT_THROW(r.client.sdo_write(0x1000, 0, 1, 4), SdoAbortError);  // read-only
  }
  const auto log = dump_.stop();
  // 2-byte upload reply: cs 0x4B, statusword 0x0240 little-endian.
  EXPECT_NE(find(log, "605#4041600000000000"), std::string::npos) << dump(log);
  EXPECT_NE(find(log, "585#4B41600040020000"), std::string::npos) << dump(log);
  // Aborts: cs 0x80, the object, then the code little-endian.
  EXPECT_NE(find(log, "585#8000200000000206"), std::string::npos) << dump(log);  // 0x06020000
  EXPECT_NE(find(log, "605#2300100001000000"), std::string::npos) << dump(log);
  EXPECT_NE(find(log, "585#8000100002000106"), std::string::npos) << dump(log);  // 0x06010002
}

// ---- cansend: frames from outside that the client must handle ------------------------------

TEST(Cia402Inject, MalformedAndValidEmcyFromCansend) {
  malformed_frames_are_counted(kVcan, 5, [](const CanFrame& f) { cansend(to_string(f)); });
}

TEST(Cia402Inject, SdoAbortFromCansendNamesTheObject) {
  auto cfg = test_config(9);  // no emulator at node 9: cansend plays the server
  cfg.sdo_timeout = std::chrono::milliseconds(1500);
  cfg.sdo_retries = 10;  // the request is repeated until the peer's candump has bound and answers
  Cia402Drive client(cfg, kVcan);
  // Answer the first request on 0x609 with abort 0x06020000 for 0x2100:03.
  std::thread peer([] {
    [[maybe_unused]] int rc = std::system("candump -n 1 vcan0,609:7FF >/dev/null && cansend vcan0 589#8000210300000206");
  });
  try {
    client.sdo_read(0x2100, 3);
    ADD_FAILURE() << "no abort";
  } catch (const SdoAbortError& e) {
    EXPECT_EQ(e.code, 0x06020000u);
    EXPECT_EQ(e.index, 0x2100);
    EXPECT_EQ(e.sub, 3);
    EXPECT_NE(std::string(e.what()).find("SDO read 0x2100:03: abort 0x06020000 (object does not exist"), std::string::npos)
        << e.what();
  }
  peer.join();
}

TEST(Cia402Inject, BusOffErrorFrameFromCansend) {
  auto cfg = test_config(5);
  cfg.bus_off_policy = BusOffPolicy::wait;
  cfg.heartbeat_timeout = std::chrono::milliseconds(5000);
  Rig r(kVcan, cfg);
  r.client.configure();
  // cansend with an 8-digit id carrying CAN_ERR_FLAG (0x20000000) | CAN_ERR_BUSOFF (0x40).
  cansend("20000040#0000000000000000");
  ASSERT_TRUE(eventually([&] { return r.client.health().bus_state == BusState::bus_off; }));
  EXPECT_TRUE(r.client.health().fault);
  cansend("20000100#0000000000000000");  // CAN_ERR_RESTARTED
  ASSERT_TRUE(eventually([&] { return !r.client.health().fault; })) << r.client.health().last_error_text();
  EXPECT_EQ(r.client.health().bus_state, BusState::error_active);
  EXPECT_GE(r.client.health().error_frames, 2u);
}

TEST(Cia402Inject, FloodOfHighPriorityFramesDoesNotStopTheDrive) {
  Rig r(kVcan, test_config(5));
  r.client.configure();
  r.client.activate();
  r.emulator.flood(true, 0x001, 5);
  TestLoop loop(r.client);
  loop.target_rad = 0.6;
  EXPECT_TRUE(eventually([&] { return std::abs(loop.position_rad - 0.6) < 1e-3; }));
  r.emulator.flood(false);
  EXPECT_EQ(r.client.health().malformed, 0u);  // the kernel filter kept the junk away
}

}  // namespace
}  // namespace hil::drv::test

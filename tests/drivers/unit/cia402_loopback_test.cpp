// The CiA 402 client against the emulator on the in-process loopback bus. The same scenarios
// run on a real vcan0 in tests/drivers/vcan.
#include <gtest/gtest.h>

#include <boost/asio/executor_work_guard.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/asio/post.hpp>
#include <optional>
#include <algorithm>
#include <limits>
#include <mutex>
#include <vector>

#include "../cia402_scenarios.hpp"
#include "hil/drv/can_loopback.hpp"
#include "hil/drv/canopen.hpp"
#include "hil/drv/cia402_probe.hpp"
#include "hil/drv/sdo_client.hpp"

namespace hil::drv::test {
namespace {

// A misbehaving drive's SDO server at node `node`: `answer` makes the reply (or none) to each
// request the client sends; every request is kept for the test to look at.
class FakeSdoServer {
 public:
  using Answer = std::function<std::optional<CanFrame>(const CanFrame& request)>;
  FakeSdoServer(LoopbackBus& bus, std::uint8_t node, Answer answer)
      : answer_(std::move(answer)), tr_(bus.factory()(io_, {{canopen::kSdoRx + node, 0x7FF}})) {
    tr_->start([this](const CanFrame& f) {
      {
        std::lock_guard lock(mutex_);
        requests_.push_back(f);
      }
      if (auto reply = answer_(f)) tr_->send(*reply);
    });
    thread_ = std::thread([this] { io_.run(); });
  }
  ~FakeSdoServer() {
    boost::asio::post(io_, [this] { tr_->stop(); });
    work_.reset();
    io_.stop();
    thread_.join();
  }
  std::vector<CanFrame> requests() {
    std::lock_guard lock(mutex_);
    return requests_;
  }

 private:
  boost::asio::io_context io_;
  boost::asio::executor_work_guard<boost::asio::io_context::executor_type> work_{io_.get_executor()};
  Answer answer_;
  std::unique_ptr<CanTransport> tr_;
  std::mutex mutex_;
  std::vector<CanFrame> requests_;
  std::thread thread_;
};

// A channel whose next send() blocks for `stall_ms` when set: the client's I/O thread stops as in
// a stopped process (SIGSTOP), while the drive on the bus goes on by its own clock.
class StallingTransport final : public CanTransport {
 public:
  StallingTransport(std::unique_ptr<CanTransport> inner, std::atomic<long>& stall_ms)
      : inner_(std::move(inner)), stall_ms_(stall_ms) {}
  void start(Handler on_frame) override { inner_->start(std::move(on_frame)); }
  bool send(const CanFrame& f) noexcept override {
    if (const long ms = stall_ms_.exchange(0); ms > 0) std::this_thread::sleep_for(std::chrono::milliseconds(ms));
    return inner_->send(f);
  }
  void stop() noexcept override { inner_->stop(); }
  void reopen() override { inner_->reopen(); }
  const std::string& name() const override { return inner_->name(); }

 private:
  std::unique_ptr<CanTransport> inner_;
  std::atomic<long>& stall_ms_;
};

class Cia402Loopback : public ::testing::Test {
 protected:
  LoopbackBus bus;
  CanTransportFactory factory() { return bus.factory(); }
};

TEST_F(Cia402Loopback, BootsToOperationEnabled) { boots_to_operation_enabled(factory(), 5); }
TEST_F(Cia402Loopback, CspPositionTracking) { csp_position_tracking(factory(), 5); }
TEST_F(Cia402Loopback, HeartbeatLossDetected) { heartbeat_loss_detected(factory(), 5); }
TEST_F(Cia402Loopback, SdoAbortNamesObject) { sdo_abort_names_object(factory(), 5); }
TEST_F(Cia402Loopback, EmcyEntersFaultAndResets) { emcy_enters_fault_and_resets(factory(), 5); }
TEST_F(Cia402Loopback, SdoTimeoutRetryAndLateAnswer) { sdo_timeout_retry_and_late_answer(factory(), 5); }
TEST_F(Cia402Loopback, BusOffPolicyReport) { bus_off_policy(factory(), 5, BusOffPolicy::report); }
TEST_F(Cia402Loopback, BusOffPolicyWait) { bus_off_policy(factory(), 5, BusOffPolicy::wait); }
TEST_F(Cia402Loopback, BusOffPolicyRecover) { bus_off_policy(factory(), 5, BusOffPolicy::recover); }
TEST_F(Cia402Loopback, VariantTwoPdosEachWay) { variant_two_pdos_each_way(factory(), 5); }
TEST_F(Cia402Loopback, VariantNoInterpolationPeriod) { variant_no_interpolation_period(factory(), 5); }
TEST_F(Cia402Loopback, VariantDelayedModeDisplay) { variant_delayed_mode_display(factory(), 5); }
TEST_F(Cia402Loopback, VariantFollowingError) { variant_following_error(factory(), 5); }
TEST_F(Cia402Loopback, VariantQuickStopRamp) { variant_quick_stop_ramp(factory(), 5); }
TEST_F(Cia402Loopback, ProbeReadsEachVariantWithoutMovingIt) { probe_variants(factory(), 5); }
TEST_F(Cia402Loopback, EmcyTextSurvivesTheFault) { emcy_text_survives_the_fault(factory(), 5); }
TEST_F(Cia402Loopback, ADeadBenchQuickStopsTheDrive) {
  drive_watches_the_bench(factory(), 5, 3, cia402::State::switch_on_disabled);
}
TEST_F(Cia402Loopback, ADeadBenchDisablesTheDrive) {
  drive_watches_the_bench(factory(), 5, 2, cia402::State::switch_on_disabled);
}
TEST_F(Cia402Loopback, AHungLoopStopsTheDriveAndItsHeartbeat) { a_hung_loop_stops_the_drive(factory(), 5, true); }
TEST_F(Cia402Loopback, AHungLoopStopsADriveWithoutAConsumer) { a_hung_loop_stops_the_drive(factory(), 5, false); }
TEST_F(Cia402Loopback, ADriveThatLeftOperationalIsSwitchedOffBySdo) {
  a_drive_out_of_operational_is_switched_off(factory(), 5, false);
}
TEST_F(Cia402Loopback, ADriveThatRefusesSdoIsStoppedByNmt) { a_drive_out_of_operational_is_switched_off(factory(), 5, true); }

// Issue 50: the bench stalls (its I/O thread stopped 1.2 s, as a SIGSTOP of the process stops it)
// longer than the drive's consumer time: the drive sends EMCY 0x8130 and quick-stops. The fault
// says so in words and names the bench's own heartbeat gap, measured on the bench's clock: the
// host stalled, the drive did as configured. Nor is the drive's heartbeat, queued meanwhile,
// taken for lost.
TEST_F(Cia402Loopback, ABenchStallIsNamedAsTheBenchsNotTheDrives) {
  std::atomic<long> stall_ms{0};
  const CanTransportFactory inner = factory();
  const CanTransportFactory stalling = [&](boost::asio::io_context& io,
                                           std::vector<CanFilter> filters) -> std::unique_ptr<CanTransport> {
    return std::make_unique<StallingTransport>(inner(io, std::move(filters)), stall_ms);
  };
  auto cfg = test_config(5);
  cfg.bench_heartbeat.producer = 50ms;
  cfg.bench_heartbeat.drive_timeout = 600ms;
  FirstOrderServoTestModel model{0.01, 20.0, 0.25};
  Cia402DriveEmulator emulator(Rig::emulator_config(cfg, {}), model, inner);
  Cia402Drive client(cfg, stalling);
  client.configure();
  client.activate();
  TestLoop loop(client);
  ASSERT_TRUE(eventually([&] { return emulator.state() == cia402::State::operation_enabled; }));
  stall_ms = 1200;
  ASSERT_TRUE(eventually([&] { return emulator.heartbeat_consumer_events() > 0; }, 20s));
  std::string cause;
  ASSERT_TRUE(eventually([&] {
    cause = std::string(client.health().fault_cause_text());
    return !cause.empty();
  })) << client.health().last_error_text();
  EXPECT_NE(cause.find("EMCY 0x8130: the drive lost the bench's heartbeat and did its 0x6007 reaction (quick stop)"),
            std::string::npos)
      << cause;
  EXPECT_NE(cause.find("(0x1016 gives the drive 600 ms): the host stalled"), std::string::npos) << cause;
  const long late_ms = number_after(cause, "the bench's heartbeat was ");
  EXPECT_GE(late_ms, 1200) << cause;  // the stall, measured by the bench
  EXPECT_EQ(cause.find("heartbeat lost"), std::string::npos) << cause;
  EXPECT_FALSE(client.health().heartbeat_lost);
  std::printf("bench stalled 1200 ms: %s\n", cause.c_str());
}
TEST_F(Cia402Loopback, ADeadBenchFaultsTheDrive) { drive_watches_the_bench(factory(), 5, 1, cia402::State::fault); }

// The bench's heartbeat on the bus as CiA 301 has it: 0x700 + its node id, one byte, NMT state
// operational (0x05), about every producer period (counted: several of them while the client
// runs, none from the drive's node id for the bench).
TEST_F(Cia402Loopback, TheBenchProducesItsHeartbeat) {
  std::mutex mutex;
  std::vector<CanFrame> heartbeats;
  bus.set_tap([&](const CanFrame& f) {
    if (f.id != canopen::kHeartbeat + 127) return;
    std::lock_guard lock(mutex);
    heartbeats.push_back(f);
  });
  Rig r(factory(), test_config(5));  // bench node id: the default, 127
  r.client.configure();
  ASSERT_TRUE(eventually([&] {
    std::lock_guard lock(mutex);
    return heartbeats.size() >= 5;
  }));
  bus.set_tap({});
  std::lock_guard lock(mutex);
  for (const auto& f : heartbeats) {
    EXPECT_EQ(f.dlc, 1);
    EXPECT_FALSE(f.rtr);
    EXPECT_EQ(f.data[0], 0x05);
  }
  EXPECT_EQ(r.emulator.object(0x1016, 1), (127u << 16) | 500u);  // the defaults
  EXPECT_EQ(r.emulator.object(0x6007, 0), 3u);                   // quick stop
}

// A drive with no 0x1016 cannot watch the bench: configure() says so and fails, unless the drive
// file says bench_heartbeat.required: false (then a configure note). The same for 0x6007.
TEST_F(Cia402Loopback, ADriveThatCannotWatchTheBenchIsRefusedByName) {
  for (const bool consumer : {false, true}) {
    Rig r(factory(), test_config(5), [&](Cia402EmulatorConfig& e) {
      e.heartbeat_consumer = consumer;
      e.abort_connection_option = !consumer;
    });
    try {
      r.client.configure();
      ADD_FAILURE() << "configured a drive without " << (consumer ? "0x6007" : "0x1016");
    } catch (const DriveError& e) {
      EXPECT_NE(std::string(e.what()).find(consumer ? "0x6007:00 absent: the drive has no abort connection option code"
                                                    : "0x1016:00 absent: the drive has no consumer heartbeat time"),
                std::string::npos)
          << e.what();
      EXPECT_NE(std::string(e.what()).find("bench_heartbeat.required: false"), std::string::npos) << e.what();
    }
  }
  auto cfg = test_config(5);
  cfg.bench_heartbeat.required = false;
  Rig r(factory(), cfg, [](Cia402EmulatorConfig& e) { e.heartbeat_consumer = false; });
  r.client.configure();
  const auto notes = r.client.configure_notes();
  ASSERT_FALSE(notes.empty());
  EXPECT_NE(notes.front().find("0x1016:00 absent"), std::string::npos) << notes.front();
}

TEST_F(Cia402Loopback, MalformedFramesAreCounted) {
  malformed_frames_are_counted(factory(), 5, [this](const CanFrame& f) { bus.inject(f); });
}

TEST_F(Cia402Loopback, TwoDrivesOnOneBusDoNotMix) {
  Rig a(factory(), test_config(3));
  Rig b(factory(), test_config(4));
  a.client.configure();
  b.client.configure();
  a.client.activate();
  EXPECT_TRUE(eventually([&] { return a.emulator.state() == cia402::State::operation_enabled; }));
  EXPECT_NE(b.emulator.state(), cia402::State::operation_enabled);
}

TEST_F(Cia402Loopback, NoBootUpIsAnErrorNamingTheNode) {
  auto cfg = test_config(9);
  cfg.boot_timeout = std::chrono::milliseconds(300);
  Cia402Drive client(cfg, factory());  // nobody at node 9
  try {
    client.configure();
    FAIL();
  } catch (const DriveError& e) {
    EXPECT_NE(std::string(e.what()).find("node 9 on vcan0: no boot-up message (0x709)"), std::string::npos) << e.what();
  }
}

// Another master (or the drive itself) takes the drive out of operational mid-run: its
// heartbeat keeps coming, so only the NMT state in it tells that PDOs are no longer processed.
TEST_F(Cia402Loopback, DriveLeavingOperationalMidRunIsAFault) {
  for (const auto command : {canopen::NmtCommand::stop, canopen::NmtCommand::enter_pre_operational}) {
    Rig r(factory(), test_config(5));
    r.client.configure();
    r.client.activate();
    ASSERT_FALSE(r.client.read(Clock::now(), 1ms).fault);
    bus.inject(canopen::nmt(command, 5));  // not from our client
    ASSERT_TRUE(eventually([&] { return r.client.health().fault; }, 5s)) << r.client.health().last_error_text();
    EXPECT_TRUE(r.client.read(Clock::now(), 1ms).fault);
    // The cause is kept (the client's own switch-off by SDO, or NMT stop, is the newest error soon).
    const std::string text(r.client.health().fault_cause_text());
    EXPECT_NE(text.find("node 5 on vcan0: the drive left NMT operational (heartbeat says "), std::string::npos) << text;
    // Latched like a reboot: back to operational is not enough, configure() is.
    bus.inject(canopen::nmt(canopen::NmtCommand::start, 5));
    ASSERT_TRUE(eventually([&] { return r.client.health().nmt_state == 0x05; }, 5s));
    EXPECT_TRUE(r.client.health().fault);
    r.client.configure();
    EXPECT_FALSE(r.client.read(Clock::now(), 1ms).fault) << r.client.health().last_error_text();
  }
}

// Our own NMT stop is asked for, not a surprise: no fault.
TEST_F(Cia402Loopback, OwnNmtStopIsNoFault) {
  Rig r(factory(), test_config(5));
  r.client.configure();
  r.client.nmt(canopen::NmtCommand::stop);
  ASSERT_TRUE(eventually([&] { return r.client.health().nmt_state == 0x04; }, 5s));
  EXPECT_FALSE(r.client.health().fault) << r.client.health().last_error_text();
}

// A drive that starts a segmented upload (0x1008 device name, 1000 bytes): the client refuses
// it, and must tell the drive with an abort, or the drive's server waits in the transfer.
TEST_F(Cia402Loopback, RefusedSegmentedUploadIsAbortedOnTheBus) {
  FakeSdoServer drive(bus, 7, [](const CanFrame& req) -> std::optional<CanFrame> {
    if (req.data[0] != 0x40) return std::nullopt;  // only the upload request is answered
    CanFrame f = canopen::sdo_upload_ok(7, 0x1008, 0, 1000, 4);
    f.data[0] = 0x41;  // initiate upload, segmented, size indicated
    return f;
  });
  Cia402Drive client(test_config(7), factory());
  try {
    client.sdo_read(0x1008, 0);
    ADD_FAILURE() << "a segmented upload was accepted";
  } catch (const DriveError& e) {
    EXPECT_NE(std::string(e.what()).find("only expedited SDO is supported"), std::string::npos) << e.what();
  }
  ASSERT_TRUE(eventually([&] { return drive.requests().size() >= 2; }, 5s)) << "no abort sent to the drive";
  const CanFrame abort = drive.requests()[1];
  EXPECT_EQ(abort.data[0], 0x80);
  EXPECT_EQ(canopen::get_le(&abort.data[1], 2), 0x1008u);
  EXPECT_EQ(canopen::get_le(&abort.data[4], 4), 0x05040001u);  // command specifier not valid
}

// A drive that answers every request, but for another object, or with the wrong service: the
// error must not claim it was silent.
TEST_F(Cia402Loopback, WrongSdoRepliesAreNamedNotCalledSilence) {
  FakeSdoServer drive(bus, 7, [](const CanFrame& req) -> std::optional<CanFrame> {
    if (req.data[0] == 0x40) return canopen::sdo_upload_ok(7, 0x1009, 0, 42, 4);  // read 0x1008 -> reply for 0x1009
    return canopen::sdo_upload_ok(7, 0x1017, 0, 42, 2);                           // write -> an upload reply
  });
  auto cfg = test_config(7);
  cfg.sdo_timeout = 100ms;
  cfg.sdo_retries = 1;
  Cia402Drive client(cfg, factory());
  try {
    client.sdo_read(0x1008, 0);
    ADD_FAILURE() << "a reply for 0x1009 answered a read of 0x1008";
  } catch (const DriveError& e) {
    const std::string text = e.what();
    EXPECT_NE(text.find("SDO read 0x1008:00: no matching reply after 2 tries of 100 ms (2 replies ignored"), std::string::npos)
        << text;
    EXPECT_NE(text.find("last 587#4309100"), std::string::npos) << text;  // the last ignored frame, as received
  }
  try {
    client.sdo_write(0x1017, 0, 100, 2);
    ADD_FAILURE() << "an upload reply confirmed a write";
  } catch (const DriveError& e) {
    EXPECT_NE(std::string(e.what()).find("no matching reply after 2 tries"), std::string::npos) << e.what();
  }
}

// 0x60C2 = value (u8) x 10^index s must say the SYNC period. 1050 us used to be sent as
// 10 x 10^-4 s (1.0 ms), 350 us as 300 us and 25600 us as 256 cast to a byte, 0; 30500 us fits
// no byte exactly and is the nearest, 31 ms, with a configure note; 200 ms is 2 x 10^-1 s.
TEST_F(Cia402Loopback, InterpolationPeriodSaysTheSyncPeriod) {
  struct Case {
    long long sync_us;
    std::uint32_t value;
    std::int8_t index;
    bool note;
  };
  for (const auto& c : {Case{2000, 2, -3, false}, Case{1050, 105, -5, false}, Case{350, 35, -5, false}, Case{25600, 26, -3, true},
                        Case{30500, 31, -3, true}, Case{200000, 2, -1, false}}) {
    auto cfg = test_config(5);
    cfg.sync_period = std::chrono::microseconds(c.sync_us);
    Rig r(factory(), cfg);
    r.client.configure();
    EXPECT_EQ(r.emulator.object(0x60C2, 1), c.value) << c.sync_us << " us";
    EXPECT_EQ(static_cast<std::int8_t>(r.emulator.object(0x60C2, 2).value_or(0)), c.index) << c.sync_us << " us";
    bool noted = false;
    for (const auto& n : r.client.configure_notes()) noted |= n.find("nearest to the SYNC period") != std::string::npos;
    EXPECT_EQ(noted, c.note) << c.sync_us << " us";
  }
}

// A broken command (NaN, infinite) reaching the client holds the last target. It used to go
// out as INT32_MIN / INT32_MAX counts: a move to the end of the encoder range.
TEST_F(Cia402Loopback, NonFiniteTargetHoldsTheLastOne) {
  Rig r(factory(), test_config(5));
  r.client.configure();
  r.client.activate();
  r.client.write(Clock::now(), 1ms, {0.3, true, false});
  ASSERT_TRUE(eventually([&] { return std::abs(r.model.target_rad() - 0.3) < 1e-3; }));
  for (const double bad : {kNaN, std::numeric_limits<double>::infinity(), -std::numeric_limits<double>::infinity()}) {
    r.client.write(Clock::now(), 1ms, {bad, true, false});
    const auto syncs = r.emulator.syncs_seen();
    ASSERT_TRUE(eventually([&] { return r.emulator.syncs_seen() > syncs + 10; }));  // several RPDOs with it
    EXPECT_NEAR(r.model.target_rad(), 0.3, 1e-3) << bad;
  }
  EXPECT_NE(r.client.health().last_error_text().find("target position is not a number; the last target is held"),
            std::string_view::npos)
      << r.client.health().last_error_text();
  r.client.write(Clock::now(), 1ms, {0.1, true, false});  // a good command is followed again
  EXPECT_TRUE(eventually([&] { return std::abs(r.model.target_rad() - 0.1) < 1e-3; }));
}

// RPDO1 + SYNC + TPDO1 need 285 us of a 1 Mbit/s bus (worst-case stuffing): a shorter SYNC
// period would be stale every period on a real bus. Refused before anything is opened.
TEST_F(Cia402Loopback, SyncPeriodTheBusCannotCarryIsRefused) {
  auto cfg = test_config(5);
  EXPECT_EQ(cfg.min_sync_period(), std::chrono::microseconds(285));
  cfg.sync_period = std::chrono::microseconds(200);
  try {
    Cia402Drive client(cfg, factory());
    ADD_FAILURE() << "a 200 us SYNC period on a 1 Mbit/s bus was accepted";
  } catch (const DriveError& e) {
    EXPECT_NE(std::string(e.what()).find("node 5 on vcan0: a SYNC period of 200 us is shorter than the 285 us"),
              std::string::npos)
        << e.what();
  }
  cfg.bitrate = 125000;
  cfg.sync_period = std::chrono::microseconds(2000);
  EXPECT_THROW(Cia402Drive(cfg, factory()), DriveError);  // 2280 us at 125 kbit/s
}

// A drive whose TPDO1 arrives too short (here remapped to the statusword alone): the feedback is
// stale although TPDOs flow; the stale reason used to say "no TPDO since the last SYNC".
TEST_F(Cia402Loopback, ShortTpdoIsNamedAsTheStaleReason) {
  Rig r(factory(), test_config(5));
  r.client.configure();
  EXPECT_EQ(r.client.missing_reply_text(), "no TPDO since the last SYNC");
  r.client.sdo_write(0x1800, 1, canopen::kCobIdInvalid | 0x185, 4);
  r.client.sdo_write(0x1A00, 0, 0, 1);
  r.client.sdo_write(0x1A00, 1, 0x60410010, 4);  // statusword only: 2 bytes
  r.client.sdo_write(0x1A00, 0, 1, 1);
  r.client.sdo_write(0x1800, 1, 0x185, 4);
  ASSERT_TRUE(eventually([&] { return r.client.health().malformed > 2; }, 5s));
  EXPECT_NE(r.client.missing_reply_text().find("TPDO1 arrives too short (expected 6 bytes"), std::string_view::npos)
      << r.client.missing_reply_text();
}

// The drive resets while configure() writes its mapping (a brown-out, a watchdog): the mapping,
// 0x1017 and the mode are back at their defaults. configure() must fail saying so, not carry on.
TEST_F(Cia402Loopback, RebootDuringConfigureFailsSayingSo) {
  auto cfg = test_config(5);
  cfg.boot_timeout = 2s;
  Rig r(factory(), cfg);
  std::atomic<bool> rebooted{false};
  bus.set_tap([&](const CanFrame& f) {
    // The client validates TPDO1 (0x1800:01 = 0x185): the mapping is written; now the drive resets.
    if (f.id == canopen::kSdoRx + 5 && f.data[0] == 0x23 && canopen::get_le(&f.data[1], 2) == 0x1800 && f.data[3] == 1 &&
        canopen::get_le(&f.data[4], 4) == 0x185 && !rebooted.exchange(true)) {
      r.emulator.reboot();  // posted to the emulator's thread: safe under the bus lock
    }
  });
  try {
    r.client.configure();
    ADD_FAILURE() << "configure() went through a reboot";
  } catch (const DriveError& e) {
    EXPECT_NE(std::string(e.what()).find("node 5 on vcan0: the drive rebooted during configure()"), std::string::npos)
        << e.what();
  }
  bus.set_tap({});
  EXPECT_TRUE(rebooted);
  r.client.configure();  // once more, undisturbed: it comes up
  EXPECT_FALSE(r.client.read(Clock::now(), 1ms).fault) << r.client.health().last_error_text();
}

// A request given up on is aborted on the bus (CiA 301 "SDO protocol timed out"), so a drive
// that was only slow drops it instead of answering it into the next request.
TEST_F(Cia402Loopback, SdoGivenUpOnIsAbortedOnTheBus) {
  FakeSdoServer drive(bus, 7, [](const CanFrame&) { return std::optional<CanFrame>(); });  // never answers
  auto cfg = test_config(7);
  cfg.sdo_timeout = 50ms;
  cfg.sdo_retries = 1;
  Cia402Drive client(cfg, factory());
  EXPECT_THROW(client.sdo_read(0x6064, 0), DriveError);
  ASSERT_TRUE(eventually([&] { return drive.requests().size() >= 3; }, 5s)) << drive.requests().size();
  const auto requests = drive.requests();
  EXPECT_EQ(requests[0].data[0], 0x40);  // the try and its retry
  EXPECT_EQ(requests[1].data[0], 0x40);
  EXPECT_EQ(requests[2].data[0], 0x80);  // then the abort, for that object
  EXPECT_EQ(canopen::get_le(&requests[2].data[1], 2), 0x6064u);
  EXPECT_EQ(canopen::get_le(&requests[2].data[4], 4), 0x05040000u);
}

// A drive that answers neither value nor abort for one object (here 0x6502) is reported for
// that object; the probe used to end there with the SDO timeout, reporting nothing else.
TEST_F(Cia402Loopback, ProbeReportsAnObjectTheDriveDoesNotAnswer) {
  FakeSdoServer drive(bus, 7, [](const CanFrame& req) -> std::optional<CanFrame> {
    const auto index = static_cast<std::uint16_t>(canopen::get_le(&req.data[1], 2));
    if (req.data[0] != 0x40 || index == 0x6502) return std::nullopt;
    if (index == 0x1000) return canopen::sdo_upload_ok(7, 0x1000, 0, 0x00020192, 4);
    return canopen::sdo_abort(7, index, req.data[3], 0x06020000, true);
  });
  auto cfg = test_config(7);
  cfg.sdo_timeout = 50ms;
  cfg.sdo_retries = 0;
  Cia402Drive client(cfg, factory());
  const Cia402Probe p = probe(client);
  ASSERT_NE(p.find(0x6502, 0), nullptr);
  EXPECT_NE(p.find(0x6502, 0)->no_answer.find("SDO read 0x6502:00: no reply"), std::string::npos) << p.find(0x6502, 0)->no_answer;
  ASSERT_NE(p.find(0x6064, 0), nullptr);  // the probe went on past it
  EXPECT_EQ(p.find(0x6064, 0)->abort_code, 0x06020000u);
  EXPECT_FALSE(p.usable);
  EXPECT_NE(p.report().find("no answer: CiA 402 drive node 7 on vcan0: SDO read 0x6502:00"), std::string::npos) << p.report();
}

// The probe on an SDO client of its own (what `hilbench drive probe` runs): the same report as
// through a CiA 402 client's, from the same requests, each an expedited upload (0x40) to 0x600 + node.
TEST_F(Cia402Loopback, ProbeOnAnSdoChannelOfItsOwnReadsAsThroughTheClient) {
  FakeSdoServer drive(bus, 7, [](const CanFrame& req) -> std::optional<CanFrame> {
    const auto index = static_cast<std::uint16_t>(canopen::get_le(&req.data[1], 2));
    if (index == 0x1000) return canopen::sdo_upload_ok(7, 0x1000, 0, 0x00020192, 4);
    if (index == 0x6502) return canopen::sdo_upload_ok(7, 0x6502, 0, 0x80, 4);  // CSP
    return canopen::sdo_abort(7, index, req.data[3], 0x06020000, true);
  });
  const auto cfg = test_config(7);
  std::string via_client;
  {
    Cia402Drive client(cfg, factory());
    via_client = probe(client).report();
  }
  const std::size_t client_requests = drive.requests().size();
  SdoChannel channel(cfg.interface,
                     {.node_id = 7, .who = "CiA 402 drive node 7 on vcan0", .timeout = cfg.sdo_timeout, .retries = 0}, factory());
  const Cia402Probe p = probe(channel.sdo(), cfg);
  EXPECT_EQ(p.report(), via_client);
  const std::vector<CanFrame> requests = drive.requests();
  ASSERT_EQ(requests.size(), 2 * client_requests);
  for (std::size_t i = client_requests; i < requests.size(); ++i) {
    EXPECT_EQ(requests[i].id, canopen::kSdoRx + 7u);
    EXPECT_EQ(requests[i].data[0], 0x40) << i;  // initiate upload
    EXPECT_EQ(
        std::vector<std::uint8_t>(requests[i].data.begin(), requests[i].data.begin() + 4),
        std::vector<std::uint8_t>(requests[i - client_requests].data.begin(), requests[i - client_requests].data.begin() + 4));
  }
  // Every object the drive refused is an abort the channel counted (no timeouts here).
  const auto refused = std::count_if(p.objects.begin(), p.objects.end(), [](const auto& o) { return !o.value.has_value(); });
  EXPECT_GT(refused, 0);
  EXPECT_EQ(channel.health().aborts_or_exceptions, static_cast<std::uint64_t>(refused));
}

TEST_F(Cia402Loopback, SyncFromTheLoopWhenConfigured) {
  auto cfg = test_config(6);
  cfg.sync_source = Cia402Config::SyncSource::loop;
  cfg.sync_period = std::chrono::milliseconds(50);  // the timer only covers setup; the loop is faster
  Rig r(factory(), cfg);
  r.client.configure();
  r.client.activate();
  const auto before = r.emulator.syncs_seen();
  for (int i = 0; i < 200; ++i) {
    r.client.write(Clock::now(), std::chrono::milliseconds(1), {0.3, true, false});
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  // 200 loop writes give far more SYNCs than the 50 ms timer could have.
  EXPECT_TRUE(eventually([&] { return r.emulator.syncs_seen() - before > 60; })) << r.emulator.syncs_seen() - before;
}

// Every controlword the client sends `node` in RPDO1, in bus order (the bus's tap, as candump
// would show them). Made before the Rig, so it outlives the client that feeds it.
class ControlwordLog {
 public:
  ControlwordLog(LoopbackBus& bus, std::uint8_t node) : bus_(bus) {
    bus_.set_tap([this, node](const CanFrame& f) {
      if (f.id != canopen::kRpdo1 + node || f.dlc < 2) return;
      std::lock_guard lock(mutex_);
      words_.push_back(static_cast<std::uint16_t>(canopen::get_le(&f.data[0], 2)));
    });
  }
  ~ControlwordLog() { bus_.set_tap({}); }
  std::size_t size() {
    std::lock_guard lock(mutex_);
    return words_.size();
  }
  std::vector<std::uint16_t> since(std::size_t from) {
    std::lock_guard lock(mutex_);
    return {words_.begin() + static_cast<std::ptrdiff_t>(std::min(from, words_.size())), words_.end()};
  }

 private:
  LoopbackBus& bus_;
  std::mutex mutex_;
  std::vector<std::uint16_t> words_;
};

// The controlwords sent in the next `window`, which must all be `want` (and there must be some).
void expect_only_controlword(ControlwordLog& log, std::uint16_t want, std::chrono::milliseconds window) {
  const std::size_t from = log.size();
  std::this_thread::sleep_for(window);
  const auto words = log.since(from);
  ASSERT_GT(words.size(), 10u);
  for (const std::uint16_t cw : words) ASSERT_EQ(cw, want) << "controlword 0x" << std::hex << cw;
}

// A fault reset asked for while the drive was healthy stayed armed and reset the next fault the
// moment it came: the drive was walked back to operation enabled (0x80, 0x06, 0x07, 0x0F) with
// nobody asking. Once the drive reports a fault the client sends disable voltage only, until an
// explicit request (here activate()).
TEST_F(Cia402Loopback, DriveFaultHoldsDisableVoltageUntilAnExplicitReset) {
  ControlwordLog log(bus, 5);
  Rig r(factory(), test_config(5));
  r.client.configure();
  r.client.activate();
  r.client.reset_fault();  // nothing to reset: must not stay armed
  std::this_thread::sleep_for(50ms);
  r.emulator.raise_emcy(0x2310, 0x02);
  ASSERT_TRUE(eventually([&] { return r.client.state() == cia402::State::fault; }));
  expect_only_controlword(log, cia402::kCwDisableVoltage, 300ms);
  EXPECT_EQ(r.emulator.state(), cia402::State::fault);
  r.client.activate();  // the explicit request: one reset, then enabled again
  EXPECT_EQ(r.client.state(), cia402::State::operation_enabled);
  EXPECT_FALSE(r.client.read(Clock::now(), 1ms).fault) << r.client.health().last_error_text();
}

// The client latches a fault of its own (here the heartbeat lost; the drive still answers
// every SYNC): it used to keep sending enable operation, and after the heartbeat came back the
// drive ran on as if nothing had happened. Now it quick-stops the drive and holds it disabled
// after the heartbeat resumes, until activate().
TEST_F(Cia402Loopback, HeartbeatLossStopsTheEnableSequenceUntilActivate) {
  ControlwordLog log(bus, 5);
  auto cfg = test_config(5);
  cfg.heartbeat_timeout = 300ms;
  Rig r(factory(), cfg);
  r.client.configure();
  r.client.activate();
  r.emulator.stop_heartbeat(true);
  ASSERT_TRUE(eventually([&] { return r.client.health().heartbeat_lost; }));
  EXPECT_TRUE(eventually([&] { return r.emulator.state() == cia402::State::switch_on_disabled; }, 5s))
      << cia402::to_string(r.emulator.state());
  r.emulator.stop_heartbeat(false);
  ASSERT_TRUE(eventually([&] { return !r.client.health().heartbeat_lost; }));
  expect_only_controlword(log, cia402::kCwDisableVoltage, 300ms);
  EXPECT_EQ(r.emulator.state(), cia402::State::switch_on_disabled);
  r.client.activate();
  EXPECT_EQ(r.client.state(), cia402::State::operation_enabled);
}

// A TPDO1 as the drive sends it, with `counts` as the position actual value.
CanFrame tpdo1(std::uint8_t node, std::uint16_t statusword, std::int32_t counts) {
  CanFrame f;
  f.id = canopen::kTpdo1 + node;
  f.dlc = 6;
  canopen::put_le(&f.data[0], statusword, 2);
  canopen::put_le(&f.data[2], static_cast<std::uint32_t>(counts), 4);
  return f;
}

// 0x6064 wrapping from near INT32_MAX to near INT32_MIN (or any step no drive makes in one
// period) was taken as a real move of thousands of revolutions. Now it is a fault naming the
// jump, the position keeps its last trusted value, the drive is quick-stopped, and only
// configure() (which reads the position afresh) clears it.
TEST_F(Cia402Loopback, PositionWrapIsAFaultNotAMove) {
  Rig r(factory(), test_config(5));
  r.client.configure();
  r.client.activate();
  const double before_rad = r.client.read(Clock::now(), 1ms).position_rad;
  // Near the top of the range: a legal step without a velocity limit (less than half the range).
  const std::uint16_t enabled = r.client.read(Clock::now(), 1ms).statusword;
  bus.inject(tpdo1(5, enabled, INT32_MAX - 100));
  bus.inject(tpdo1(5, enabled, INT32_MIN + 100));  // the wrap
  ASSERT_TRUE(eventually([&] { return r.client.health().fault; }, 5s));
  const std::string text(r.client.health().last_error_text());
  EXPECT_NE(text.find("node 5 on vcan0: position jump: 0x6064 from "), std::string::npos) << text;
  EXPECT_NE(text.find("(int32 wrap)"), std::string::npos) << text;
  const auto fb = r.client.read(Clock::now(), 1ms);
  EXPECT_TRUE(fb.fault);
  EXPECT_GT(fb.position_rad, 0.0) << "the wrapped count (about -3.3e5 rad) was published as the position";
  EXPECT_TRUE(eventually([&] { return r.emulator.state() == cia402::State::switch_on_disabled; }, 5s));
  r.client.configure();
  EXPECT_FALSE(r.client.health().fault) << r.client.health().last_error_text();
  EXPECT_NEAR(r.client.read(Clock::now(), 1ms).position_rad, before_rad, 1e-2);
}

// With max_profile_velocity configured, a step far beyond what that speed covers in a period is
// caught even when it is no wrap; ordinary motion at that speed is not.
TEST_F(Cia402Loopback, PositionStepBeyondTheVelocityLimitIsAFault) {
  auto cfg = test_config(5);
  cfg.limits.max_profile_velocity_rad_s = 40.0;  // the drive's limit; the test model runs at most 20 rad/s
  Rig r(factory(), cfg);
  r.client.configure();
  r.client.activate();
  {
    TestLoop loop(r.client);
    loop.target_rad = 2.0;  // 1.75 rad, mostly at the model's full 20 rad/s
    ASSERT_TRUE(eventually([&] { return std::abs(loop.position_rad.load() - 2.0) < 1e-2; }, 5s));
  }
  EXPECT_FALSE(r.client.health().fault) << r.client.health().last_error_text();
  const auto fb = r.client.read(Clock::now(), 1ms);
  // One revolution of the valve (40960 counts) between two TPDOs: 6.3 rad where 0.3 is the most.
  bus.inject(tpdo1(5, fb.statusword, cfg.units.to_counts(fb.position_rad) + 40960));
  ASSERT_TRUE(eventually([&] { return r.client.health().fault; }, 5s));
  const std::string text(r.client.health().last_error_text());
  EXPECT_NE(text.find("position jump"), std::string::npos) << text;
  EXPECT_EQ(text.find("int32 wrap"), std::string::npos) << text;
  EXPECT_NEAR(r.client.read(Clock::now(), 1ms).position_rad, fb.position_rad, 1e-2);
}

// configure() reads 0x6064 by SDO so that the loop starts by holding where the motor is; the
// first TPDO after NMT start was then taken unchecked, so a corrupt or wrapped first count became
// the position. It is checked against that read now: configure() fails naming the jump, and the
// position stays the one read.
TEST_F(Cia402Loopback, FirstTpdoIsCheckedAgainstThePositionReadBySdo) {
  auto cfg = test_config(5);
  cfg.limits.max_profile_velocity_rad_s = 40.0;
  Rig r(factory(), cfg);
  const auto read_counts = static_cast<std::int32_t>(r.emulator.object(0x6064, 0).value());
  std::atomic<bool> started{false};
  bus.set_tap([&](const CanFrame& f) {
    // The client's NMT start: the drive falls silent before it sees it, so the first TPDO is ours.
    if (f.id == 0 && f.dlc >= 2 && f.data[0] == 0x01 && f.data[1] == 5 && !started.exchange(true)) r.emulator.set_silent(true);
  });
  std::thread corrupt_drive([&] {
    if (!eventually([&] { return started.load(); }, 10s)) return;
    bus.inject(canopen::heartbeat(5, canopen::NmtState::operational));
    // Ten valve revolutions from the read: 63 rad, where 40 rad/s covers 0.3 rad a few ms later.
    bus.inject(tpdo1(5, 0x0250, read_counts + 10 * 40960));
  });
  try {
    r.client.configure();
    ADD_FAILURE() << "configure() took a first TPDO 10 revolutions from the position it had read";
  } catch (const DriveError& e) {
    const std::string text = e.what();
    EXPECT_NE(text.find("node 5 on vcan0: the first TPDO's 0x6064 is not the position read by SDO just before"),
              std::string::npos)
        << text;
    EXPECT_NE(text.find("position jump: 0x6064 from " + std::to_string(read_counts) + " to " +
                        std::to_string(read_counts + 10 * 40960) + " counts"),
              std::string::npos)
        << text;
  }
  corrupt_drive.join();
  EXPECT_TRUE(started);
  EXPECT_TRUE(r.client.health().fault);
  EXPECT_NEAR(r.client.read(Clock::now(), 1ms).position_rad, cfg.units.to_rad(read_counts), 1e-9);
  bus.set_tap({});
  r.emulator.set_silent(false);
  r.client.configure();  // the drive answers for itself again: its first TPDO agrees with the read
  EXPECT_FALSE(r.client.health().fault) << r.client.health().last_error_text();
  EXPECT_NEAR(r.client.read(Clock::now(), 1ms).position_rad, cfg.units.to_rad(read_counts), 1e-2);
}

// configure() and activate() each wait up to their timeouts (here 600 s) for a drive that does
// not answer; an operator's abort could not cut them short. cancel_setup() from another thread
// ends the one in progress within a poll, and the enable sequence does not go on behind it.
TEST_F(Cia402Loopback, CancelEndsASetupCallWithinAPoll) {
  const auto cancelled_within = [](Cia402Drive& client, auto&& setup_call, const std::string& want) {
    std::thread canceller([&] {
      std::this_thread::sleep_for(200ms);
      client.cancel_setup();
    });
    const auto t0 = Clock::now();
    try {
      setup_call();
      ADD_FAILURE() << "not cancelled";
    } catch (const DriveError& e) {
      EXPECT_NE(std::string(e.what()).find(want), std::string::npos) << e.what();
    }
    canceller.join();
    return Clock::now() - t0;
  };
  auto cfg = test_config(9);
  cfg.boot_timeout = 600s;
  {
    Cia402Drive client(cfg, factory());  // nobody at node 9: configure() waits for a boot-up
    const auto took = cancelled_within(
        client, [&] { client.configure(); }, "node 9 on vcan0: configure() cancelled");
    EXPECT_LT(took, 2s);                           // 200 ms, and a loaded machine's slack; not 600 s
    EXPECT_THROW(client.configure(), DriveError);  // given up: no later setup call waits either
  }
  cfg = test_config(5);
  cfg.transition_timeout = 600s;
  ControlwordLog log(bus, 5);
  Rig r(factory(), cfg);
  r.client.configure();
  r.emulator.set_silent(true);  // activate() waits for a statusword that never comes
  const auto took = cancelled_within(
      r.client, [&] { r.client.activate(); }, "node 5 on vcan0: activate() cancelled");
  EXPECT_LT(took, 2s);
  r.emulator.set_silent(false);
  ASSERT_TRUE(eventually([&] { return r.client.read(Clock::now(), 1ms).statusword != 0; }));
  expect_only_controlword(log, cia402::kCwDisableVoltage, 200ms);
}

// CiA 301: a PDO mapping's count is checked when it is written; every entry it counts must map an
// object. The emulator took a count over entries that map nothing (0, the default of subs 2..8),
// and its next RPDO (or SYNC, for a TPDO) looked up object 0x0000:00 and threw out of its I/O
// thread: std::terminate, the whole `hilbench plant` gone, from a frame any node may send.
TEST_F(Cia402Loopback, EmulatorRefusesAMappingCountOverEntriesThatMapNothing) {
  FirstOrderServoTestModel model{0.01, 20.0, 0.25};
  Cia402DriveEmulator emulator(Rig::emulator_config(test_config(5), {}), model, factory());
  Cia402Drive client(test_config(5), factory());
  ASSERT_TRUE(eventually([&] { return emulator.nmt_state() == canopen::NmtState::pre_operational; }));
  const auto refused = [&](std::uint16_t index, std::uint32_t count) -> std::uint32_t {
    try {
      client.sdo_write(index, 0, count, 1);
    } catch (const SdoAbortError& e) {
      return e.code;
    }
    return 0;
  };
  for (std::uint16_t comm : {0x1400, 0x1800}) {  // RPDO1, TPDO1: invalid while remapped
    client.sdo_write(comm, 1, canopen::kCobIdInvalid | (comm == 0x1400 ? 0x205u : 0x185u), 4);
    const auto map = static_cast<std::uint16_t>(comm + 0x200);
    client.sdo_write(map, 0, 0, 1);
    EXPECT_EQ(refused(map, 2), 0x06040041u) << std::hex << map << ": sub 2 maps nothing";
    EXPECT_EQ(refused(map, 1), 0u) << std::hex << map << ": sub 1 maps the controlword/statusword";
    EXPECT_EQ(emulator.object(map, 0), 1u);
    client.sdo_write(comm, 1, comm == 0x1400 ? 0x205u : 0x185u, 4);
    client.sdo_write(comm, 2, 1, 1);  // synchronous
  }
  // The PDOs run with what was accepted: an RPDO applied at the next SYNC, a TPDO sent for it.
  std::atomic<int> tpdos{0};
  bus.set_tap([&](const CanFrame& f) {
    if (f.id == 0x185) ++tpdos;
  });
  client.nmt(canopen::NmtCommand::start);
  ASSERT_TRUE(eventually([&] { return emulator.nmt_state() == canopen::NmtState::operational; }));
  CanFrame rpdo;
  rpdo.id = 0x205;
  rpdo.dlc = 8;
  canopen::put_le(rpdo.data.data(), 0x0006, 2);  // shutdown
  bus.inject(rpdo);
  CanFrame sync;
  sync.id = canopen::kSync;
  bus.inject(sync);
  EXPECT_TRUE(eventually([&] { return tpdos.load() > 0; }));
  EXPECT_EQ(emulator.object(0x6040, 0), 0x0006u);  // and the emulator is still there to answer
}

// CiA 301: no PDO on a restricted CAN-ID. The emulator took any: a TPDO moved to 0x000 reaches
// every node at each SYNC as an NMT command (its first two bytes read as command and node), one
// on 0x705 speaks as node 5's heartbeat, one on 0x585 as its SDO replies.
TEST_F(Cia402Loopback, EmulatorRefusesAPdoOnARestrictedCanId) {
  FirstOrderServoTestModel model{0.01, 20.0, 0.25};
  Cia402DriveEmulator emulator(Rig::emulator_config(test_config(5), {}), model, factory());
  Cia402Drive client(test_config(5), factory());
  ASSERT_TRUE(eventually([&] { return emulator.nmt_state() == canopen::NmtState::pre_operational; }));
  client.sdo_write(0x1800, 1, canopen::kCobIdInvalid | 0x185u, 4);
  for (std::uint32_t cob : {0x000u, 0x005u, 0x605u, 0x585u, 0x705u, 0x7E5u, canopen::kCobIdExtended | 0x285u}) {
    try {
      client.sdo_write(0x1800, 1, cob, 4);
      ADD_FAILURE() << "TPDO1 on " << std::hex << cob << " was taken";
    } catch (const SdoAbortError& e) {
      EXPECT_EQ(e.code, 0x06090030u) << std::hex << cob;  // value range of parameter exceeded
    }
  }
  EXPECT_EQ(emulator.object(0x1800, 1), canopen::kCobIdInvalid | 0x185u);
  client.sdo_write(0x1800, 1, 0x285u, 4);  // a free id is taken
  EXPECT_EQ(emulator.object(0x1800, 1), 0x285u);
}

}  // namespace
}  // namespace hil::drv::test

namespace hil::drv::test {

// Issue 38 item 11: the drive file's example window of 0.5 deg with a 10 ms drive lag and targets
// shaped to 60 deg/s at a 2 ms SYNC is a following error of 60 x 0.012 = 0.72 deg on shaping
// alone: configure() refuses it, saying so with the numbers, whether the window is the file's or
// the drive's own; the probe says the same and calls the drive not usable. A window wide enough
// (1 deg) passes.
TEST_F(Cia402Loopback, AFollowingErrorWindowTheShapingWouldExceedIsRefusedWithTheNumbers) {
  constexpr double kDeg = 3.14159265358979323846 / 180;
  auto cfg = test_config(5);
  cfg.units = {36000, 1.0, 1};  // 100 counts per degree: 0.5 deg is a whole count
  cfg.sync_period = 2ms;
  cfg.limits.drive_lag = 10ms;
  cfg.target_velocity_rad_s = 60 * kDeg;
  const std::string want =
      "following error window 0x6065 = 0.5 deg is narrower than the following error the bench's targets make by "
      "themselves: 60 deg/s x (10 ms drive lag + 2 ms SYNC period) = 0.72 deg";
  EXPECT_NE(following_window_problem(cfg, 0.5 * kDeg).find(want), std::string::npos) << following_window_problem(cfg, 0.5 * kDeg);
  EXPECT_EQ(following_window_problem(cfg, 1.0 * kDeg), "");
  auto unknown_lag = cfg;
  unknown_lag.limits.drive_lag = 0ms;
  // Issue 50: an unknown lag is not taken as 0 (which passed 0.5 deg at 2 ms): refused, saying what to add.
  for (const double window_deg : {0.1, 0.5, 10.0}) {
    const std::string text = following_window_problem(unknown_lag, window_deg * kDeg);
    EXPECT_NE(text.find("cannot be checked against the bench's targets: the drive's lag is unknown, and at 60 deg/s each 10 ms "
                        "of it takes 0.6 deg of the window; add limits.drive_lag_ms"),
              std::string::npos)
        << text;
  }
  const auto following = [](Cia402EmulatorConfig& e) { e.following_error = true; };
  {  // the file's window
    auto c = cfg;
    c.limits.following_error_window_rad = 0.5 * kDeg;
    Rig r(factory(), c, following);
    const Cia402Probe p = probe(r.client);
    EXPECT_FALSE(p.usable);
    EXPECT_NE(p.report().find("configure() will refuse: " + want), std::string::npos) << p.report();
    try {
      r.client.configure();
      ADD_FAILURE() << "configured with a window the shaping exceeds";
    } catch (const DriveError& e) {
      EXPECT_NE(std::string(e.what()).find("node 5 on vcan0: " + want), std::string::npos) << e.what();
    }
  }
  {  // the drive's own window (the file sets none)
    Rig r(factory(), cfg, following);
    r.client.sdo_write(0x6065, 0, static_cast<std::uint32_t>(std::lround(0.5 * kDeg / cfg.units.rad_per_count())), 4);
    EXPECT_FALSE(probe(r.client).usable);
    EXPECT_THROW(r.client.configure(), DriveError);
  }
  {  // wide enough
    auto c = cfg;
    c.limits.following_error_window_rad = 1.0 * kDeg;
    Rig r(factory(), c, following);
    EXPECT_TRUE(probe(r.client).usable) << probe(r.client).report();
    r.client.configure();
  }
}

}  // namespace hil::drv::test

namespace hil::drv::test {

// Issue 38 item 12: the unused PDOs are made invalid with bit 31 of the drive's own COB-IDs
// (bits 29/30 and the id kept), not the predefined connection set's id with bit 31; and 0x1006
// communication cycle period holds the SYNC period in us.
TEST_F(Cia402Loopback, UnusedPdosAreInvalidatedWithTheirOwnCobIdAnd0x1006IsTheSyncPeriod) {
  Rig r(factory(), test_config(5), [](Cia402EmulatorConfig& e) { e.own_pdo_ids = true; });
  EXPECT_EQ(r.emulator.object(0x1401, 1), 0x525u);
  r.client.configure();
  for (std::uint32_t k = 1; k <= 3; ++k) {
    EXPECT_EQ(r.emulator.object(static_cast<std::uint16_t>(0x1400 + k), 1), 0x80000000u | (0x500u + 0x20u * k + 5)) << k;
    EXPECT_EQ(r.emulator.object(static_cast<std::uint16_t>(0x1800 + k), 1), 0xC0000000u | (0x480u + 0x20u * k + 5)) << k;
  }
  EXPECT_EQ(r.emulator.object(0x1006, 0), 2000u);  // test_config: a 2 ms SYNC
  EXPECT_TRUE(r.client.configure_notes().empty()) << r.client.configure_notes().front();
}

// Issue 38 item 12 (and 10): a drive with node guarding instead of a heartbeat (CiA 301 allows
// either). The probe calls it usable; configure() writes guard time 0x100C and life time factor
// 0x100D, sends a guarding request (a remote frame on 0x705) every guard time and watches the
// replies (state + toggle bit) as the heartbeat; the drive's life guarding watches the bench, so a
// client that dies puts the drive into quick stop (0x6007 = 3) after guard time x factor.
TEST_F(Cia402Loopback, NodeGuardingInPlaceOfTheHeartbeatBothWays) {
  std::mutex mutex;
  std::vector<CanFrame> guarding;
  bus.set_tap([&](const CanFrame& f) {
    if (f.id != canopen::kHeartbeat + 5) return;
    std::lock_guard lock(mutex);
    guarding.push_back(f);
  });
  auto cfg = test_config(5);
  cfg.node_guarding = {50ms, 12};  // the drive watches the bench for 600 ms
  FirstOrderServoTestModel model{0.01, 20.0, 0.25};
  Cia402EmulatorConfig ecfg = Rig::emulator_config(cfg, {});
  ecfg.node_guarding = true;
  Cia402DriveEmulator emulator(ecfg, model, factory());
  auto client = std::make_unique<Cia402Drive>(cfg, factory());
  const Cia402Probe p = probe(*client);
  EXPECT_TRUE(p.usable) << p.report();
  EXPECT_NE(p.report().find("node guarding in place of the heartbeat it lacks: 0x100C = 50 ms, 0x100D = 12"), std::string::npos)
      << p.report();
  client->configure();
  EXPECT_EQ(emulator.object(0x100C, 0), 50u);
  EXPECT_EQ(emulator.object(0x100D, 0), 12u);
  EXPECT_FALSE(emulator.object(0x1017, 0).has_value());
  ASSERT_FALSE(client->configure_notes().empty());
  EXPECT_NE(client->configure_notes().front().find("0x1017:00 absent: node guarding instead"), std::string::npos);
  client->activate();
  {
    TestLoop loop(*client);
    loop.target_rad = 0.3;
    ASSERT_TRUE(eventually([&] { return std::abs(loop.position_rad - 0.3) < 1e-3; }));
    EXPECT_FALSE(client->health().fault) << client->health().last_error_text();
    EXPECT_EQ(client->health().nmt_state, 0x05);
    EXPECT_EQ(emulator.heartbeat_consumer_events(), 0u);
    // Counted, not timed: at least six requests answered while the loop runs.
    EXPECT_TRUE(eventually([&] {
      std::lock_guard lock(mutex);
      return std::count_if(guarding.begin(), guarding.end(), [](const CanFrame& f) { return !f.rtr; }) >= 8;
    }));
  }
  {
    // Requests are remote frames of length 1; replies one byte: toggle bit 7 alternating from 0
    // after the reset communication, then the NMT state.
    std::lock_guard lock(mutex);
    int requests = 0, replies = 0;
    bool toggle = false, seen_start = false;
    for (const auto& f : guarding) {
      if (f.rtr) {
        ++requests;
        EXPECT_EQ(f.dlc, 1);
        continue;
      }
      if (f.data[0] == 0x00) {  // the boot-up message of the reset: the toggle starts at 0
        seen_start = true, toggle = false, replies = 0;
        continue;
      }
      if (!seen_start) continue;
      ++replies;
      EXPECT_EQ((f.data[0] & 0x80) != 0, toggle) << "reply " << replies;
      toggle = !toggle;
    }
    EXPECT_GT(requests, 5);
    EXPECT_GT(replies, 5);
  }
  bus.set_tap({});
  client.reset();  // the bench dies
  ASSERT_TRUE(eventually([&] { return emulator.heartbeat_consumer_events() > 0; }, 20s));
  const auto event = emulator.last_consumer_event();
  ASSERT_TRUE(event.has_value());
  EXPECT_GE(event->silence, 600ms);
  EXPECT_EQ(event->state_after, cia402::State::switch_on_disabled) << cia402::to_string(event->state_after);
}

}  // namespace hil::drv::test

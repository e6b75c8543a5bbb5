// The CAN rig on a real vcan0 (run by tests/drivers/vcan/run-on-vcan.sh: on the host where the
// kernel has CAN, else inside the qemu VM): paper_adaptive through `hilbench serve` against
// `hilbench plant` (the CiA 402 emulator on vcan0, the transducer on loopback TCP), and the CAN
// fault scenarios of rig_fault_scenarios.hpp on SocketCAN instead of the loopback bus. candump
// (can-utils) watches the bus as the independent peer during the end-to-end run.
//
// Options after the gtest ones: --period-ms=X sets the campaigns' dT (default 1).
//
// What the VM can do. Inside qemu (TCG: no KVM here, 2 vCPUs on this 2-core machine) the whole
// chain (hilbench serve's loop and recorder, the CAN client, the CiA 402 emulator, the plant
// stepping every 1 ms, the Modbus transducer client and emulator) does not keep a 1 kHz loop.
// paper_adaptive through serve, alone on the machine, status polled every 0.5 s (2026-11-21):
//   dT 1 ms: 10-20 % of the periods stale, ~1 % overruns and 2 % skipped deadlines, wake-up p99
//            0.7 ms, max 5-8 ms, compute p99 140-180 us; one run of two tripped its 20-period
//            watchdog, the other ended 3.2 % RMS off the simulation.
//   dT 2 ms: 1-1.5 % stale, 0.3-0.5 % overruns, wake-up p99 0.8 ms; 0.8-1.1 % RMS.
//   dT 5 ms: no overrun, 0.5 % stale; 1.2-2.1 % RMS: CANopen's own delay weighs more: a TPDO
//            samples the drive at the SYNC that follows the previous command, so the loop reads
//            an encoder angle one period old, where the lock-step simulation has none (on the
//            host, without the VM, the same chain gives 0.6 % at 1 ms, 1.2 % at 5 ms, 1.9 % at 10 ms).
// On a shared machine under load none of these periods is held for sure, so the trace is checked
// in lock-step (simulated time, LockstepMatchesTheSimulation), and the real-time run through
// serve checks what the protocol guarantees at any speed. ctest runs this suite with
// --period-ms=2 and alone (RUN_SERIAL: a second VM beside it starves TCG). Real-time figures:
// docs/benchmarks.md (bench_rt_loop --can).
#include <gtest/gtest.h>

#include <cstring>

#include <boost/asio/io_context.hpp>

#include "hil/drv/canopen.hpp"
#include "hil/drv/socketcan.hpp"
#include "servo_test_model.hpp"
#include "lockstep.hpp"
#include "rig_fault_scenarios.hpp"
#include "serve_e2e.hpp"

using namespace hil;
using namespace hil::test;

namespace {

double g_period_ms = 1.0;

bool have_vcan0() { return std::filesystem::exists("/sys/class/net/vcan0"); }

}  // namespace

// Trace equivalence on a real vcan0, in simulated time (lockstep.hpp): the bench's loop, the CAN
// rig's SocketCAN client, the CiA 402 emulator on its own SocketCAN socket, the Modbus transducer
// over TCP and the plant step in lock-step, so the result is the same on a loaded machine and in
// TCG. A third socket sends the extra SYNC that asks the drive for its new position.
TEST(VcanCanRig, LockstepMatchesTheSimulation) {
  ASSERT_TRUE(have_vcan0()) << "run me with tests/drivers/vcan/run-on-vcan.sh";
  const auto campaign = short_paper_campaign(8, 6.0, g_period_ms);  // reversals at 2.5, 5, 7.5 s; the gap grows at 6 s
  boost::asio::io_context io;
  const auto syncer = drv::SocketCanTransport::factory("vcan0")(io, {{0x7FE, 0x7FF}});  // sends; receives next to nothing
  LockstepSide side(campaign, {}, [&] { syncer->send(drv::canopen::sync()); });
  const LockstepResult r = run_lockstep(campaign, "adaptive", side, lockstep_can_rig_yaml(side), {});
  ASSERT_TRUE(r.error.empty()) << r.error;
  EXPECT_EQ(r.end, bench::LoopEnd::completed);
  ASSERT_EQ(r.rows.size(), static_cast<std::size_t>(std::lround(campaign.duration_s / campaign.period_s)));
  EXPECT_EQ(r.missed, 0) << r.first_miss;
  const LockstepDiff d = compare_lockstep(campaign, "adaptive", r.rows);
  std::printf(
      "CAN rig in lock-step on vcan0: %zu periods in %.1f s wall; pressure RMS difference to the simulation %.3f kPa = "
      "%.4f %% of the range (max %.3f kPa)\n",
      r.rows.size(), r.wall_s, d.p_rms_pa * 1e-3, d.percent, d.p_max_abs_pa * 1e-3);
  EXPECT_LT(d.percent, 0.2);
}

// The same campaign end to end in real time: `hilbench serve` against `hilbench plant` (two
// processes), candump as the independent peer. Real time in a VM on a shared machine holds no
// period for sure, so this checks what the protocol guarantees whatever the load: the run
// completes (the watchdog out of the way, the devices' timeouts at 2 s: at load 10 the VM stalls
// the loop for more than 0.5 s, 86 % of the periods stale), every row is on disk, one RPDO1 goes out with each SYNC and the drive answers each
// SYNC with one TPDO1. The trace is printed; its equivalence with the simulation is the
// lock-step test above.
// The number after `key` in `text` (-1 when absent): "hung for 1502 ms" -> 1502.
static long number_after(const std::string& text, const std::string& key) {
  const auto at = text.find(key);
  return at == std::string::npos ? -1 : std::atol(text.c_str() + at + key.size());
}

TEST(VcanCanRig, PaperAdaptiveThroughServeEndToEnd) {
  ASSERT_TRUE(have_vcan0()) << "run me with tests/drivers/vcan/run-on-vcan.sh";
  TempDir dir;
  const auto dump = dir.path() / "candump.log";
  const pid_t candump = spawn({"/usr/bin/candump", "-t", "z", "vcan0"}, dump);
  RigOptions o;
  o.watchdog_misses = 1000000;  // never within the run: stalls of the loaded VM are not under test here
  o.loop_extra = "target_shaping: {max_velocity_deg_s: 60, max_acceleration_deg_s2: 30000}";  // as the shipped rigs
  const ServeResult r = serve_paper_adaptive(
      g_period_ms, {"--can", "vcan0", "--modbus", "tcp:127.0.0.1:0", "--period-ms", "1"},
      [&](const PlantProcess& p) {
        // A device's own timeouts as generous as the watchdog: a reply 100 ms late in a loaded VM is
        // the machine, not the device (the fault tests check those timeouts).
        return rig_yaml("can", can_drive_yaml("vcan0", "recover", 2000),
                        modbus_device_yaml(p.transducer_port(), "modbus_transducer_map.yaml", 4, 2000), o);
      },
      /*may_abort=*/true);
  kill(candump, SIGTERM);
  wait_exit(candump, std::chrono::seconds(5));
  EXPECT_EQ(r.run["rig"]["kind"], "can");
  // Issue 50: a VM that cannot keep the period may stall the whole bench past the drive's consumer
  // time (its 0x1016), and the drive then quick-stops as configured. That run ends aborted, and
  // only with the bench's own stall named, truthfully: its heartbeat gap longer than the time the
  // drive gives it, or a loop hang longer than the bench allows. Anything else fails, as does a
  // run that ended otherwise.
  if (r.outcome != "completed") {
    ASSERT_EQ(r.outcome, "aborted") << r.reason;
    const long late_ms = number_after(r.reason, "the bench's heartbeat was ");
    const long allowed_ms = number_after(r.reason, "ms late (0x1016 gives the drive ");
    const long hung_ms = number_after(r.reason, "control loop hung for ");
    ASSERT_TRUE((late_ms > 0 && r.reason.find("): the host stalled") != std::string::npos) || hung_ms > 0) << r.reason;
    if (late_ms > 0) {
      EXPECT_GT(allowed_ms, 0) << r.reason;
      EXPECT_GT(late_ms, allowed_ms) << r.reason;
      EXPECT_NE(r.reason.find("EMCY 0x8130: the drive lost the bench's heartbeat"), std::string::npos) << r.reason;
    }
    if (hung_ms > 0) {
      EXPECT_GE(r.run["trip"]["longest_gap_ms"].get<double>(), number_after(r.reason, "(the bench allows ")) << r.reason;
    }
    std::printf("the loaded VM stalled the bench: the run aborted naming it: %s\n", r.reason.c_str());
    return;
  }
  // The bus carried the loop: SYNC (0x080), RPDO1 (0x205: controlword + target), TPDO1 (0x185).
  const std::string frames = slurp(dump);
  long sync = 0, rpdo = 0, tpdo = 0;
  // Issue 38 item 11: between consecutive targets on the bus (RPDO1 with enable operation, 0x0F)
  // the step stays within the shaping's 60 deg/s x one 2 ms SYNC period (+1 count of rounding),
  // however many periods the loaded VM made the loop skip or write twice before one SYNC.
  const double limit_counts = 60.0 * (g_period_ms / 1000.0) / 360.0 * 131072 + 1;
  long enabled_targets = 0;
  double largest_step = 0;
  bool have_previous = false;
  std::int32_t previous = 0;
  std::istringstream in(frames);
  for (std::string line; std::getline(in, line);) {
    sync += line.find("  080   [0]") != std::string::npos;
    tpdo += line.find("  185   [6]") != std::string::npos;
    const auto at = line.find("  205   [6]");
    if (at == std::string::npos) continue;
    ++rpdo;
    std::istringstream bytes(line.substr(at + 11));
    int b[6] = {};
    for (int& x : b) bytes >> std::hex >> x;
    if ((b[0] | b[1] << 8) != 0x0F) {
      have_previous = false;
      continue;
    }
    const auto target = static_cast<std::int32_t>(static_cast<std::uint32_t>(b[2] | b[3] << 8 | b[4] << 16) |
                                                  static_cast<std::uint32_t>(b[5]) << 24);
    if (have_previous) largest_step = std::max(largest_step, std::abs(static_cast<double>(target) - previous));
    previous = target;
    have_previous = true;
    ++enabled_targets;
  }
  std::printf(
      "candump: %ld targets with enable operation; largest step between two on the bus %.0f counts (limit %.1f: "
      "60 deg/s x %.3g ms)\n",
      enabled_targets, largest_step, limit_counts, g_period_ms);
  EXPECT_GT(enabled_targets, 1000);
  EXPECT_LE(largest_step, limit_counts);
  const long periods = r.run["periods_run"].get<long>();
  std::printf("candump on vcan0: %ld SYNC, %ld RPDO1, %ld TPDO1 for %ld loop periods\n", sync, rpdo, tpdo, periods);
  EXPECT_GT(sync, 0);
  // Each tick sends RPDO1 then SYNC (candump may stop between the two).
  EXPECT_LE(std::abs(rpdo - sync), 1);
  // The drive answers every SYNC it sees while operational: all but those before NMT start and
  // the last few in flight when candump stopped.
  EXPECT_LE(tpdo, sync);
  EXPECT_GE(tpdo, sync - 20);
}

// Issue 41: a campaign's checks as a CI job runs them on the hybrid rig (the drive on vcan0, the
// backlash and chamber simulated by the bench): `hilbench ctl start ... --junit FILE` against
// `hilbench serve`, paper_adaptive's adaptive run with its shipped checks and one more set to fail
// (IAE at most 0). The command exits 3 and the JUnit XML has one testcase per check with the
// verdicts run.json has. The XML is printed between HIL-JUNIT markers: the VM has no Python, so
// tests/hil/vcan_junit_check.sh reads it on the host with Debian's python3-junitparser.
// Measured 2026-12-02 in the VM at load ~20: 57 s; 8 verdicts (3 failed: set_to_fail and, at that
// load, the gap-estimate and pressure-settling claims; 2 skipped: stall_vs_none without `none`).
TEST(VcanHybridRig, ChecksBecomeJunitAndACheckSetToFailFailsTheCommand) {
  ASSERT_TRUE(have_vcan0()) << "run me with tests/drivers/vcan/run-on-vcan.sh";
  TempDir configs;
  std::filesystem::create_symlink(source_path("configs/plant"), configs.path() / "plant");
  std::string yaml = paper_adaptive_yaml(g_period_ms);
  ASSERT_TRUE(yaml.ends_with("    max: 0\n")) << "paper_adaptive.yaml's checks are no longer its last block";
  yaml += "  - {name: set_to_fail, runs: [adaptive], metric: iae_mpa_s, max: 0}\n";
  const auto campaign_file = configs.write("campaigns/paper_adaptive.yaml", yaml);
  const bench::Campaign campaign = bench::load_campaign(campaign_file);
  SimulatorSide side(campaign, {}, "vcan0");  // its CiA 402 emulator is the drive; the rig simulates the rest
  RigOptions o;
  o.watchdog_misses = 1000000;  // the loaded VM's stalls are not under test
  o.loop_extra = "target_shaping: {max_velocity_deg_s: 60, max_acceleration_deg_s2: 30000}";  // as configs/rigs/hybrid.yaml
  configs.write("rigs/hybrid_vcan.yaml", rig_yaml("hybrid", can_drive_yaml("vcan0", "recover", 2000), "", o));
  ServerProcess server({"--configs", configs.path().string()});
  const auto junit = configs.path() / "out" / "junit.xml";
  const auto log = configs.path() / "ctl.log";
  const pid_t ctl = spawn({hilbench_exe(), "ctl", "--server", "http://127.0.0.1:" + std::to_string(server.port()), "start",
                           "paper_adaptive", "--rig", "hybrid_vcan", "--runs", "adaptive", "--junit", junit.string()},
                          log);
  const auto rc = wait_exit(ctl, std::chrono::seconds(static_cast<long>(campaign.duration_s * 3 + 60)));
  if (!rc) kill(ctl, SIGKILL);
  ASSERT_TRUE(rc.has_value()) << slurp(log);
  EXPECT_EQ(*rc, 3) << slurp(log);
  EXPECT_NE(slurp(log).find("check(s) failed"), std::string::npos) << slurp(log);
  const RunFiles f(only_run(server.runs_dir()));
  EXPECT_EQ(f.run["rig"]["kind"], "hybrid");
  const auto& checks = f.run["checks"];
  ASSERT_TRUE(checks.is_object()) << f.run.dump(2);
  const long passed = checks["passed"], failed = checks["failed"], skipped = checks["skipped"];
  EXPECT_GE(failed, 1);
  bool set_to_fail_failed = false;
  for (const auto& c : checks["results"]) set_to_fail_failed |= c["check"] == "set_to_fail" && c["verdict"] == "fail";
  EXPECT_TRUE(set_to_fail_failed) << checks.dump(2);
  const std::string xml = slurp(junit);
  ASSERT_FALSE(xml.empty()) << slurp(log);
  // For the host's junitparser check: what the XML must hold, then the XML itself.
  std::printf("HIL-JUNIT-BEGIN tests=%ld failures=%ld skipped=%ld failing=set_to_fail\n%sHIL-JUNIT-END\n",
              passed + failed + skipped, failed, skipped, xml.c_str());
  std::fflush(stdout);
}

// Issue 38 item 10, as its acceptance asks: kill -9 of `hilbench serve` in the middle of a run
// on vcan0 puts the CiA 402 emulator (in this process; it implements the consumer heartbeat time
// 0x1016 as a real drive does) into its safe state: no heartbeat of the bench's node for the
// configured 400 ms -> EMCY 0x8130 and 0x6007 = quick stop -> switch on disabled. The drive used to
// hold its last target, powered. The reaction is counted from the bench's last heartbeat on the
// drive's clock; how late after the 400 ms it came is printed (a loaded VM delays the drive's timer).
TEST(VcanCanRig, KillNineOfServeMidRunQuickStopsTheDrive) {
  ASSERT_TRUE(have_vcan0()) << "run me with tests/drivers/vcan/run-on-vcan.sh";
  TempDir configs;
  std::filesystem::create_symlink(source_path("configs/plant"), configs.path() / "plant");
  const auto campaign_file = configs.write("campaigns/paper_adaptive.yaml", paper_adaptive_yaml(2));
  const bench::Campaign campaign = bench::load_campaign(campaign_file);
  SimulatorSide side(campaign, {}, "vcan0");
  RigOptions o;
  o.watchdog_misses = 1000000;  // the loaded VM's stalls are not under test
  configs.write("rigs/kill.yaml",
                rig_yaml("can",
                         can_drive_yaml("vcan0", "recover", 2000, "",
                                        "{node_id: 100, producer_ms: 50, drive_timeout_ms: 400, on_loss: quick_stop}"),
                         modbus_device_yaml(side.transducer.port(), "modbus_transducer_map.yaml", 4, 2000), o));
  ServerProcess server({"--configs", configs.path().string()});
  const auto api = server.client();
  const auto started = api.post("/api/start", {{"campaign", "paper_adaptive"}, {"rig", "kill"}, {"runs", {"adaptive"}}});
  ASSERT_EQ(started.status, 202) << started.body;
  ASSERT_TRUE(wait_state([&] { return side.can.state() == drv::cia402::State::operation_enabled; }, std::chrono::seconds(60)))
      << server.log();
  EXPECT_EQ(side.can.object(0x1016, 1), (100u << 16) | 400u);
  const auto syncs = side.can.syncs_seen();
  ASSERT_TRUE(wait_state([&] { return side.can.syncs_seen() > syncs + 100; }, std::chrono::seconds(60)));  // mid-run
  EXPECT_EQ(side.can.heartbeat_consumer_events(), 0u);
  ASSERT_EQ(kill(server.pid(), SIGKILL), 0);
  ASSERT_TRUE(wait_exit(server.pid(), std::chrono::seconds(30)).has_value());
  ASSERT_TRUE(wait_state([&] { return side.can.heartbeat_consumer_events() > 0; }, std::chrono::seconds(30)));
  const auto event = side.can.last_consumer_event();
  ASSERT_TRUE(event.has_value());
  EXPECT_EQ(event->node, 100);
  EXPECT_GE(event->silence, std::chrono::milliseconds(400));
  EXPECT_EQ(event->state_after, drv::cia402::State::switch_on_disabled) << drv::cia402::to_string(event->state_after);
  EXPECT_EQ(side.can.state(), drv::cia402::State::switch_on_disabled);
  std::printf(
      "kill -9 of hilbench serve mid-run: the drive quick-stopped %.1f ms after the bench's last heartbeat "
      "(consumer time 400 ms), state %s\n",
      std::chrono::duration<double, std::milli>(event->silence).count(),
      std::string(drv::cia402::to_string(side.can.state())).c_str());
}

// Issue 50: `hilbench serve` stopped (SIGSTOP) for 1.2 s mid-run, three times the drive's consumer
// time: the drive sees the bench's heartbeat missing, sends EMCY 0x8130 and quick-stops; on
// SIGCONT the run aborts with a reason that says so in words and names the bench's own heartbeat
// gap as measured by the bench (not "the drive left operational", not a drive fault), and
// run.json says how the drive was switched off.
TEST(VcanCanRig, SigstopOfServeIsNamedAsTheBenchsStall) {
  ASSERT_TRUE(have_vcan0()) << "run me with tests/drivers/vcan/run-on-vcan.sh";
  TempDir configs;
  std::filesystem::create_symlink(source_path("configs/plant"), configs.path() / "plant");
  const auto campaign_file = configs.write("campaigns/paper_adaptive.yaml", paper_adaptive_yaml(2));
  const bench::Campaign campaign = bench::load_campaign(campaign_file);
  SimulatorSide side(campaign, {}, "vcan0");
  RigOptions o;
  o.watchdog_misses = 1000000;  // the loaded VM's stalls are not under test
  configs.write("rigs/stop.yaml",
                rig_yaml("can",
                         can_drive_yaml("vcan0", "recover", 2000, "",
                                        "{node_id: 100, producer_ms: 50, drive_timeout_ms: 400, on_loss: quick_stop}"),
                         modbus_device_yaml(side.transducer.port(), "modbus_transducer_map.yaml", 4, 2000), o));
  ServerProcess server({"--configs", configs.path().string()});
  const auto api = server.client();
  const auto started = api.post("/api/start", {{"campaign", "paper_adaptive"}, {"rig", "stop"}, {"runs", {"adaptive"}}});
  ASSERT_EQ(started.status, 202) << started.body;
  ASSERT_TRUE(wait_state([&] { return side.can.state() == drv::cia402::State::operation_enabled; }, std::chrono::seconds(60)))
      << server.log();
  const auto syncs = side.can.syncs_seen();
  ASSERT_TRUE(wait_state([&] { return side.can.syncs_seen() > syncs + 100; }, std::chrono::seconds(60)));  // mid-run
  ASSERT_EQ(kill(server.pid(), SIGSTOP), 0);
  std::this_thread::sleep_for(std::chrono::milliseconds(1200));
  ASSERT_EQ(kill(server.pid(), SIGCONT), 0);
  ASSERT_TRUE(wait_state([&] { return side.can.heartbeat_consumer_events() > 0; }, std::chrono::seconds(30)));
  nlohmann::json s;
  ASSERT_TRUE(wait_state(
      [&] {
        s = api.get("/api/status").json();
        return s["state"] == "idle";
      },
      std::chrono::seconds(120)))
      << s.dump(2);
  const RunFiles f(only_run(server.runs_dir()));
  ASSERT_EQ(f.run["outcome"], "aborted") << f.run.dump(2);
  const std::string reason = f.run["reason"].get<std::string>();
  EXPECT_NE(reason.find("EMCY 0x8130: the drive lost the bench's heartbeat and did its 0x6007 reaction (quick stop)"),
            std::string::npos)
      << reason;
  EXPECT_NE(reason.find("ms late (0x1016 gives the drive 400 ms): the host stalled"), std::string::npos) << reason;
  // How late the heartbeat was when the bench read the drive's EMCY: past the consumer's 400 ms
  // (the drive reacted to the bench, not to itself); the whole stop is the longest gap below.
  EXPECT_GT(number_after(reason, "the bench's heartbeat was "), 400) << reason;
  EXPECT_EQ(reason.find("left NMT operational"), std::string::npos) << reason;
  const auto& off = f.run["rig_health"]["switch_off"];
  ASSERT_TRUE(off.is_object()) << f.run["rig_health"].dump(2);
  EXPECT_TRUE(off["off"].get<bool>()) << off.dump();
  EXPECT_GE(f.run["trip"]["longest_gap_ms"].get<double>(), 1000) << f.run["trip"].dump();
  std::printf("SIGSTOP of hilbench serve for 1200 ms: %s; switched off by %s in %.1f ms (%s)\n", reason.c_str(),
              off["path"].get<std::string>().c_str(), off["after_ms"].get<double>(), off["state"].get<std::string>().c_str());
}

// `hilbench drive probe --rig FILE` against the emulator as other legal drives on vcan0: it reads
// and reports what each has and lacks, and moves nothing (no SYNC seen, no NMT start, no enable).
TEST(VcanDriveProbe, ProbesEachVariantWithoutMovingIt) {
  ASSERT_TRUE(have_vcan0()) << "run me with tests/drivers/vcan/run-on-vcan.sh";
  TempDir dir;
  const auto rig = dir.write("rigs/probe.yaml",
                             rig_yaml("can", can_drive_yaml("vcan0"), modbus_device_yaml(1503, "modbus_transducer_map.yaml")));
  const auto run = [&](const std::vector<std::string>& args, const std::string& name) {
    const auto out = dir.path() / (name + ".txt");
    std::vector<std::string> argv = {hilbench_exe(), "drive"};
    argv.insert(argv.end(), args.begin(), args.end());
    const auto rc = wait_exit(spawn(argv, out), std::chrono::seconds(120));
    return std::make_pair(rc.value_or(-999), slurp(out));
  };
  {
    const auto [rc, text] = run({"probe", "--help"}, "help");
    EXPECT_EQ(rc, 0);
    EXPECT_NE(text.find("usage: hilbench drive probe --rig FILE"), std::string::npos) << text;
  }
  struct Variant {
    std::string name;
    std::function<void(drv::Cia402EmulatorConfig&)> apply;
    std::vector<std::string> expect;
  };
  const std::vector<Variant> variants = {
      {"full",
       [](drv::Cia402EmulatorConfig&) {},
       {"PDOs: 4 RPDO, 4 TPDO", "0x1018:01 vendor id", "0x00000ABC", "verdict: usable"}},
      {"two_pdos",
       [](drv::Cia402EmulatorConfig& e) { e.pdos = 2; },
       {"PDOs: 2 RPDO, 2 TPDO", "invalidate the other PDOs it has (1 RPDO, 1 TPDO", "verdict: usable"}},
      {"no_60c2",
       [](drv::Cia402EmulatorConfig& e) { e.interpolation_period = false; },
       {"0x60C2 interpolation time period (optional", "verdict: usable"}},
      {"following_error",
       [](drv::Cia402EmulatorConfig& e) { e.following_error = true; },
       {"following error window 0x6065 is off", "verdict: usable"}},
      {"quick_stop_ramp",
       [](drv::Cia402EmulatorConfig& e) { e.quick_stop_ramp = true; },
       {"0x605A = 2 (quick stop ramp)", "verdict: usable"}},
  };
  for (const auto& v : variants) {
    drv::FirstOrderServoTestModel motor(0.01, 1.0, 0.25);
    drv::Cia402EmulatorConfig ec{"vcan0", kNode, kUnits};
    v.apply(ec);
    drv::Cia402DriveEmulator emulator(ec, motor);
    const auto [rc, text] = run({"probe", "--rig", rig.string()}, v.name);
    EXPECT_EQ(rc, 0) << v.name << "\n" << text;
    for (const auto& e : v.expect) EXPECT_NE(text.find(e), std::string::npos) << v.name << ": no '" << e << "' in\n" << text;
    EXPECT_EQ(emulator.syncs_seen(), 0u) << v.name;
    EXPECT_EQ(emulator.nmt_state(), drv::canopen::NmtState::pre_operational) << v.name;
    EXPECT_FALSE(motor.enabled()) << v.name;
    std::printf("--- hilbench drive probe, %s ---\n%s", v.name.c_str(), text.c_str());
  }
  // Nobody at the node: the probe says so and fails.
  const auto [rc, text] = run({"probe", "--rig", rig.string()}, "absent");
  EXPECT_EQ(rc, 1) << text;
  EXPECT_NE(text.find("SDO read 0x1000:00: no reply"), std::string::npos) << text;
}

class VcanRigFaults : public ::testing::Test {
 protected:
  void SetUp() override { ASSERT_TRUE(have_vcan0()) << "run me with tests/drivers/vcan/run-on-vcan.sh"; }
  FaultSetup setup{{}, "vcan0", g_period_ms};  // no transport factory: SocketCAN
};

TEST_F(VcanRigFaults, HeartbeatLossReachesTheSafeStateAndIsReported) { heartbeat_loss(setup); }
TEST_F(VcanRigFaults, SilentDriveTripsTheWatchdog) { drive_silent(setup); }
TEST_F(VcanRigFaults, EmcyFaultTripsAndIsNamed) { emcy_fault(setup); }
TEST_F(VcanRigFaults, BusOffIsDetectedReportedAndRecovered) { bus_off(setup); }
TEST_F(VcanRigFaults, SdoAbortAtConfigureNamesTheObject) { sdo_abort(setup); }
TEST_F(VcanRigFaults, AnAbortCutsTheRigSetupShort) { abort_during_setup(setup); }
TEST_F(VcanRigFaults, AFrozenEncoderTripsTheFollowingError) { frozen_encoder(setup, false); }

int main(int argc, char** argv) {
  ::testing::InitGoogleTest(&argc, argv);
  for (int i = 1; i < argc; ++i) {
    if (std::strncmp(argv[i], "--period-ms=", 12) == 0) g_period_ms = std::atof(argv[i] + 12);
  }
  return RUN_ALL_TESTS();
}

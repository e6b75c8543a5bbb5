#include "hil/drv/cia402_emulator.hpp"

#include "cia402_emulator_impl.hpp"
#include "hil/config.hpp"
#include "hil/drv/socketcan.hpp"

namespace hil::drv {

Cia402EmulatorConfig Cia402EmulatorConfig::from_yaml(const cfg::Node& n) {
  n.allow_keys({"interface", "node_id", "units", "pdos", "interpolation_period", "mode_display_delay_ms", "following_error",
                "quick_stop_ramp", "heartbeat_consumer", "abort_connection_option", "node_guarding", "own_pdo_ids"});
  Cia402EmulatorConfig c;
  if (auto i = n.find("interface")) check_can_interface_name(*i);
  c.interface = n.text("interface", c.interface);
  const long long node = n.at("node_id").integer();
  n.at("node_id").require(node >= 1 && node <= 127, "a CANopen node id is 1..127");
  c.node_id = static_cast<std::uint8_t>(node);
  if (auto u = n.find("units")) c.units = DriveUnits::from_yaml(*u);
  c.pdos = static_cast<int>(n.integer_in("pdos", c.pdos, 1, 4));
  c.interpolation_period = n.boolean("interpolation_period", c.interpolation_period);
  c.mode_display_delay = n.milliseconds_in("mode_display_delay_ms", c.mode_display_delay, 0, 10000);
  c.following_error = n.boolean("following_error", c.following_error);
  c.quick_stop_ramp = n.boolean("quick_stop_ramp", c.quick_stop_ramp);
  c.heartbeat_consumer = n.boolean("heartbeat_consumer", c.heartbeat_consumer);
  c.abort_connection_option = n.boolean("abort_connection_option", c.abort_connection_option);
  c.node_guarding = n.boolean("node_guarding", c.node_guarding);
  c.own_pdo_ids = n.boolean("own_pdo_ids", c.own_pdo_ids);
  return c;
}

Cia402EmulatorConfig Cia402EmulatorConfig::load(const std::filesystem::path& file) {
  const auto root = cfg::Node::load_file(file);
  if (auto d = root.find("cia402_emulator")) return from_yaml(*d);
  return from_yaml(root);
}

Cia402DriveEmulator::Cia402DriveEmulator(Cia402EmulatorConfig config, DriveModel& model, CanTransportFactory transport)
    : impl_(std::make_unique<Impl>(std::move(config), model)) {
  auto& m = *impl_;
  if (!transport) transport = SocketCanTransport::factory(m.cfg.interface);
  const std::uint32_t n = m.n;
  m.tr = transport(m.io, {{kNmt, 0x7FF},
                          {kSync, 0x7FF},
                          {kHeartbeat, 0x780},  // 0x700..0x77F: the heartbeats 0x1016 may name
                          {kSdoRx + n, 0x7FF},
                          {kRpdo1 + n, 0x7FF},
                          {kRpdo1 + 0x100 + n, 0x7FF},
                          {kRpdo1 + 0x200 + n, 0x7FF},
                          {kRpdo1 + 0x300 + n, 0x7FF}});
  m.tr->start([&m](const CanFrame& f) { m.on_frame(f); });
  asio::post(m.io, [&m] { m.boot(true); });
  m.thread = std::thread([&m] { m.io.run(); });
}

Cia402DriveEmulator::~Cia402DriveEmulator() {
  auto& m = *impl_;
  asio::post(m.io, [&m] {
    m.tr->stop();
    m.hb_timer.cancel();
    m.flood_timer.cancel();
    m.consumer_timer.cancel();
    m.own_clock.cancel();
  });
  m.work.reset();
  m.io.stop();
  if (m.thread.joinable()) m.thread.join();
}

canopen::NmtState Cia402DriveEmulator::nmt_state() const { return impl_->nmt(); }
cia402::State Cia402DriveEmulator::state() const { return static_cast<State>(impl_->state_now.load()); }
std::uint64_t Cia402DriveEmulator::syncs_seen() const { return impl_->syncs.load(); }

std::optional<std::uint32_t> Cia402DriveEmulator::object(std::uint16_t index, std::uint8_t sub) {
  auto& m = *impl_;
  return m.on_io([&m, index, sub]() -> std::optional<std::uint32_t> {
    const auto it = m.od.find(key(index, sub));
    if (it == m.od.end()) return std::nullopt;
    return it->second.value;
  });
}

std::optional<Cia402DriveEmulator::RampStart> Cia402DriveEmulator::quick_stop_ramp_start() {
  auto& m = *impl_;
  return m.on_io([&m]() -> std::optional<RampStart> {
    if (!m.qs_started) return std::nullopt;
    return RampStart{m.qs_p0, m.qs_v0};
  });
}

std::uint64_t Cia402DriveEmulator::heartbeat_consumer_events() const { return impl_->consumer_events.load(); }

std::optional<Cia402DriveEmulator::ConsumerEvent> Cia402DriveEmulator::last_consumer_event() {
  auto& m = *impl_;
  return m.on_io([&m] { return m.last_event; });
}

void Cia402DriveEmulator::stop_heartbeat(bool stopped) { impl_->hb_stopped = stopped; }
void Cia402DriveEmulator::set_silent(bool silent) { impl_->silent = silent; }
void Cia402DriveEmulator::enter_nmt_state(canopen::NmtState state) { impl_->set_nmt(state); }
void Cia402DriveEmulator::freeze_position(bool frozen) {
  // Each freeze holds the position of the first SYNC after it, not one a former freeze took (a
  // freeze, a clear and a freeze with no SYNC between, as between two runs, held the old one).
  if (frozen) impl_->refreeze = true;
  impl_->freeze_position = frozen;
}
void Cia402DriveEmulator::set_response_delay(std::chrono::microseconds delay) { impl_->delay_us = delay.count(); }

void Cia402DriveEmulator::raise_emcy(std::uint16_t code, std::uint8_t error_register, std::array<std::uint8_t, 5> mfr) {
  auto& m = *impl_;
  asio::post(m.io, [&m, code, error_register, mfr] {
    m.enter_fault(code, error_register, mfr);
    m.app_step();
  });
}

void Cia402DriveEmulator::fail_sdo(std::uint16_t index, std::uint8_t sub, std::uint32_t abort_code) {
  auto& m = *impl_;
  m.on_io([&m, index, sub, abort_code] {
    m.sdo_failures[key(index, sub)] = abort_code;
    return 0;
  });
}

void Cia402DriveEmulator::clear_sdo_failures() {
  auto& m = *impl_;
  m.on_io([&m] {
    m.sdo_failures.clear();
    return 0;
  });
}

void Cia402DriveEmulator::flood(bool on, std::uint32_t id, int frames_per_ms) {
  auto& m = *impl_;
  asio::post(m.io, [&m, on, id, frames_per_ms] {
    m.flood_id = id;
    m.flood_per_ms = on ? frames_per_ms : 0;
    if (on)
      m.arm_flood();
    else
      m.flood_timer.cancel();
  });
}

void Cia402DriveEmulator::emulate_bus_error(EmulatedBusError kind) {
  auto& m = *impl_;
  asio::post(m.io, [&m, kind] { m.send(make_error_frame(kind)); });
}

void Cia402DriveEmulator::reboot() {
  auto& m = *impl_;
  asio::post(m.io, [&m] { m.boot(true); });
}

}  // namespace hil::drv

// A CiA 402 drive's file (drivers/configs/*.yaml): its units, node, timing, limits and the
// bench's heartbeat, checked with file:line:key errors before any frame is sent.
#include <net/if.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <numbers>

#include "hil/config.hpp"
#include "hil/drv/cia402_drive.hpp"
#include "setup_util.hpp"

namespace hil::drv {

using std::chrono::milliseconds;

double DriveUnits::rad_per_count() const { return sign * 2.0 * std::numbers::pi / (counts_per_rev * gear_ratio); }

std::int32_t DriveUnits::to_counts(double position_rad) const noexcept {
  const double c = std::nearbyint(position_rad / rad_per_count());
  if (!(c > -2147483648.0)) return INT32_MIN;  // also NaN
  if (c > 2147483647.0) return INT32_MAX;
  return static_cast<std::int32_t>(c);
}

double DriveUnits::to_rad(std::int32_t counts) const noexcept { return counts * rad_per_count(); }

DriveUnits DriveUnits::from_yaml(const cfg::Node& n) {
  n.allow_keys({"counts_per_rev", "gear_ratio", "sign"});
  DriveUnits u;
  u.counts_per_rev = n.number("counts_per_rev", u.counts_per_rev);
  n.at("counts_per_rev").require(u.counts_per_rev > 0, "must be > 0");
  u.gear_ratio = n.number("gear_ratio", u.gear_ratio);
  if (auto g = n.find("gear_ratio")) g->require(u.gear_ratio > 0, "must be > 0");
  u.sign = static_cast<int>(n.integer("sign", 1));
  if (auto s = n.find("sign")) s->require(u.sign == 1 || u.sign == -1, "must be 1 or -1");
  // Each finite and > 0 is not enough: 1e200 x 1e200 overflows to inf (every position would read
  // 0 rad), 1e-200 x 1e-200 underflows to 0 (every position inf).
  const double rpc = std::abs(u.rad_per_count());
  const cfg::Node at = n.find("gear_ratio") ? n.at("gear_ratio") : n.at("counts_per_rev");
  at.require(std::isfinite(rpc) && rpc > 0, "counts_per_rev x gear_ratio must be a finite, non-zero count per valve revolution");
  return u;
}

void check_can_interface_name(const cfg::Node& n) {
  // What the kernel takes as a network interface name (dev_valid_name()): 1..15 bytes (IFNAMSIZ
  // with its NUL), no '/', ':' or white space, not "." or "..". Anything else would only fail
  // later as "no such network interface", without the file and line.
  const std::string name = n.text();
  bool ok = !name.empty() && name.size() < IFNAMSIZ && name != "." && name != "..";
  for (const char ch : name) ok = ok && ch != '/' && ch != ':' && !std::isspace(static_cast<unsigned char>(ch));
  n.require(ok, "a network interface name is 1..15 characters without '/', ':' or spaces");
}

Cia402Config Cia402Config::from_yaml(const cfg::Node& n) {
  n.allow_keys({"interface", "node_id", "bitrate", "sync_period_us", "sync_source", "heartbeat", "node_guarding",
                "bench_heartbeat", "units", "timeouts", "bus_off", "disable_unused_pdos", "limits"});
  Cia402Config c;
  check_can_interface_name(n.at("interface"));
  c.interface = n.text("interface");
  const long long node = n.at("node_id").integer();
  n.at("node_id").require(node >= 1 && node <= 127, "a CANopen node id is 1..127");
  c.node_id = static_cast<std::uint8_t>(node);
  c.bitrate = static_cast<long>(n.integer("bitrate", c.bitrate));
  // Classic CAN (CiA 301 bit timing table): 10 kbit/s .. 1 Mbit/s.
  if (auto b = n.find("bitrate")) b->require(c.bitrate >= 10000 && c.bitrate <= 1000000, "must be 10000..1000000 bit/s");
  const long long sync_us = n.integer("sync_period_us", c.sync_period.count());
  c.sync_period = std::chrono::microseconds(sync_us);
  if (auto s = n.find("sync_period_us")) {
    s->require(sync_us >= 100 && sync_us <= 100000, "must be 100..100000 us");
    const auto bus_us = c.min_sync_period().count();
    s->require(sync_us >= bus_us, "must be >= " + std::to_string(bus_us) + " us, the time RPDO1 + SYNC + TPDO1 take at " +
                                      std::to_string(c.bitrate) + " bit/s");
  }
  const std::string src = n.text("sync_source", "timer");
  if (src == "loop")
    c.sync_source = SyncSource::loop;
  else if (src != "timer")
    n.at("sync_source").fail("must be 'timer' or 'loop', got '" + src + "'");
  if (auto hb = n.find("heartbeat")) {
    hb->allow_keys({"producer_ms", "timeout_ms"});
    // 0x1017 is 16 bit: 65536 ms would be written as 0, which turns the heartbeat off.
    c.heartbeat_producer = hb->milliseconds_in("producer_ms", c.heartbeat_producer, 1, 65535,
                                               "0x1017 is 16 bit: 65536 would be written as 0, which turns the heartbeat off");
    c.heartbeat_timeout = hb->milliseconds_in("timeout_ms", c.heartbeat_timeout, 1, detail::kMaxWaitMs);
    if (c.heartbeat_timeout <= c.heartbeat_producer) {
      hb->at("timeout_ms").fail("must be longer than producer_ms (" + std::to_string(c.heartbeat_producer.count()) + " ms)");
    }
  }
  if (auto g = n.find("node_guarding")) {
    g->allow_keys({"guard_time_ms", "life_time_factor"});
    c.node_guarding.guard_time = g->milliseconds_in("guard_time_ms", c.node_guarding.guard_time, 1, 65535, "0x100C is 16 bit");
    c.node_guarding.life_time_factor =
        static_cast<int>(g->integer_in("life_time_factor", c.node_guarding.life_time_factor, 1, 255, "0x100D is 8 bit"));
  }
  if (!n.find("node_guarding")) {
    // Unset: requests three times per heartbeat timeout at least (the default 100 ms within 350 ms).
    c.node_guarding.guard_time = std::max(milliseconds(1), std::min(c.node_guarding.guard_time, c.heartbeat_timeout / 3));
  } else if (c.node_guarding.guard_time >= c.heartbeat_timeout) {
    n.at("node_guarding")
        .fail("guard_time_ms (" + std::to_string(c.node_guarding.guard_time.count()) +
              ") must be shorter than heartbeat.timeout_ms (" + std::to_string(c.heartbeat_timeout.count()) +
              "): the drive's replies are watched with that timeout");
  }
  if (auto bh = n.find("bench_heartbeat")) {
    bh->allow_keys({"node_id", "producer_ms", "drive_timeout_ms", "on_loss", "required"});
    auto& b = c.bench_heartbeat;
    b.node_id = static_cast<std::uint8_t>(bh->integer_in("node_id", b.node_id, 1, 127, "a CANopen node id"));
    if (auto id = bh->find("node_id")) id->require(b.node_id != c.node_id, "must not be the drive's node id");
    b.producer = bh->milliseconds_in("producer_ms", b.producer, 1, 65535);
    b.drive_timeout = bh->milliseconds_in("drive_timeout_ms", b.drive_timeout, 1, 65535, "0x1016 holds the time in 16 bits");
    if (b.drive_timeout <= b.producer) {
      bh->at(bh->find("drive_timeout_ms") ? "drive_timeout_ms" : "producer_ms")
          .fail("drive_timeout_ms (" + std::to_string(b.drive_timeout.count()) + ") must be longer than producer_ms (" +
                std::to_string(b.producer.count()) + ")");
    }
    const std::string loss = bh->text("on_loss", "quick_stop");
    if (loss == "quick_stop")
      b.on_loss = 3;
    else if (loss == "disable_voltage")
      b.on_loss = 2;
    else if (loss == "fault")
      b.on_loss = 1;
    else
      bh->at("on_loss").fail("must be quick_stop, disable_voltage or fault (0x6007 = 3, 2, 1), got '" + loss + "'");
    b.required = bh->boolean("required", b.required);
  } else if (c.bench_heartbeat.node_id == c.node_id) {
    n.at("node_id").fail("is the bench's default node id (127): give bench_heartbeat.node_id another one");
  }
  if (auto u = n.find("units")) c.units = DriveUnits::from_yaml(*u);
  if (auto t = n.find("timeouts")) {
    t->allow_keys({"boot_ms", "sdo_ms", "sdo_retries", "transition_ms"});
    c.boot_timeout = t->milliseconds_in("boot_ms", c.boot_timeout, 1, detail::kMaxWaitMs);
    c.sdo_timeout = t->milliseconds_in("sdo_ms", c.sdo_timeout, 1, detail::kMaxWaitMs);
    c.sdo_retries = static_cast<int>(t->integer_in("sdo_retries", c.sdo_retries, 0, 10));
    c.transition_timeout = t->milliseconds_in("transition_ms", c.transition_timeout, 1, detail::kMaxWaitMs);
  }
  if (auto b = n.find("bus_off")) {
    b->allow_keys({"policy", "recover_after_ms"});
    const std::string p = b->text("policy", "wait");
    if (p == "report")
      c.bus_off_policy = BusOffPolicy::report;
    else if (p == "wait")
      c.bus_off_policy = BusOffPolicy::wait;
    else if (p == "recover")
      c.bus_off_policy = BusOffPolicy::recover;
    else
      b->at("policy").fail("must be report, wait or recover, got '" + p + "'");
    c.bus_off_recover_after = b->milliseconds_in("recover_after_ms", c.bus_off_recover_after, 1, detail::kMaxWaitMs);
  }
  c.disable_unused_pdos = n.boolean("disable_unused_pdos", c.disable_unused_pdos);
  if (auto l = n.find("limits")) {
    l->allow_keys({"following_error_window_deg", "following_error_timeout_ms", "max_profile_velocity_deg_s",
                   "quick_stop_deceleration_deg_s2", "drive_lag_ms"});
    const auto positive = [&](std::string_view key, double& out) {
      if (auto v = l->find(key)) {
        const double x = v->number();
        v->require(std::isfinite(x) && x > 0, "must be > 0");
        out = x * std::numbers::pi / 180.0;
      }
    };
    positive("following_error_window_deg", c.limits.following_error_window_rad);
    positive("max_profile_velocity_deg_s", c.limits.max_profile_velocity_rad_s);
    positive("quick_stop_deceleration_deg_s2", c.limits.quick_stop_deceleration_rad_s2);
    c.limits.following_error_timeout =
        l->milliseconds_in("following_error_timeout_ms", c.limits.following_error_timeout, 0, 65535, "0x6066 is 16 bit");
    if (auto lag = l->find("drive_lag_ms")) {
      const double ms = lag->number();
      lag->require(std::isfinite(ms) && ms >= 0 && ms <= 10000, "must be 0..10000 ms");
      c.limits.drive_lag = std::chrono::microseconds(std::llround(ms * 1000));
    }
  }
  return c;
}

Cia402Config Cia402Config::load(const std::filesystem::path& file) {
  const auto root = cfg::Node::load_file(file);
  if (auto d = root.find("cia402_drive")) return from_yaml(*d);
  return from_yaml(root);
}

std::string following_window_problem(const Cia402Config& c, double window_rad) {
  if (!(c.target_velocity_rad_s > 0) || !(window_rad > 0)) return {};
  const double lag_s = std::chrono::duration<double>(c.limits.drive_lag).count();
  const double period_s = std::chrono::duration<double>(c.sync_period).count();
  const double needed_rad = c.target_velocity_rad_s * (lag_s + period_s);
  constexpr double kDeg = 180.0 / std::numbers::pi;
  char text[400];
  if (c.limits.drive_lag.count() == 0) {
    // Taken as 0 the lag passed any window at a short period, though every drive lags: the check
    // needs the number.
    std::snprintf(text, sizeof text,
                  "following error window 0x6065 = %.4g deg cannot be checked against the bench's targets: the drive's lag "
                  "is unknown, and at %.4g deg/s each 10 ms of it takes %.4g deg of the window; add limits.drive_lag_ms "
                  "(the following error at a constant speed over the speed, measured) to the drive file",
                  window_rad * kDeg, c.target_velocity_rad_s * kDeg, c.target_velocity_rad_s * 0.01 * kDeg);
    return text;
  }
  if (window_rad >= needed_rad) return {};
  std::snprintf(text, sizeof text,
                "following error window 0x6065 = %.4g deg is narrower than the following error the bench's targets make by "
                "themselves: %.4g deg/s x (%.4g ms drive lag + %.4g ms SYNC period) = %.4g deg; the drive would fault on "
                "shaping alone (widen limits.following_error_window_deg, or lower the rig's loop.target_shaping."
                "max_velocity_deg_s)",
                window_rad * kDeg, c.target_velocity_rad_s * kDeg, lag_s * 1e3, period_s * 1e3, needed_rad * kDeg);
  return text;
}

std::chrono::microseconds Cia402Config::min_sync_period() const {
  // Worst-case bits of a classic base frame with `bytes` data bytes: 47 framing bits (with the
  // 3 of interframe space) + the data + a stuff bit per 4 of the 34 + 8n bits SOF..CRC.
  const auto frame_bits = [](long bytes) { return 47 + 8 * bytes + (34 + 8 * bytes - 1) / 4; };
  const long bits = 2 * frame_bits(6) + frame_bits(0);  // RPDO1, TPDO1 (6 bytes each), SYNC
  const long rate = bitrate > 0 ? bitrate : 1000000;
  return std::chrono::microseconds((bits * 1000000 + rate - 1) / rate);
}

}  // namespace hil::drv

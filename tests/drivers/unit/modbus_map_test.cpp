#include <gtest/gtest.h>

#include <cmath>
#include <functional>

#include "hil/config.hpp"
#include "hil/drv/modbus.hpp"
#include "hil/drv/modbus_emulator.hpp"
#include "hil/drv/modbus_map.hpp"
#include "servo_test_model.hpp"

namespace hil::drv {
namespace {

RegisterMap map_of(const std::string& yaml) { return RegisterMap::from_yaml(cfg::Node::load_string(yaml, "map.yaml")); }

TEST(RegisterMap, DecodeAndEncodeEachType) {
  const auto m = map_of(R"(registers:
  a: {table: holding, address: 0, type: int16, scale: 0.5, offset: 1}
  b: {table: holding, address: 1, type: uint16}
  c: {table: input, address: 0, type: int32, word_order: big}
  d: {table: input, address: 2, type: int32, word_order: little}
  e: {table: input, address: 4, type: float32, word_order: big, scale: 1.0e6}
  f: {table: input, address: 6, type: uint32, word_order: little}
)");
  std::uint16_t w[2];
  const std::uint16_t neg[1] = {0xFFFE};  // -2 -> -2 * 0.5 + 1 = 0
  EXPECT_DOUBLE_EQ(m.at("a").decode(neg), 0.0);
  m.at("a").encode(-4.0, w);  // (-4 - 1) / 0.5 = -10
  EXPECT_EQ(w[0], 0xFFF6);
  m.at("b").encode(70000, w);  // saturates
  EXPECT_EQ(w[0], 0xFFFF);
  const std::uint16_t big[2] = {0xFFFF, 0xFFFE}, little[2] = {0xFFFE, 0xFFFF};
  EXPECT_DOUBLE_EQ(m.at("c").decode(big), -2.0);
  EXPECT_DOUBLE_EQ(m.at("d").decode(little), -2.0);
  m.at("c").encode(65537, w);
  EXPECT_EQ(w[0], 0x0001);
  EXPECT_EQ(w[1], 0x0001);
  m.at("d").encode(0x00020003, w);
  EXPECT_EQ(w[0], 0x0003);
  EXPECT_EQ(w[1], 0x0002);
  const std::uint16_t f15[2] = {0x3FC0, 0x0000};  // 1.5f, high word first
  EXPECT_DOUBLE_EQ(m.at("e").decode(f15), 1.5e6);
  m.at("e").encode(2.25e6, w);
  EXPECT_EQ(w[0], 0x4010);
  EXPECT_EQ(w[1], 0x0000);
  m.at("f").encode(4294967295.0, w);
  EXPECT_DOUBLE_EQ(m.at("f").decode(w), 4294967295.0);
  m.at("c").encode(NAN, w);
  EXPECT_DOUBLE_EQ(m.at("c").decode(w), 0.0);
}

// A count's span and its wrap, against the types' ranges: what the drive's position-jump check
// and the emulator's wrapping counter are built on.
TEST(RegisterMap, CountSpanAndWrapFollowTheTypesRange) {
  const auto m = map_of(R"(registers:
  a: {table: holding, address: 0, type: int16, scale: 0.5, offset: 1}
  b: {table: holding, address: 1, type: uint16, scale: -2}
  c: {table: input, address: 0, type: int32, scale: 1.0e-5}
  d: {table: input, address: 2, type: uint32}
  e: {table: input, address: 4, type: float32}
)");
  EXPECT_DOUBLE_EQ(m.at("a").count_span(), 32768.0);
  EXPECT_DOUBLE_EQ(m.at("b").count_span(), 131072.0);  // |scale|
  EXPECT_DOUBLE_EQ(m.at("c").count_span(), 42949.67296);
  EXPECT_DOUBLE_EQ(m.at("d").count_span(), 4294967296.0);
  EXPECT_TRUE(std::isinf(m.at("e").count_span()));
  // int16: counts -32768..32767; 32768 counts (physical 16385) is -32768 (physical -16383).
  EXPECT_DOUBLE_EQ(m.at("a").wrapped(16385.0), -16383.0);
  EXPECT_DOUBLE_EQ(m.at("a").wrapped(16384.5), 16384.5);   // 32767 counts: in range, unchanged
  EXPECT_DOUBLE_EQ(m.at("a").wrapped(-16383.5), 16384.5);  // -32769 counts -> 32767
  // uint16 with a negative scale: physical -2 is count 1; physical 2 is count -1 -> 65535.
  EXPECT_DOUBLE_EQ(m.at("b").wrapped(2.0), -131070.0);
  EXPECT_DOUBLE_EQ(m.at("c").wrapped(21474.83648), -21474.83648);  // 2^31 counts -> -2^31
  EXPECT_DOUBLE_EQ(m.at("d").wrapped(4294967297.0), 1.0);
  EXPECT_DOUBLE_EQ(m.at("e").wrapped(1e12), 1e12);
  // What a wrapped value encodes to is what the device's counter shows: encode no longer saturates it.
  std::uint16_t w[1];
  m.at("a").encode(m.at("a").wrapped(16385.0), w);
  EXPECT_EQ(w[0], 0x8000);
}

TEST(RegisterMap, BlocksJoinNeighboursPerTable) {
  const auto m = RegisterMap::load(HIL_SOURCE_DIR "/drivers/configs/modbus_drive_map.yaml");
  const auto b = m.blocks({"status", "actual_position", "actual_velocity", "fault_code", "missing"});
  ASSERT_EQ(b.size(), 1u);
  EXPECT_EQ(b[0].table, RegisterTable::input);
  EXPECT_EQ(b[0].start, 0);
  EXPECT_EQ(b[0].count, 6);
  EXPECT_EQ(b[0].names, "status, actual_position, actual_velocity, fault_code");
  EXPECT_EQ(m.bit("fault", -1), 3);
  EXPECT_EQ(m.extent(RegisterTable::holding), (std::pair<std::uint16_t, std::uint32_t>{0, 3}));
}

TEST(RegisterMap, ErrorsNameTheKey) {
  const auto expect_error = [](const std::string& yaml, const std::string& text) {
    try {
      map_of(yaml);
      ADD_FAILURE() << "accepted: " << yaml;
    } catch (const cfg::Error& e) {
      EXPECT_NE(std::string(e.what()).find(text), std::string::npos) << e.what();
    }
  };
  expect_error("registers:\n  p: {table: input, address: 0, type: float64}\n",
               "map.yaml:2:33: registers.p.type: must be int16, uint16, int32, uint32 or float32, got 'float64'");
  expect_error("registers:\n  p: {table: input, address: 0, type: int32}\n  q: {table: input, address: 1, type: uint16}\n",
               "registers.q.address: overlaps input register 0 (p)");
  expect_error("registers:\n  p: {table: input, address: 0, type: int16, word_order: little}\n",
               "a 16-bit register has no word order");
  expect_error("registers:\n  p: {table: coil, address: 0, type: int16}\n", "must be holding or input");
  expect_error("registers:\n  p: {table: input, adress: 0, type: int16}\n", "did you mean 'address'");
}

// A device reads only the names it knows: any other name was accepted and the register silently
// left out (`staus:` lost the transducer's fault bit, `falut:` the drive's fault bit, which then
// fell back to bit 3). Now refused, naming file:line:key and the name meant, by the clients'
// configs and by the emulators.
TEST(RegisterMap, NamesADeviceDoesNotReadAreRefused) {
  const auto transducer = [](const std::string& map) {
    return ModbusTransducerConfig::from_yaml(
        cfg::Node::load_string("link: {host: 127.0.0.1, port: 1502}\nregister_map:\n" + map, "transducer.yaml"));
  };
  const std::string pressure = "    pressure: {table: input, address: 0, type: float32, scale: 1.0e6}\n";
  const auto expect_error = [](const std::function<void()>& load, const std::string& text) {
    try {
      load();
      ADD_FAILURE() << "accepted; expected " << text;
    } catch (const cfg::Error& e) {
      EXPECT_NE(std::string(e.what()).find(text), std::string::npos) << e.what();
    }
  };
  expect_error([&] { transducer("  registers:\n" + pressure + "    staus: {table: input, address: 2, type: uint16}\n"); },
               "transducer.yaml:5:5: register_map.registers.staus: unknown key 'staus' (did you mean 'status'?)");
  expect_error([&] { transducer("  registers:\n" + pressure + "  bits:\n    falt: 0\n"); },
               "transducer.yaml:6:5: register_map.bits.falt: unknown key 'falt' (did you mean 'fault'?)");
  expect_error(
      [&] {
        ModbusDriveConfig::from_yaml(
            cfg::Node::load_string("link: {host: 127.0.0.1, port: 1502}\nregister_map:\n  registers:\n"
                                   "    control: {table: holding, address: 0, type: uint16}\n"
                                   "    target_position: {table: holding, address: 1, type: int32, scale: 1.0e-5}\n"
                                   "    status: {table: input, address: 0, type: uint16}\n"
                                   "    actual_position: {table: input, address: 1, type: int32, scale: 1.0e-5}\n"
                                   "  bits: {enable: 0, falut: 4}\n",
                                   "drive.yaml"));
      },
      "drive.yaml:8:21: register_map.bits.falut: unknown key 'falut' (did you mean 'fault'?)");
  // The emulators (hilbench plant's --drive-map, --transducer-map) check the same names.
  PositionPressureTestModel model(1e6);
  const auto typo = map_of(
      "registers:\n  pressure: {table: input, address: 0, type: float32}\n  staus: {table: input, address: 2, type: uint16}\n");
  ModbusLinkConfig link;
  link.port = 0;
  expect_error([&] { ModbusTransducerEmulator(link, typo, model); }, "map.yaml:3:3: registers.staus: unknown key 'staus'");
  // The shipped maps use only names their device reads.
  RegisterMap::load(HIL_SOURCE_DIR "/drivers/configs/modbus_drive_map.yaml").allow_names(ModbusDriveConfig::map_names());
  RegisterMap::load(HIL_SOURCE_DIR "/drivers/configs/modbus_transducer_map.yaml")
      .allow_names(ModbusTransducerConfig::map_names());
}

// Link values libmodbus would bend without a word (any baud not in its table is 9600, data bits
// other than 5..7 are 8, stop bits other than 1 are 2, "localhost" is 255.255.255.255), values a
// client cannot use (port 0, unit 0: a broadcast no device answers), numbers that passed their
// range only after a cast to int, and keys of the other transport that were ignored: refused,
// naming file:line:key.
TEST(ModbusLinkConfig, ValuesAClientCannotUseAreRefused) {
  const auto expect_error = [](const std::string& link, const std::string& text) {
    try {
      ModbusLinkConfig::from_yaml(cfg::Node::load_string("link: {" + link + "}\n", "link.yaml").at("link"));
      ADD_FAILURE() << "accepted: " << link;
    } catch (const cfg::Error& e) {
      EXPECT_NE(std::string(e.what()).find(text), std::string::npos) << e.what();
    }
  };
  const std::string rtu = "transport: rtu, device: /dev/ttyUSB0, ";
  expect_error("port: 0", "link.yaml:1:");
  expect_error("port: 0", "link.port: a device's TCP port is 1..65535, got '0'");
  expect_error("port: 4294967298", "link.port: a device's TCP port is 1..65535, got '4294967298'");
  expect_error("host: localhost, port: 502", "link.host: must be the device's numeric IPv4 address");
  expect_error("host: 0.0.0.0, port: 502", "link.host: must be the device's numeric IPv4 address");
  expect_error(
      "port: 502, unit_id: 0",
      "link.yaml:1:19: link.unit_id: must be 1..247 (a device's unit id; 0 is a broadcast, which no device answers), got '0'");
  expect_error("port: 502, unit_id: 4294967297",
               "link.unit_id: must be 1..247 (a device's unit id; 0 is a broadcast, which no device answers), got '4294967297'");
  expect_error("port: 502, baud: 9600", "link.baud: a tcp link has no baud");
  expect_error(rtu + "baud: 12345", "link.baud: must be one of 110, 300,");
  expect_error(rtu + "baud: 12345", "(libmodbus makes any other 9600), got '12345'");
  expect_error(rtu + "baud: -9600", "link.baud: must be one of");
  expect_error(rtu + "data_bits: 9", "link.data_bits: must be 5..8 (libmodbus makes any other 8), got '9'");
  expect_error(rtu + "stop_bits: 0", "link.stop_bits: must be 1..2 (libmodbus makes any other 2), got '0'");
  expect_error(rtu + "parity: X", "link.parity: must be N, E or O, got 'X'");
  expect_error(rtu + "port: 502", "link.port: a rtu link has no port");
  expect_error(
      "port: 502, response_timeout_ms: 0",
      "link.yaml:1:19: link.response_timeout_ms: must be 1..10000 ms (an abort waits for the transaction in flight, which "
      "libmodbus cannot cut short), got '0'");
  // libmodbus cannot cut a transaction short: an abort waited up to 600 s for one in flight.
  expect_error("port: 502, response_timeout_ms: 600000", "must be 1..10000 ms (an abort waits for the transaction in flight");
  expect_error("port: 502, poll_period_ms: -1", "link.poll_period_ms: must be 1..600000 ms, got '-1'");
  // What a device takes stays accepted.
  const auto ok = ModbusLinkConfig::from_yaml(
      cfg::Node::load_string("{" + rtu + "baud: 19200, parity: E, data_bits: 7, stop_bits: 2, unit_id: 247}", "ok.yaml"));
  EXPECT_EQ(ok.describe(), "rtu /dev/ttyUSB0 19200 7E2 unit 247");
}

}  // namespace
}  // namespace hil::drv

// Fuzz target "rig": the bytes as the files a rig is made of, read the ways the bench reads them:
//   1. a rig file (hil::bench::load_rig_config_text) as if it lay in configs/rigs/, so a device
//      named by path ("modbus: ../../drivers/configs/modbus_drive.yaml") loads the shipped file;
//      a rig that loads is then made (make_rig opens nothing until it is configured);
//   2. a device client's file: a Modbus drive, a Modbus transducer, a CiA 402 drive (each from a
//      file, top level or under its own key), and the CiA 402 emulator's file;
//   3. a Modbus register map (RegisterMap::load); every register of a map that loads decodes the
//      input's bytes as a device's reply words (any 16-bit values can come back) and encodes the
//      values read from them, NaN and infinities included, as a request's words.
// Clear errors: hil::cfg::Error (file:line:column: key: what); an unknown rig kind is a
// cfg::Error at its key. make_rig and the map's `at` name what is missing with std::invalid_argument.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include "fuzz_support.hpp"
#include "hil/bench/rt/rig.hpp"
#include "hil/bench/rt/rig_config.hpp"
#include "hil/config.hpp"
#include "hil/drv/cia402_drive.hpp"
#include "hil/drv/cia402_emulator.hpp"
#include "hil/drv/modbus.hpp"
#include "hil/drv/modbus_map.hpp"

namespace {

// The input's bytes as reply words, at least two (a 32-bit register reads two), zero-padded.
std::vector<std::uint16_t> reply_words(const std::uint8_t* data, std::size_t size) {
  std::vector<std::uint16_t> w(std::max<std::size_t>(2, (size + 1) / 2), 0);
  std::memcpy(w.data(), data, size);
  return w;
}

void round_trip(const hil::drv::RegisterMap& map, const std::vector<std::uint16_t>& reply) {
  const double specials[] = {std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::infinity(),
                             -std::numeric_limits<double>::infinity(), std::numeric_limits<double>::max(),
                             -std::numeric_limits<double>::max(),      std::numeric_limits<double>::denorm_min()};
  std::uint16_t request[2];
  for (const auto& r : map.registers()) {
    for (std::size_t i = 0; i + 1 < reply.size(); ++i) {
      const double physical = r.decode(&reply[i]);
      r.encode(physical, request);
      // An integer register without scale and offset gives back the words it read (a float32's
      // NaN may come back quieted, so floats are only encoded).
      const bool integer = r.type != hil::drv::RegisterType::float32;
      if (integer && r.scale == 1.0 && r.offset == 0.0 && std::memcmp(request, &reply[i], 2 * r.words()) != 0) {
        std::fprintf(stderr, "\nFINDING: %s: words %04x %04x decoded to %.17g encode as %04x %04x\n", r.where().c_str(), reply[i],
                     reply[i + 1], physical, request[0], request[1]);
        std::abort();
      }
    }
    for (const double x : specials) r.encode(x, request);
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static hil::fuzz::InputFile device_file("device.yaml");
  const std::string text(reinterpret_cast<const char*>(data), size);

  hil::fuzz::expect_clear_errors<hil::cfg::Error>("bench::load_rig_config_text", [&] {
    const auto rig = hil::bench::load_rig_config_text(text, HIL_SOURCE_DIR "/configs/rigs/fuzz.yaml");
    // A loaded file names a kind this build has: making it must not throw.
    (void)hil::bench::make_rig(rig);
  });

  const auto& file = device_file.write(data, size);
  using namespace hil::drv;
  hil::fuzz::expect_clear_errors<hil::cfg::Error>("drv::ModbusDriveConfig::load", [&] { (void)ModbusDriveConfig::load(file); });
  hil::fuzz::expect_clear_errors<hil::cfg::Error>("drv::ModbusTransducerConfig::load",
                                                  [&] { (void)ModbusTransducerConfig::load(file); });
  hil::fuzz::expect_clear_errors<hil::cfg::Error>("drv::Cia402Config::load", [&] { (void)Cia402Config::load(file); });
  hil::fuzz::expect_clear_errors<hil::cfg::Error>("drv::Cia402EmulatorConfig::load",
                                                  [&] { (void)Cia402EmulatorConfig::load(file); });
  const auto reply = reply_words(data, size);
  hil::fuzz::expect_clear_errors<hil::cfg::Error>("drv::RegisterMap::load", [&] { round_trip(RegisterMap::load(file), reply); });
  return 0;
}

// Modbus TCP on loopback: read-input-registers round trip against our transducer emulator,
// with libmodbus directly, next to mbpoll doing the same read (one process per read: mbpoll
// has no faster loop than 10 ms, so its number includes process start and connect).
#include <modbus/modbus.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "hil/drv/modbus.hpp"
#include "hil/drv/modbus_emulator.hpp"
#include "servo_test_model.hpp"
#include "stats.hpp"

using namespace hil::drv;

int main(int argc, char** argv) {
  const int n = argc > 1 ? std::atoi(argv[1]) : 20000;
  const int n_mbpoll = argc > 2 ? std::atoi(argv[2]) : 200;
  ModbusLinkConfig server;
  server.host = "127.0.0.1";
  server.port = 0;
  PositionPressureTestModel model(1.5e6);
  ModbusTransducerEmulator emu(server, RegisterMap::load(HIL_SOURCE_DIR "/drivers/configs/modbus_transducer_map.yaml"), model);
  const int port = emu.port();

  modbus_t* ctx = modbus_new_tcp("127.0.0.1", port);
  if (modbus_connect(ctx) != 0) {
    std::fprintf(stderr, "connect: %s\n", modbus_strerror(errno));
    return 1;
  }
  std::vector<double> us;
  std::uint16_t regs[3];
  for (int i = 0; i < n; ++i) {
    const auto t0 = std::chrono::steady_clock::now();
    if (modbus_read_input_registers(ctx, 0, 3, regs) != 3) {
      std::fprintf(stderr, "read: %s\n", modbus_strerror(errno));
      return 1;
    }
    us.push_back(std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - t0).count());
  }
  modbus_close(ctx);
  modbus_free(ctx);
  bench::print_stats("modbus_tcp read 3 input regs (libmodbus)", us);

  us.clear();
  const std::string cmd = "mbpoll -m tcp -a 1 -0 -1 -t 3 -r 0 -c 3 -p " + std::to_string(port) + " 127.0.0.1 >/dev/null 2>&1";
  for (int i = 0; i < n_mbpoll; ++i) {
    const auto t0 = std::chrono::steady_clock::now();
    if (std::system(cmd.c_str()) != 0) {
      std::fprintf(stderr, "mbpoll failed\n");
      return 1;
    }
    us.push_back(std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - t0).count());
  }
  bench::print_stats("mbpoll -1 same read (process per read)", us);
  return 0;
}

// `hilbench plant --modbus tcp:HOST:PORT` with endpoints a careless or hostile user gives it: each
// is a clear error before anything says ready, never a truncated port or an address no client
// reaches. Each refused run would have run (and said ready) for 0.2 s on the old parsing.
#include <gtest/gtest.h>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <string>

#include "support/run_command.hpp"
#include "support/temp_file.hpp"

using hil::test::hilbench;
using hil::test::run_command;
using hil::test::source_path;

namespace {

// `timeout 20`: a plant that does not stop at the end of its --duration-s is killed, and fails.
hil::test::CommandResult plant(const std::string& endpoint, const std::string& options = "") {
  return run_command("timeout 20 " + hilbench() + " plant --plant " + source_path("configs/plant/nominal.yaml").string() +
                     " --drive-map " + source_path("drivers/configs/modbus_drive_map.yaml").string() + " --transducer-map " +
                     source_path("drivers/configs/modbus_transducer_map.yaml").string() + " --modbus " + endpoint +
                     " --duration-s 0.2 --quiet" + options);
}

void expect_refused(const std::string& endpoint, const std::string& why, const std::string& options = "") {
  const auto r = plant(endpoint, options);
  EXPECT_NE(r.status, 0) << endpoint << options << "\n" << r.output;
  EXPECT_NE(r.output.find(why), std::string::npos) << endpoint << options << "\n" << r.output;
  EXPECT_EQ(r.output.find("plant: ready"), std::string::npos) << endpoint << options << "\n" << r.output;
}

}  // namespace

TEST(PlantCli, ModbusPortIsAWholeNumberWithRoomForTheTransducer) {
  // 70000 was truncated to port 4464, "12abc" read as 12, 65535 left the transducer on 65536 (0).
  for (const std::string port : {"70000", "12abc", "65535", "-1", "", "1e3", " 5020"}) {
    expect_refused("'tcp:127.0.0.1:" + port + "'", "the PORT '" + port + "' is not a whole number 0..65534");
  }
  expect_refused("tcp::5020", "no HOST in 'tcp::5020'");
}

TEST(PlantCli, ModbusHostIsANumericAddressAClientCanReach) {
  // "localhost" was inet_addr()'d into 255.255.255.255: bound, no client could connect, "ready".
  expect_refused("tcp:localhost:0", "host 'localhost' is not a numeric IPv4 address");
  expect_refused("tcp:127.0.0.256:0", "host '127.0.0.256' is not a numeric IPv4 address");
  expect_refused("tcp:255.255.255.255:0", "255.255.255.255 is the broadcast address");
}

TEST(PlantCli, APortThatCannotBeBoundFailsLoudly) {
  // Someone else listens on the port: the plant says so and never says ready.
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  ASSERT_GE(fd, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  socklen_t len = sizeof a;
  ASSERT_EQ(::bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof a), 0);
  ASSERT_EQ(::listen(fd, 1), 0);
  ASSERT_EQ(::getsockname(fd, reinterpret_cast<sockaddr*>(&a), &len), 0);
  expect_refused("tcp:127.0.0.1:" + std::to_string(ntohs(a.sin_port)), "cannot listen: Address already in use");
  ::close(fd);
}

TEST(PlantCli, AnyFreePortsAreSaid) {
  const auto r = plant("tcp:127.0.0.1:0");
  EXPECT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("plant: ready"), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("tcp port 0"), std::string::npos) << r.output;  // the real ports, not 0
}

TEST(PlantCli, PeriodIsWithinTheCampaignsRange) {
  // --period-ms had no range: 30000 ran a plant SIGINT/SIGTERM could not stop for up to 30 s (the
  // stop waited out the period), 1e13 overflowed the period's conversion and ran flat out on NaN,
  // 1e-12 busy-spun, and 0 or -1 failed with "plant service: the period must be > 0", naming no
  // option. A campaign file's period_ms is 0.01..1000; so is this option.
  for (const std::string ms : {"30000", "1e13", "1e-12", "0", "-1", "0.009", "1000.5"}) {
    expect_refused("tcp:127.0.0.1:0", "--period-ms: needs a number in 0.01..1000, got '" + ms + "'", " --period-ms " + ms);
  }
  for (const std::string ms : {"0.01", "1000"}) {  // the limits themselves run
    const auto r = plant("tcp:127.0.0.1:0", " --period-ms " + ms);
    EXPECT_EQ(r.status, 0) << ms << "\n" << r.output;
    EXPECT_NE(r.output.find("plant: ready"), std::string::npos) << ms << "\n" << r.output;
  }
}

// CAN benchmarks on a real vcan0 (run inside the VM by tests/drivers/vcan/run-on-vcan.sh):
//  1. SYNC -> TPDO round trip: a raw master socket sends SYNC, our emulator answers with TPDO1.
//  2. The client path the bench uses: write() (sync_source loop) -> new TPDO in read().
//  3. Frames/s sustained: one socket sends numbered frames as fast as it can, another receives
//     them; losses are gaps in the numbers plus the kernel's SO_RXQ_OVFL drop count.
#include <linux/can.h>
#include <linux/can/raw.h>
#include <net/if.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <string>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <thread>

#include "hil/drv/cia402_drive.hpp"
#include "hil/drv/cia402_emulator.hpp"
#include "servo_test_model.hpp"
#include "hil/drv/socketcan.hpp"
#include "stats.hpp"

using namespace hil::drv;
using namespace std::chrono_literals;

namespace {

int raw_socket(can_filter* filter) {
  const int s = ::socket(PF_CAN, SOCK_RAW, CAN_RAW);
  if (s < 0) {
    std::perror("socket(PF_CAN)");
    std::exit(1);
  }
  if (filter) ::setsockopt(s, SOL_CAN_RAW, CAN_RAW_FILTER, filter, sizeof *filter);
  sockaddr_can a{};
  a.can_family = AF_CAN;
  a.can_ifindex = static_cast<int>(::if_nametoindex("vcan0"));
  if (::bind(s, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0) {
    std::perror("bind vcan0");
    std::exit(1);
  }
  return s;
}

double us_since(Clock::time_point t0) { return std::chrono::duration<double, std::micro>(Clock::now() - t0).count(); }

void sync_tpdo_round_trip(int n) {
  FirstOrderServoTestModel model;
  Cia402DriveEmulator emulator({"vcan0", 5, {}}, model);
  {
    Cia402Config cfg;
    cfg.node_id = 5;
    cfg.sync_period = 100ms;  // the client only maps the PDOs here; the raw socket below sends SYNC
    Cia402Drive client(cfg);
    client.configure();
  }
  can_filter f{0x185, CAN_SFF_MASK};
  const int s = raw_socket(&f);
  timeval tv{1, 0};
  ::setsockopt(s, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
  can_frame sync{};
  sync.can_id = 0x080;
  std::vector<double> rtt;
  int lost = 0;
  for (int i = 0; i < n; ++i) {
    const auto t0 = Clock::now();
    [[maybe_unused]] auto w = ::write(s, &sync, sizeof sync);
    can_frame r{};
    if (::read(s, &r, sizeof r) == sizeof r)
      rtt.push_back(us_since(t0));
    else
      ++lost;
  }
  ::close(s);
  bench::print_stats("sync_to_tpdo_rtt (raw master, emulator)", rtt);
  std::printf("%-40s %d\n", "sync_to_tpdo_no_answer", lost);
}

void client_write_to_feedback(int n) {
  FirstOrderServoTestModel model;
  Cia402DriveEmulator emulator({"vcan0", 5, {}}, model);
  Cia402Config cfg;
  cfg.node_id = 5;
  cfg.sync_source = Cia402Config::SyncSource::loop;
  cfg.sync_period = 100ms;  // the timer only covers setup
  Cia402Drive client(cfg);
  client.configure();
  client.activate();
  std::vector<double> lat;
  for (int i = 0; i < n; ++i) {
    const auto seq = client.read(Clock::now(), 1ms).sequence;
    const auto t0 = Clock::now();
    client.write(t0, 1ms, {0.0, true, false});
    while (client.read(Clock::now(), 1ms).sequence == seq && us_since(t0) < 1e6) {}
    lat.push_back(us_since(t0));
    std::this_thread::sleep_for(200us);
  }
  bench::print_stats("client write()->TPDO in read()", lat);
}

// rate_fps 0: as fast as the sender can; else paced in 1 ms bursts.
double throughput(int n, int rate_fps) {  // returns frames/s achieved, 0 if any frame was lost
  can_filter f{0x123, CAN_SFF_MASK};
  const int rx = raw_socket(&f);
  const int big = 8 << 20, on = 1;
  ::setsockopt(rx, SOL_SOCKET, SO_RCVBUF, &big, sizeof big);
  ::setsockopt(rx, SOL_SOCKET, SO_RXQ_OVFL, &on, sizeof on);
  const int tx = raw_socket(nullptr);
  std::atomic<bool> done{false};
  std::uint32_t received = 0, gaps = 0, dropped = 0;
  std::thread receiver([&] {
    std::uint32_t expect = 0;
    timeval tv{0, 200000};
    ::setsockopt(rx, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
    while (true) {
      can_frame r{};
      alignas(cmsghdr) char ctl[CMSG_SPACE(sizeof(std::uint32_t))];
      iovec iov{&r, sizeof r};
      msghdr m{};
      m.msg_iov = &iov, m.msg_iovlen = 1, m.msg_control = ctl, m.msg_controllen = sizeof ctl;
      if (::recvmsg(rx, &m, 0) != sizeof r) {
        if (done) break;
        continue;
      }
      for (cmsghdr* c = CMSG_FIRSTHDR(&m); c; c = CMSG_NXTHDR(&m, c)) {
        if (c->cmsg_type == SO_RXQ_OVFL) std::memcpy(&dropped, CMSG_DATA(c), sizeof dropped);
      }
      std::uint32_t seq;
      std::memcpy(&seq, r.data, 4);
      if (seq != expect) ++gaps;
      expect = seq + 1;
      ++received;
    }
  });
  can_frame f8{};
  f8.can_id = 0x123;
  f8.can_dlc = 8;
  std::uint32_t send_fail = 0;
  const auto t0 = Clock::now();
  const int burst = rate_fps > 0 ? std::max(1, rate_fps / 1000) : n;
  auto next = t0;
  for (std::uint32_t i = 0; i < static_cast<std::uint32_t>(n); ++i) {
    if (rate_fps > 0 && i % burst == 0) {
      std::this_thread::sleep_until(next);
      next += 1ms;
    }
    std::memcpy(f8.data, &i, 4);
    while (::write(tx, &f8, sizeof f8) != sizeof f8) {
      ++send_fail;  // ENOBUFS: the tx queue is full; try again
      std::this_thread::yield();
    }
  }
  const double secs = std::chrono::duration<double>(Clock::now() - t0).count();
  std::this_thread::sleep_for(300ms);
  done = true;
  receiver.join();
  char name[64];
  std::snprintf(name, sizeof name, "vcan_throughput %s",
                rate_fps > 0 ? ("paced " + std::to_string(rate_fps) + "/s").c_str() : "unpaced");
  std::printf("%-40s sent=%d in %.3f s = %.0f frames/s, received=%u, lost=%u (gaps %u, kernel drops %u), tx retries=%u\n", name,
              n, secs, n / secs, received, static_cast<unsigned>(n) - received, gaps, dropped, send_fail);
  std::fflush(stdout);
  ::close(rx);
  ::close(tx);
  return received == static_cast<std::uint32_t>(n) ? n / secs : 0.0;
}

}  // namespace

int main(int argc, char** argv) {
  const int n = argc > 1 ? std::atoi(argv[1]) : 5000;
  std::printf("hil drivers CAN benchmark on vcan0, %d round trips\n", n);
  sync_tpdo_round_trip(n);
  client_write_to_feedback(n / 2);
  throughput(n * 40, 0);
  double best = 0;
  for (int rate : {8000, 16000, 32000, 64000, 128000}) {  // 8000/s is about a saturated 1 Mbit/s bus
    const double achieved = throughput(rate, rate);       // one second each
    if (achieved == 0) break;
    best = achieved;
  }
  std::printf("%-40s %.0f frames/s (highest paced run with no loss)\n", "vcan_sustained_without_loss", best);
  return 0;
}

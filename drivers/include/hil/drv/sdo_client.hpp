// An expedited SDO client (CiA 301) for one CANopen node, over a CAN transport's frames: the
// requests queued one at a time on the channel's Asio I/O thread, each with its timeout, retries
// and the abort a given-up transfer is owed; the caller blocks until the reply (or throws). The
// CiA 402 client runs one on its own channel (configure's object writes, sdo_read/sdo_write); the
// probe runs one on an SdoChannel of its own, with no SYNC, PDO or heartbeat (as lely-core's
// coapp keeps its SDO client apart from the driver that uses it).
#pragma once

#include <boost/asio/io_context.hpp>
#include <boost/asio/steady_timer.hpp>

#include <chrono>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <stdexcept>
#include <string>
#include <thread>

#include "hil/drv/can.hpp"
#include "hil/drv/io_types.hpp"

namespace hil::drv {

class DriveError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// The drive refused an SDO: what() names the drive, the object and the abort code's meaning.
class SdoAbortError : public DriveError {
 public:
  SdoAbortError(const std::string& what, std::uint16_t index, std::uint8_t sub, std::uint32_t code)
      : DriveError(what), index(index), sub(sub), code(code) {}
  std::uint16_t index;
  std::uint8_t sub;
  std::uint32_t code;
};

class SdoClient {
 public:
  struct Settings {
    std::uint8_t node_id = 1;
    std::string who;  // names the node in every message: "CiA 402 drive node 5 on vcan0"
    std::chrono::milliseconds timeout{200};
    int retries = 2;  // tries after the first
  };
  // What the client needs of the channel's owner. `send`, `error` and `publish` run on the I/O
  // thread; `check_cancelled` on the caller's, every 2 ms of a wait (it throws to end the wait;
  // the request stays with the I/O thread, which ends it by its own timeout).
  struct Link {
    std::function<bool(const CanFrame&)> send;
    std::function<void(const std::string&)> error;  // an error for the owner's health text
    std::function<void()> publish;                  // the owner's health out, before a waiter wakes
    std::function<void()> check_cancelled;          // may be empty
  };

  // `health` is the owner's, written on the I/O thread only (timeouts, aborts, malformed replies).
  SdoClient(boost::asio::io_context& io, Settings settings, DeviceHealth& health, Link link);
  ~SdoClient();
  SdoClient(const SdoClient&) = delete;
  SdoClient& operator=(const SdoClient&) = delete;

  // I/O thread: a frame on 0x580 + node (the channel's filter passes it).
  void on_reply(const CanFrame& f);
  // I/O thread: stops the timer (the channel is closing).
  void cancel() noexcept;

  // Blocking, never from the I/O thread. Throws SdoAbortError (the node refused) or DriveError
  // (no reply after the tries, a segmented transfer, the I/O thread gone), naming node and object.
  std::uint32_t read(std::uint16_t index, std::uint8_t sub);
  void write(std::uint16_t index, std::uint8_t sub, std::uint32_t value, std::uint8_t size);

  const Settings& settings() const { return settings_; }

 private:
  struct Request;
  std::uint32_t transfer(bool upload, std::uint16_t index, std::uint8_t sub, std::uint32_t value, std::uint8_t size);
  void finish(std::exception_ptr err, std::uint32_t value);
  void next();
  void send_active();

  boost::asio::io_context& io_;
  const Settings settings_;
  DeviceHealth& h_;
  const Link link_;
  boost::asio::steady_timer timer_;
  std::deque<std::shared_ptr<Request>> queue_;
  std::shared_ptr<Request> active_;
};

// An SDO client on a CAN channel of its own (its own I/O thread, receiving 0x580 + node only):
// for a tool that only reads and writes objects, such as the probe. Sends nothing but SDO requests.
class SdoChannel {
 public:
  // Opens the channel (SocketCAN on `interface` unless a factory is given). Throws when it cannot.
  SdoChannel(const std::string& interface, SdoClient::Settings settings, CanTransportFactory transport = {});
  ~SdoChannel();
  SdoChannel(const SdoChannel&) = delete;
  SdoChannel& operator=(const SdoChannel&) = delete;

  SdoClient& sdo() { return *sdo_; }
  DeviceHealth health() const { return health_box_.load(); }  // counters and the last error

 private:
  boost::asio::io_context io_;
  std::unique_ptr<CanTransport> tr_;
  DeviceHealth h_;  // I/O thread
  Mailbox<DeviceHealth> health_box_;
  std::unique_ptr<SdoClient> sdo_;
  std::thread thread_;
};

}  // namespace hil::drv

// Private: one libmodbus context (client side) and the error vocabulary both clients share.
#pragma once

#include <modbus/modbus.h>
#include <netinet/in.h>

#include <string>

#include "hil/drv/modbus.hpp"

namespace hil::drv::detail {

enum class Failure { exception, timeout, protocol, connection };

Failure classify(int err);
// "ILLEGAL DATA ADDRESS (exception 2)", "no reply within 100 ms", "Connection reset by peer"...
std::string error_text(int err, const ModbusLinkConfig& cfg);
modbus_t* new_context(const ModbusLinkConfig& cfg);  // TCP or RTU by cfg.transport; nullptr on failure
// `host` as a numeric IPv4 address (dotted quad) into `out`; false for anything else. libmodbus'
// TCP context takes inet_addr() of its host, which makes a name such as "localhost"
// 255.255.255.255 (INADDR_NONE) instead of failing: clients and emulators both take numbers only.
bool ipv4_address(const std::string& host, in_addr& out);

class ModbusLink {
 public:
  explicit ModbusLink(const ModbusLinkConfig& cfg) : cfg_(cfg) {}
  ~ModbusLink() { close(); }
  ModbusLink(const ModbusLink&) = delete;
  ModbusLink& operator=(const ModbusLink&) = delete;

  void connect();  // throws ModbusError naming the endpoint
  void close();
  bool is_open() const { return ctx_ != nullptr; }
  bool read(const RegisterBlock& b, std::uint16_t* dest);
  bool write(const Register& r, const std::uint16_t* words);
  int error() const { return err_; }

 private:
  const ModbusLinkConfig& cfg_;
  modbus_t* ctx_ = nullptr;
  int err_ = 0;
};

}  // namespace hil::drv::detail

// Know a CiA 402 drive before a run: what it is (0x1018), which modes it supports (0x6502), which
// of the objects the client uses it has, how many PDOs, its following error monitoring, and what
// Cia402Drive::configure() will do with it. Reads SDOs only: no NMT command, no SYNC, no enable,
// so the motor does not move (a drive answers SDO in pre-operational and operational alike).
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "hil/drv/cia402_drive.hpp"
#include "hil/drv/sdo_client.hpp"

namespace hil::drv {

struct Cia402Probe {
  struct Object {
    std::uint16_t index = 0;
    std::uint8_t sub = 0;
    std::string name;
    bool required = false;               // configure() fails without it
    std::optional<std::uint32_t> value;  // nullopt: the drive aborted the read
    std::uint32_t abort_code = 0;
    std::string no_answer;  // not empty: neither a value nor an abort came (timeout, segmented reply)
  };
  std::uint32_t device_type = 0;
  std::vector<Object> objects;       // identity, modes, the client's objects, the limits
  int rpdos = 0, tpdos = 0;          // PDO communication objects present (0x1400.., 0x1800..)
  bool csp_supported = false;        // 0x6502 bit 7 (true when 0x6502 is absent: not declared)
  std::vector<std::string> plan;     // what configure() will do with this drive
  std::vector<std::string> lacks;    // what the drive lacks, and what that means
  std::vector<std::string> refused;  // what configure() will refuse, with the numbers (a following error window too narrow)
  bool usable = true;                // every required object is there and CSP is not ruled out

  const Object* find(std::uint16_t index, std::uint8_t sub) const;
  std::string report() const;  // human-readable, one fact a line
};

// Probes the drive `config` names through `sdo` (an SdoClient on a channel to it: an SdoChannel
// of its own, or a Cia402Drive's, constructed and not configured). Throws DriveError when the
// drive does not answer SDO at all, or is not a CiA 402 device.
Cia402Probe probe(SdoClient& sdo, const Cia402Config& config);
// The same through the client's own SDO client.
Cia402Probe probe(Cia402Drive& client);

}  // namespace hil::drv

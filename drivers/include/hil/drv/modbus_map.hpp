// Modbus register maps from YAML: where each named value lives (table, address), its type
// (int16, uint16, int32, uint32, float32), the word order of 32-bit values, and its scale and
// offset (physical = raw * scale + offset). Shared by the clients and the emulators.
//
//   registers:
//     pressure: {table: input, address: 0, type: float32, word_order: big, scale: 1.0e6}
//   bits:            # optional, named bit numbers for control/status words
//     fault: 3
#pragma once

#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

namespace hil::cfg {
class Node;
}

namespace hil::drv {

enum class RegisterTable : std::uint8_t { holding, input };
enum class RegisterType : std::uint8_t { int16, uint16, int32, uint32, float32 };
// big: high word first at the lower address ("ABCD", Modbus' usual); little: low word first ("CDAB").
enum class WordOrder : std::uint8_t { big, little };

struct Register {
  std::string name;
  RegisterTable table = RegisterTable::holding;
  std::uint16_t address = 0;  // PDU address (0-based)
  RegisterType type = RegisterType::uint16;
  WordOrder word_order = WordOrder::big;
  double scale = 1.0;
  double offset = 0.0;

  int words() const noexcept { return type == RegisterType::int16 || type == RegisterType::uint16 ? 1 : 2; }
  // Real-time safe.
  double decode(const std::uint16_t* words) const noexcept;
  // Rounds integers to nearest and saturates at the type's range. Real-time safe.
  void encode(double physical, std::uint16_t* words) const noexcept;
  std::string where() const;  // "input register 2 (actual_position)"
  // The physical span of the register's whole count range (|scale| times 2^16 or 2^32; infinite
  // for float32): a value that moves by more than half of it between two readings can only be
  // a wrap of the count (or a corrupt reply), never a move.
  double count_span() const noexcept;
  // What the register reads for `physical` on a device whose count wraps at the type's range (as
  // encoder counters do) instead of saturating as encode() does; float32 unchanged. Emulators.
  double wrapped(double physical) const noexcept;
};

// A contiguous span of one table that one request reads (at most 125 registers).
struct RegisterBlock {
  RegisterTable table;
  std::uint16_t start;
  std::uint16_t count;
  std::string names;  // "status, actual_position"
};

// The register and bit names a device's map may use (ModbusDriveConfig::map_names and
// ModbusTransducerConfig::map_names): a device reads only the names it knows, so any other name is
// a typo that would leave a register silently out (`staus:` lost the transducer's fault bit).
struct MapNames {
  std::vector<std::string> registers, bits;
};

class RegisterMap {
 public:
  // `node` holds `registers:` (and optional `bits:`); errors name file:line and key.
  static RegisterMap from_yaml(const cfg::Node& node);
  static RegisterMap load(const std::filesystem::path& file);

  const Register* find(std::string_view name) const;
  // Throws std::invalid_argument naming the map and the missing register.
  const Register& at(std::string_view name) const;
  const std::vector<Register>& registers() const { return registers_; }
  int bit(std::string_view name, int fallback) const;
  const std::string& origin() const { return origin_; }
  // Refuses a register or bit name outside `names` (cfg::Error naming file:line:key and the
  // closest allowed name). A map not read from YAML has nothing to check.
  void allow_names(const MapNames& names) const;

  // The fewest requests that read `names` (missing names skipped).
  std::vector<RegisterBlock> blocks(const std::vector<std::string>& names) const;
  // [first, end) addresses the table uses; {0, 0} when empty. For a server's register space.
  std::pair<std::uint16_t, std::uint32_t> extent(RegisterTable table) const;

 private:
  std::vector<Register> registers_;
  std::map<std::string, int, std::less<>> bits_;
  std::string origin_;
  std::shared_ptr<const cfg::Node> registers_node_, bits_node_;  // where the names were read
};

std::string_view to_string(RegisterTable t);

}  // namespace hil::drv

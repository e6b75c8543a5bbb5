#include "hil/drv/modbus_map.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "hil/config.hpp"
#include "hil/drv/modbus.hpp"

namespace hil::drv {

std::string_view to_string(RegisterTable t) { return t == RegisterTable::holding ? "holding" : "input"; }

namespace {
std::uint32_t join(const std::uint16_t* w, WordOrder o) {
  return o == WordOrder::big ? (std::uint32_t{w[0]} << 16 | w[1]) : (std::uint32_t{w[1]} << 16 | w[0]);
}
void split(std::uint32_t v, std::uint16_t* w, WordOrder o) {
  const auto hi = static_cast<std::uint16_t>(v >> 16), lo = static_cast<std::uint16_t>(v);
  if (o == WordOrder::big)
    w[0] = hi, w[1] = lo;
  else
    w[0] = lo, w[1] = hi;
}
template <class T>
T saturate(double x) {
  if (std::isnan(x)) return 0;
  x = std::nearbyint(x);
  if (x <= static_cast<double>(std::numeric_limits<T>::min())) return std::numeric_limits<T>::min();
  if (x >= static_cast<double>(std::numeric_limits<T>::max())) return std::numeric_limits<T>::max();
  return static_cast<T>(x);
}
}  // namespace

double Register::decode(const std::uint16_t* w) const noexcept {
  double raw = 0;
  switch (type) {
    case RegisterType::int16: raw = static_cast<std::int16_t>(w[0]); break;
    case RegisterType::uint16: raw = w[0]; break;
    case RegisterType::int32: raw = static_cast<std::int32_t>(join(w, word_order)); break;
    case RegisterType::uint32: raw = join(w, word_order); break;
    case RegisterType::float32: raw = std::bit_cast<float>(join(w, word_order)); break;
  }
  return raw * scale + offset;
}

void Register::encode(double physical, std::uint16_t* w) const noexcept {
  const double raw = (physical - offset) / scale;
  switch (type) {
    case RegisterType::int16: w[0] = static_cast<std::uint16_t>(saturate<std::int16_t>(raw)); break;
    case RegisterType::uint16: w[0] = saturate<std::uint16_t>(raw); break;
    case RegisterType::int32: split(static_cast<std::uint32_t>(saturate<std::int32_t>(raw)), w, word_order); break;
    case RegisterType::uint32: split(saturate<std::uint32_t>(raw), w, word_order); break;
    case RegisterType::float32: split(std::bit_cast<std::uint32_t>(static_cast<float>(raw)), w, word_order); break;
  }
}

namespace {
// Counts in the type's range and its lowest count; 0 for float32 (no count).
std::pair<double, double> count_range(RegisterType t) {
  switch (t) {
    case RegisterType::int16: return {65536.0, -32768.0};
    case RegisterType::uint16: return {65536.0, 0.0};
    case RegisterType::int32: return {4294967296.0, -2147483648.0};
    case RegisterType::uint32: return {4294967296.0, 0.0};
    case RegisterType::float32: break;
  }
  return {0.0, 0.0};
}
}  // namespace

double Register::count_span() const noexcept {
  const double counts = count_range(type).first;
  return counts > 0 ? counts * std::abs(scale) : std::numeric_limits<double>::infinity();
}

double Register::wrapped(double physical) const noexcept {
  const auto [counts, lowest] = count_range(type);
  if (!(counts > 0) || !std::isfinite(physical)) return physical;
  const double raw = std::nearbyint((physical - offset) / scale);
  return (raw - counts * std::floor((raw - lowest) / counts)) * scale + offset;
}

std::string Register::where() const {
  return std::string(to_string(table)) + " register " + std::to_string(address) + " (" + name + ")";
}

RegisterMap RegisterMap::from_yaml(const cfg::Node& node) {
  node.allow_keys({"registers", "bits"});
  RegisterMap m;
  m.origin_ = node.file().string();
  for (const auto& [name, n] : node.at("registers").entries()) {
    n.allow_keys({"table", "address", "type", "word_order", "scale", "offset"});
    Register r;
    r.name = name;
    const std::string table = n.text("table");
    if (table == "holding")
      r.table = RegisterTable::holding;
    else if (table == "input")
      r.table = RegisterTable::input;
    else
      n.at("table").fail("must be holding or input, got '" + table + "'");
    const long long addr = n.at("address").integer();
    n.at("address").require(addr >= 0 && addr <= 65535, "a register address is 0..65535");
    r.address = static_cast<std::uint16_t>(addr);
    const std::string type = n.text("type");
    if (type == "int16")
      r.type = RegisterType::int16;
    else if (type == "uint16")
      r.type = RegisterType::uint16;
    else if (type == "int32")
      r.type = RegisterType::int32;
    else if (type == "uint32")
      r.type = RegisterType::uint32;
    else if (type == "float32")
      r.type = RegisterType::float32;
    else
      n.at("type").fail("must be int16, uint16, int32, uint32 or float32, got '" + type + "'");
    const std::string order = n.text("word_order", "big");
    if (order == "little")
      r.word_order = WordOrder::little;
    else if (order != "big")
      n.at("word_order").fail("must be big (high word first) or little, got '" + order + "'");
    if (r.words() == 1 && n.has("word_order")) n.at("word_order").fail("a 16-bit register has no word order");
    r.scale = n.number("scale", 1.0);
    if (auto s = n.find("scale")) s->require(r.scale != 0.0, "must not be 0");
    r.offset = n.number("offset", 0.0);
    n.at("address").require(addr + r.words() <= 65536, "the register runs past address 65535");
    for (const auto& other : m.registers_) {
      if (other.table == r.table && r.address < other.address + other.words() && other.address < r.address + r.words()) {
        n.at("address").fail("overlaps " + other.where());
      }
    }
    m.registers_.push_back(r);
  }
  m.registers_node_ = std::make_shared<const cfg::Node>(node.at("registers"));
  if (auto bits = node.find("bits")) {
    m.bits_node_ = std::make_shared<const cfg::Node>(*bits);
    for (const auto& [name, b] : bits->entries()) {
      const long long v = b.integer();
      b.require(v >= 0 && v <= 15, "a bit number is 0..15");
      m.bits_[name] = static_cast<int>(v);
    }
  }
  return m;
}

void RegisterMap::allow_names(const MapNames& names) const {
  if (registers_node_) registers_node_->allow_keys(names.registers);
  if (bits_node_) bits_node_->allow_keys(names.bits);
}

RegisterMap RegisterMap::load(const std::filesystem::path& file) { return from_yaml(cfg::Node::load_file(file)); }

const Register* RegisterMap::find(std::string_view name) const {
  for (const auto& r : registers_) {
    if (r.name == name) return &r;
  }
  return nullptr;
}

const Register& RegisterMap::at(std::string_view name) const {
  if (const auto* r = find(name)) return *r;
  throw std::invalid_argument(origin_ + ": register map has no register '" + std::string(name) + "'");
}

int RegisterMap::bit(std::string_view name, int fallback) const {
  const auto it = bits_.find(name);
  return it == bits_.end() ? fallback : it->second;
}

std::vector<RegisterBlock> RegisterMap::blocks(const std::vector<std::string>& names) const {
  std::vector<const Register*> regs;
  for (const auto& n : names) {
    if (const auto* r = find(n)) regs.push_back(r);
  }
  std::sort(regs.begin(), regs.end(), [](const Register* a, const Register* b) {
    return a->table != b->table ? a->table < b->table : a->address < b->address;
  });
  std::vector<RegisterBlock> out;
  for (const auto* r : regs) {
    const std::uint32_t end = r->address + r->words();
    // Join a block when the gap is small (reading a few unused registers beats another round trip).
    if (!out.empty() && out.back().table == r->table && r->address <= out.back().start + out.back().count + 8 &&
        end - out.back().start <= 125) {
      out.back().count = static_cast<std::uint16_t>(std::max<std::uint32_t>(out.back().count, end - out.back().start));
      out.back().names += ", " + r->name;
    } else {
      out.push_back({r->table, r->address, static_cast<std::uint16_t>(r->words()), r->name});
    }
  }
  return out;
}

std::pair<std::uint16_t, std::uint32_t> RegisterMap::extent(RegisterTable table) const {
  std::uint32_t first = 65536, end = 0;
  for (const auto& r : registers_) {
    if (r.table != table) continue;
    first = std::min<std::uint32_t>(first, r.address);
    end = std::max<std::uint32_t>(end, r.address + r.words());
  }
  if (end == 0) return {0, 0};
  return {static_cast<std::uint16_t>(first), end};
}

// Modbus exception codes (Modbus Application Protocol 1.1b3, 7).
std::string_view modbus_exception_name(int code) {
  switch (code) {
    case 0x01: return "ILLEGAL FUNCTION";
    case 0x02: return "ILLEGAL DATA ADDRESS";
    case 0x03: return "ILLEGAL DATA VALUE";
    case 0x04: return "SERVER DEVICE FAILURE";
    case 0x05: return "ACKNOWLEDGE";
    case 0x06: return "SERVER DEVICE BUSY";
    case 0x07: return "NEGATIVE ACKNOWLEDGE";
    case 0x08: return "MEMORY PARITY ERROR";
    case 0x0A: return "GATEWAY PATH UNAVAILABLE";
    case 0x0B: return "GATEWAY TARGET DEVICE FAILED TO RESPOND";
    default: return "UNKNOWN EXCEPTION";
  }
}

}  // namespace hil::drv

// Fuzz target "config": the bytes as a YAML file, read the three ways a configuration is read:
//   1. hil::cfg::Node (common/): load_string, then every node visited with every typed accessor;
//   2. the campaign loader, hil::bench::load_campaign_text, with relative paths resolved from
//      configs/campaigns/ (so "plant: ../plant/nominal.yaml" loads the shipped plant);
//   3. the plant loader, hil::plant::Plant::load, from a file (Node::load_file too).
// Clear errors: hil::cfg::Error (file:line:column: key: what).
#include <cstddef>
#include <cstdint>
#include <string>

#include "fuzz_support.hpp"
#include "hil/bench/campaign/campaign.hpp"
#include "hil/config.hpp"
#include "hil/plant/plant.hpp"

namespace {

void visit(const hil::cfg::Node& n, int depth) {
  if (depth > 64) return;
  auto typed = [&](auto&& read) { hil::fuzz::expect_clear_errors<hil::cfg::Error>("cfg::Node accessor", read); };
  if (n.is_map()) {
    for (const auto& [key, child] : n.entries()) {
      (void)n.has(key);
      visit(child, depth + 1);
    }
    typed([&] { n.allow_keys({"name", "plant", "effects", "gas_generator"}); });
    typed([&] { (void)n.number("duration_s", 1.0); });
  } else if (n.is_sequence()) {
    for (const auto& item : n.items()) visit(item, depth + 1);
    typed([&] { (void)n.numbers(); });
  } else {
    typed([&] { (void)n.number(); });
    typed([&] { (void)n.integer(); });
    typed([&] { (void)n.boolean(); });
    typed([&] { (void)n.text(); });
    typed([&] { (void)n.resolve_path(n.text()); });
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static hil::fuzz::InputFile plant_file("plant.yaml");
  const std::string text(reinterpret_cast<const char*>(data), size);

  hil::fuzz::expect_clear_errors<hil::cfg::Error>("cfg::Node::load_string",
                                                  [&] { visit(hil::cfg::Node::load_string(text, "fuzz.yaml"), 0); });
  hil::fuzz::expect_clear_errors<hil::cfg::Error>("bench::load_campaign_text", [&] {
    (void)hil::bench::load_campaign_text(text, "fuzz.yaml", HIL_SOURCE_DIR "/configs/campaigns");
  });
  hil::fuzz::expect_clear_errors<hil::cfg::Error>("plant::Plant::load",
                                                  [&] { (void)hil::plant::Plant::load(plant_file.write(data, size)); });
  return 0;
}

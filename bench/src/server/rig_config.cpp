#include "hil/bench/rig_config.hpp"

#include <fstream>
#include <sstream>

#include "hil/bench/sim_rig.hpp"
#include "hil/config.hpp"

namespace hil::bench {
namespace {

const std::vector<std::string> kKinds = {"sim"};

RigConfig from_node(const cfg::Node& root, std::string name, std::string text) {
  root.allow_keys({"kind", "description", "loop", "safety"});
  RigConfig c;
  c.name = std::move(name);
  c.file = root.file();
  c.yaml_text = std::move(text);
  c.kind = root.text("kind");
  if (std::find(kKinds.begin(), kKinds.end(), c.kind) == kKinds.end()) {
    const std::string hint = cfg::closest(c.kind, kKinds);
    root.at("kind").fail("unknown rig kind '" + c.kind + "'" + (hint.empty() ? "" : " (did you mean '" + hint + "'?)") +
                         "; this build knows: sim");
  }
  c.description = root.text("description", "");
  if (const auto loop = root.find("loop")) c.loop = LoopConfig::from_yaml(*loop);
  c.safety = SafetyConfig::from_yaml(root.at("safety"));
  return c;
}

}  // namespace

RigConfig load_rig_config(const std::filesystem::path& file) {
  const cfg::Node root = cfg::Node::load_file(file);
  std::ifstream in(file, std::ios::binary);
  std::stringstream text;
  text << in.rdbuf();
  return from_node(root, file.stem().string(), text.str());
}

RigConfig load_rig_config_text(const std::string& yaml, const std::string& origin) {
  return from_node(cfg::Node::load_string(yaml, origin), std::filesystem::path(origin).stem().string(), yaml);
}

std::unique_ptr<Rig> make_rig(const RigConfig& config) {
  if (config.kind == "sim") return std::make_unique<SimRig>();
  throw std::invalid_argument(config.file.string() + ": rig kind '" + config.kind + "' is not built in");
}

}  // namespace hil::bench

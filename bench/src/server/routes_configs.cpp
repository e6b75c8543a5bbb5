// The configuration files the server can use: GET /api/campaigns, /api/rigs and /api/models, each
// listing its folder's YAML files with what a load of each says (or its error).
#include <cmath>

#include "analyses.hpp"
#include "api_router.hpp"
#include "hil/config.hpp"
#include "hil/config_files.hpp"
#include "hil/plant/plant.hpp"
#include "hil/units.hpp"

namespace hil::bench::api {
namespace {

using Listings = ApiServer::Impl::Listings;
using Listing = ApiServer::Impl::Listing;

// The entries of dir/*.yaml, each {"name", "file"} and what `describe` adds (or its "error"),
// from `kept` while every file read for it is unchanged. `kept` becomes this listing: files
// gone are forgotten.
// Loading a config file runs on the io thread, which serves every request: an unchanged one is not
// loaded again (a large register map took seconds at each GET /api/rigs; every campaign, its plant
// and its reference CSV were parsed at each GET /api/campaigns, every plant model at each GET
// /api/models).
json listing(Listings& kept, const std::filesystem::path& dir,
             const std::function<void(const std::filesystem::path& file, json& entry)>& describe) {
  Listings now;
  json list = json::array();
  for (const auto& name : yaml_stems(dir)) {
    if (const auto old = kept.find(name); old != kept.end() && cfg::unchanged(old->second.files)) {
      list.push_back(old->second.entry);
      now.insert(kept.extract(old));
      continue;
    }
    const auto file = dir / (name + ".yaml");
    json j = {{"name", name}, {"file", file.string()}};
    cfg::ReadFiles read;
    try {
      // A file that is a link to one outside its folder (a model -> /etc/shadow) is not read: a
      // YAML error would quote its first line to any client.
      if (!resolves_inside(file, dir))
        throw std::runtime_error(file.string() + ": a symbolic link to a file outside " + dir.string() + ": not read");
      describe(file, j);
    } catch (const std::exception& e) {
      j["error"] = e.what();
    }
    list.push_back(j);
    now.emplace(name, Listing{std::move(j), read.files()});
  }
  kept = std::move(now);
  return list;
}

Reply campaigns(ApiServer::Impl& api) {
  const json list = listing(api.campaign_listings, api.options.campaigns_dir, [](const std::filesystem::path& file, json& j) {
    const Campaign c = load_campaign(file);
    j["description"] = c.description;
    j["duration_s"] = c.duration_s;
    j["period_ms"] = c.period_s * 1e3;
    j["runs"] = json::array();
    for (const auto& r : c.runs) j["runs"].push_back(r.name);
  });
  return json_reply(http::status::ok, {{"campaigns", list}});
}

Reply rigs(ApiServer::Impl& api) {
  const json list = listing(api.rig_listings, api.options.rigs_dir, [](const std::filesystem::path& file, json& j) {
    const RigConfig r = load_rig_config(file);
    j["kind"] = r.kind;
    j["description"] = r.description;
    j["priority"] = r.loop.priority;
    j["cpu"] = r.loop.cpu;
    j["following_error"] =
        r.safety.watches_following()
            ? json{{"max_deg", std::round(units::rad_to_deg(r.safety.following_error_rad) * 1e9) / 1e9},  // as written
                   {"time_ms", std::lround(r.safety.following_error_s * 1000)}}
            : json(nullptr);
    if (const std::string w = rig_warning(r); !w.empty()) j["warning"] = w;
  });
  return json_reply(http::status::ok, {{"rigs", list}});
}

Reply models(ApiServer::Impl& api) {
  const json list = listing(api.model_listings, api.options.plant_dir, [](const std::filesystem::path& file, json& j) {
    const cfg::Node root = cfg::Node::load_file(file);  // read once: checked as a plant, then its description
    (void)plant::Plant::from_yaml(root);
    j["description"] = root.text("description", "");
  });
  return json_reply(http::status::ok, {{"models", list}, {"kinds", {kAnalysisKinds[0], kAnalysisKinds[1]}}});
}

}  // namespace

std::vector<Route> config_routes() {
  return {
      {50,
       http::verb::get,
       "/api/campaigns",
       "the campaign files the server can run",
       [](const Call& c) { return campaigns(c.api); },
       {},
       {},
       Thread::worker},
      {60, http::verb::get, "/api/rigs", "the rig files", [](const Call& c) { return rigs(c.api); }, {}, {}, Thread::worker},
      {70,
       http::verb::get,
       "/api/models",
       "the plant models a run can be analysed against",
       [](const Call& c) { return models(c.api); },
       {},
       {},
       Thread::worker},
  };
}

}  // namespace hil::bench::api

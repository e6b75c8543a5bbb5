// Valve angle -> throat area: a monotone table, linear between points, clamped at its ends.
#include <algorithm>

#include "hil/config.hpp"
#include "hil/plant/registry.hpp"
#include "hil/units.hpp"

namespace hil::plant {

class ThroatMap final : public Effect {
 public:
  static constexpr std::string_view kKind = "throat_map";
  static constexpr Stage kStage = Stage::throat;
  static constexpr std::string_view kTablesDoc =
      "angle_deg: valve angles [deg], strictly increasing, within -360..360 (at least two); "
      "area_mm2: the throat area [mm^2] at each angle, positive, not falling, at most 100000";

  ThroatMap(std::vector<double> angle_deg, std::vector<double> area_mm2)
      : angle_deg_(std::move(angle_deg)), area_mm2_(std::move(area_mm2)) {
    for (double a : angle_deg_) angle_rad_.push_back(units::deg_to_rad(a));
    for (double a : area_mm2_) area_m2_.push_back(a * units::kM2PerMm2);
    slope_m2_per_rad_.push_back(0);
    for (std::size_t i = 1; i < angle_rad_.size(); ++i)
      slope_m2_per_rad_.push_back((area_m2_[i] - area_m2_[i - 1]) / (angle_rad_[i] - angle_rad_[i - 1]));
  }
  static std::shared_ptr<const Effect> from_yaml(const cfg::Node& block) {
    block.allow_keys({"angle_deg", "area_mm2"});
    const cfg::Node angle = block.at("angle_deg"), area = block.at("area_mm2");
    auto a = angle.numbers(), b = area.numbers();
    angle.require(a.size() >= 2, "needs at least two points");
    area.require(b.size() == a.size(), "needs one area per angle (" + std::to_string(a.size()) + ")");
    for (std::size_t i = 1; i < a.size(); ++i) {
      angle.require(a[i] > a[i - 1], "angles must increase strictly");
      area.require(b[i] >= b[i - 1], "area must not fall as the valve opens (the map is monotone)");
    }
    area.require(b.front() > 0, "areas must be positive (a closed throat has no steady state)");
    // Beyond these a number is a typo, not a valve: a full turn each way, a throat 35 cm across.
    angle.require(a.front() >= -360 && a.back() <= 360, "angles must lie within -360..360 deg");
    area.require(b.back() <= 1e5, "areas must be at most 100000 mm^2");
    return std::make_shared<ThroatMap>(std::move(a), std::move(b));
  }

  std::string_view kind() const noexcept override { return kKind; }
  Stage stage() const noexcept override { return kStage; }
  void settle(std::span<double>, Signals& s) const override { s.throat_area_m2 = area_at(s.theta_throat_rad); }
  void step(std::span<double>, Signals& s, double, Rng&) const noexcept override {
    s.throat_area_m2 = area_at(s.theta_throat_rad);
  }
  std::vector<Param> params() const override { return {}; }
  std::span<const ParamSpec> specs() const noexcept override { return {}; }
  std::shared_ptr<const Effect> with_params(std::span<const double>) const override {
    return std::make_shared<ThroatMap>(angle_deg_, area_mm2_);
  }
  std::vector<Table> tables() const override { return {{"angle_deg", angle_deg_}, {"area_mm2", area_mm2_}}; }

 private:
  double area_at(double angle_rad) const noexcept {
    if (angle_rad <= angle_rad_.front()) return area_m2_.front();
    if (angle_rad >= angle_rad_.back()) return area_m2_.back();
    std::size_t i = 1;
    while (angle_rad > angle_rad_[i]) ++i;
    // The segment's slope is set once: a division here would sit on the period's chain from the
    // command to the pressure.
    return area_m2_[i - 1] + (angle_rad - angle_rad_[i - 1]) * slope_m2_per_rad_[i];
  }
  std::vector<double> angle_deg_, area_mm2_, angle_rad_, area_m2_, slope_m2_per_rad_;
};

HIL_REGISTER_EFFECT(ThroatMap, "valve angle to throat area, monotone table")

}  // namespace hil::plant

// A compensator added the way a controls engineer adds one: this file and nothing else. Motion
// intention from the integral command's retreat past a dead-band (the paper's eq. (3) with
// hysteresis); at each reversal it jumps jump_scale x the gap it knows (sigma with `constant`,
// sigma_r(0) with `adaptive`: it learns nothing). The touch state it reports is the flank ahead.
#include <algorithm>

#include "hil/ctl/compensator.hpp"

namespace hil::ctl {
namespace {

struct KnownGapState {
  double int_cmd_rad = 0;  // the integral command, without jumps
  double extreme_rad = 0;  // its extreme in the current direction
  int intention = 0;
  double gap_rad = 0;
};

class KnownGapCompensator final : public CompensatorOf<KnownGapCompensator, KnownGapState> {
 public:
  static constexpr std::string_view kName = "test_known_gap";
  static constexpr ParamSpec kSpecs[] = {
      {"deadband_deg", 0, 1, false, false, 0.05, "retreat of the integral command that is a reversal"},
      {"jump_scale", 0, 2, false, false, 1.0, "the jump, as a fraction of the known gap"},
  };

  KnownGapCompensator(const CompensatorSetup& setup, std::span<const double> v)
      : law_(setup.compensation),
        gap_rad_(setup.compensation == Compensation::constant ? setup.gap_known_rad : setup.gap_initial_rad),
        deadband_rad_(v[0] * units::kRadPerDeg),
        jump_scale_(v[1]) {}

  KnownGapState initial(double, double, int touch) const noexcept { return {0, 0, touch, gap_rad_}; }

  void step(KnownGapState& s, const CompensatorInputs& in, CompensatorOutputs& out) const noexcept {
    s.int_cmd_rad += in.cmd_step_rad;
    if (s.intention == 0) {
      s.intention = (in.cmd_step_rad > 0) - (in.cmd_step_rad < 0);
      s.extreme_rad = s.int_cmd_rad;
    } else if (s.intention * (s.int_cmd_rad - s.extreme_rad) > 0) {
      s.extreme_rad = s.int_cmd_rad;  // still going the same way
    } else if (s.intention * (s.extreme_rad - s.int_cmd_rad) > deadband_rad_) {
      s.intention = -s.intention;
      s.extreme_rad = s.int_cmd_rad;
      out.reversed = true;
      if (law_ != Compensation::none) out.comp_rad = s.intention * jump_scale_ * s.gap_rad;
    }
    out.intention = s.intention;
    out.touch = s.intention;
    out.gap_est_rad = s.gap_rad;
  }

 private:
  Compensation law_;
  double gap_rad_, deadband_rad_, jump_scale_;
};

}  // namespace

HIL_REGISTER_COMPENSATOR(KnownGapCompensator, "test: jumps a fraction of the known gap at each reversal")

}  // namespace hil::ctl

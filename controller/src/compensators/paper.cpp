// The paper's compensator, as written: motion intention eq. (3), touch state eq. (4)
// (PaperObserver, observer.hpp), the jump of eq. (7) (+-sigma when the touch state leaves a flank)
// and the adaptive law (10) (sigma_r grows by the command's travel while in transition). Kept to
// reproduce the paper and to show why the robust compensator exists.
#include <array>

#include "hil/ctl/compensator.hpp"
#include "hil/ctl/observer.hpp"

namespace hil::ctl {
namespace {

struct PaperState {
  PaperObserverState obs;
  double gap_est_rad = 0;  // sigma (constant) or sigma_r (adaptive; learned also with none)
};

class PaperCompensator final : public CompensatorOf<PaperCompensator, PaperState> {
 public:
  static constexpr std::string_view kName = "paper";
  static constexpr std::array<ParamSpec, 0> kSpecs{};  // the paper's method has no settings

  PaperCompensator(const CompensatorSetup& setup, std::span<const double>) : setup_(setup) {}

  PaperState initial(double, double p_meas_pa, int touch) const noexcept {
    PaperState s;
    s.gap_est_rad = setup_.compensation == Compensation::constant ? setup_.gap_known_rad : setup_.gap_initial_rad;
    s.obs = observer_.initial_state(touch, p_meas_pa);
    return s;
  }

  void step(PaperState& s, const CompensatorInputs& in, CompensatorOutputs& out) const noexcept {
    const bool constant = setup_.compensation == Compensation::constant;
    const double gap_before = constant ? setup_.gap_known_rad : s.gap_est_rad;
    const ObserverInputs obs_in{in.cmd_step_rad, in.error_pa, in.p_meas_pa, in.motor_rad, in.tau_s, in.volume_m3, 0};
    const ObserverOutputs obs = observer_.step(s.obs, obs_in);
    if (!constant) s.gap_est_rad += obs.transition_travel_rad;  // law (10)
    // Eq. (7) with sigma (constant) or sigma_r (adaptive) as it was before this step's law (10).
    if (setup_.compensation != Compensation::none) out.comp_rad = obs.kick * gap_before;
    out.touch = obs.touch;
    out.intention = obs.intention;
    out.gap_est_rad = s.gap_est_rad;
  }

 private:
  CompensatorSetup setup_;
  PaperObserver observer_;
};

}  // namespace

HIL_REGISTER_COMPENSATOR(PaperCompensator, "the paper's observer, eqs. (3), (4), its jump (7) and adaptive law (10)")

}  // namespace hil::ctl

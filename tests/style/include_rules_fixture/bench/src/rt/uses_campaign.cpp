// Breaks the rule on purpose: rt/ may not include campaign/ (see check_include_rules.sh).
#include "hil/bench/campaign/campaign.hpp"

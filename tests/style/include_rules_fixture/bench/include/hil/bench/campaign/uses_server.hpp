// Breaks the rule on purpose: campaign/ may not include server/ (see check_include_rules.sh).
#pragma once

#include "../server/runner.hpp"

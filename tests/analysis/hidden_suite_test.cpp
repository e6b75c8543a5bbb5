#include <gtest/gtest.h>
#include "hidden_suite.hpp"
TEST(HiddenSuite, Placeholder) {}

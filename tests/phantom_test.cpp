// placeholder
#include <gtest/gtest.h>
TEST(Phantom, Placeholder) {}

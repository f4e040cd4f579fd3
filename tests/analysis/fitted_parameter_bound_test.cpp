// A fitted parameter the data does not fix within its search's bounds says so (issue 50: OS2's
// bias_factor "-2 .. 2", the tails' probability at its bound 1, printed as if fitted).
#include <gtest/gtest.h>

#include "lidartwin/analysis/diagnosis.h"

namespace lidartwin {
namespace {

FittedParameter parameter(double value, double lo, double hi, double lower, double upper) {
  FittedParameter p;
  p.name = "bias_factor";
  p.value = value;
  p.ci95_lo = lo;
  p.ci95_hi = hi;
  p.lower = lower;
  p.upper = upper;
  return p;
}

TEST(FittedParameterBound, AValueAtABoundOrAnIntervalSpanningBothIsNamed) {
  EXPECT_EQ(bound_note(parameter(0.1, 0.05, 0.15, -2.0, 2.0)), "");
  EXPECT_EQ(bound_note(parameter(2.0, 1.5, 2.0, -2.0, 2.0)), "at its upper bound 2");
  EXPECT_EQ(bound_note(parameter(0.0, 0.0, 0.01, 0.0, 1.0)), "at its lower bound 0");
  EXPECT_EQ(bound_note(parameter(-0.04, -2.0, 2.0, -2.0, 2.0)), "its interval spans its bounds -2 .. 2");
  // An interval that reaches one bound only is a one-sided interval, not an unfixed value.
  EXPECT_EQ(bound_note(parameter(0.3, 0.0, 0.7, 0.0, 1.0)), "");
  FittedParameter unknown;  // bounds not known (a refit that does not search within any)
  unknown.value = 5.0;
  EXPECT_EQ(bound_note(unknown), "");
}

}  // namespace
}  // namespace lidartwin

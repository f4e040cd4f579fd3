// excess_note: where a better fit's excess over its own expectation moves away from 0 (the real
// OS-1-128 against os1-128 and its recommended fit: -3.1 to +6.2 standard errors, the NLL 0.05 a
// pixel lower), the report says why, with the parts of the excess that cannot cancel.
#include <string>

#include <gtest/gtest.h>

#include "lidartwin/analysis/compare_report.h"

namespace lidartwin {
namespace {

WaterfallStep step(const std::string& profile, double nll, double excess_se, double below, double above) {
  WaterfallStep w;
  w.profile = profile;
  w.nll_se = 0.002;
  w.nll_per_pixel = nll;
  w.nll_expected = nll - excess_se * w.nll_se;
  w.excess_below = below;
  w.excess_above = above;
  return w;
}

TEST(ExcessNote, ABetterFitWhoseExcessGrowsSaysWhy) {
  const std::string note =
      excess_note(step("os1-128", 2.4935, -3.1, -0.0583, 0.0512), step("fitted", 2.4416, 6.2, -0.0476, 0.0620));
  EXPECT_EQ(note.rfind("fitted fits better than os1-128 (NLL 0.0519 a pixel lower) although its excess moved from "
                       "-3.1 to +6.2 standard errors",
                       0),
            0u)
      << note;
  EXPECT_NE(note.find("os1-128 is -0.0583 nats a pixel where its NLL lies below its expectation"), std::string::npos)
      << note;
  EXPECT_NE(note.find("fitted -0.0476 and +0.0620"), std::string::npos) << note;
}

TEST(ExcessNote, AWorseFitWhoseExcessIsNearerZeroIsNotCalledBetter) {
  const std::string note = excess_note(step("tight", 2.40, 8.0, -0.01, 0.05), step("wide", 2.45, 0.5, -0.04, 0.04));
  EXPECT_EQ(note.rfind("wide fits worse than tight (NLL 0.0500 a pixel higher) although its excess is nearer 0", 0), 0u)
      << note;
}

TEST(ExcessNote, NothingToSayWhereNllAndExcessAgree) {
  EXPECT_EQ(excess_note(step("a", 2.5, 12.0, -0.01, 0.08), step("b", 2.4, 0.4, -0.01, 0.01)), "");
  EXPECT_EQ(excess_note(step("a", 2.5, 1.0, -0.01, 0.02), step("b", 2.49, 1.5, -0.01, 0.02)), "");
}

}  // namespace
}  // namespace lidartwin

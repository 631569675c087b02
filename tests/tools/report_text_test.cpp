// Numbers in fogctl's reports (tools/fogctl/report_text): fixed decimals, JSON numbers, and what
// stands for a number that is not finite in each (NaN is not JSON).
#include "tools/fogctl/report_text.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

namespace fogmap::cli {
namespace {

TEST(ReportText, FixedTextRoundsToTheDigitsAsked) {
  EXPECT_EQ(fixedText(1.23456, 2), "1.23");
  EXPECT_EQ(fixedText(-0.0005, 3), "-0.001");
  EXPECT_EQ(fixedText(149.96, 1), "150.0");
  EXPECT_EQ(fixedText(7.0, 0), "7");
}

TEST(ReportText, ANumberThatIsNotFiniteIsNotApplicableInTextAndNullInJson) {
  for (const double v : {std::nan(""), std::numeric_limits<double>::infinity(), -std::numeric_limits<double>::infinity()}) {
    EXPECT_EQ(fixedText(v, 3), "n/a");
    EXPECT_EQ(jsonNumber(v), "null");
  }
}

TEST(ReportText, JsonNumbersKeepTenSignificantDigits) {
  EXPECT_EQ(jsonNumber(0.1), "0.1");
  EXPECT_EQ(jsonNumber(-3.0), "-3");
  EXPECT_EQ(jsonNumber(2.0 / 3.0), "0.6666666667");
  EXPECT_EQ(jsonNumber(1.5e-12), "1.5e-12");
  EXPECT_EQ(jsonNumber(123456789012.0), "1.23456789e+11");
}

}  // namespace
}  // namespace fogmap::cli

// Numbers in fogctl's reports (harness/report_text): fixed decimals, JSON numbers, and what
// stands for a number that is not finite in each (NaN is not JSON); the reports' JSON text.
#include "harness/report_text.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>

namespace fogmap::harness {
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
    EXPECT_TRUE(jsonNumber(v).is_null());
    EXPECT_EQ(jsonNumber(v).dump(), "null");
  }
}

TEST(ReportText, FormatTextIsPrintfIntoAStringOfAnyLength) {
  EXPECT_EQ(formatText("%5zu|%-4s|%.2f", std::size_t{42}, "ab", 3.14159), "   42|ab  |3.14");
  EXPECT_EQ(formatText("%s", ""), "");
  const std::string long_text(5000, 'x');
  EXPECT_EQ(formatText("<%s>", long_text.c_str()), "<" + long_text + ">");
}

TEST(ReportText, JsonNumbersKeepTenSignificantDigits) {
  EXPECT_EQ(jsonNumber(0.1).dump(), "0.1");
  EXPECT_EQ(jsonNumber(-3.0).dump(), "-3.0");
  EXPECT_EQ(jsonNumber(2.0 / 3.0).dump(), "0.6666666667");
  EXPECT_EQ(jsonNumber(1.5e-12).dump(), "1.5e-12");
  EXPECT_EQ(jsonNumber(123456789012.0).dump(), "123456789000.0");
  EXPECT_TRUE(jsonNumber(7.0).is_number());
}

TEST(ReportText, JsonReportsKeepTheirKeyOrderAndEndWithANewline) {
  Json report;
  report["zeta"] = 1;
  report["alpha"] = jsonNumber(0.5);
  report["name"] = "a \"quoted\"\nname";
  EXPECT_EQ(jsonText(report), "{\n  \"zeta\": 1,\n  \"alpha\": 0.5,\n  \"name\": \"a \\\"quoted\\\"\\nname\"\n}\n");
  // Bytes that are not UTF-8 (a path, say) are replaced, not refused.
  Json odd;
  odd["path"] = std::string("caf\xe9");
  EXPECT_EQ(jsonText(odd), "{\n  \"path\": \"caf\ufffd\"\n}\n");
}

}  // namespace
}  // namespace fogmap::harness

// Error messages made safe for a terminal line (printableMessage): control characters, escape
// sequences, C1 controls and malformed UTF-8 shown escaped; valid UTF-8 kept; long text cut at a
// character boundary with the count of what was left out.
#include <gtest/gtest.h>

#include "preprocess/core/check.h"

namespace strata {
namespace {

TEST(Messages, ControlCharactersAreShownEscaped) {
  EXPECT_EQ(printableMessage("a\nb\tc\x1b[31md\x7f"), "a\\x0ab\\x09c\\x1b[31md\\x7f");
  EXPECT_EQ(printableMessage(std::string("nul\0here", 8)), "nul\\x00here");
}

TEST(Messages, Utf8IsKeptExceptC1ControlsAndMalformedBytes) {
  EXPECT_EQ(printableMessage("caf\xc3\xa9 \xe2\x82\xac \xf0\x9f\x99\x82"),
            "caf\xc3\xa9 \xe2\x82\xac \xf0\x9f\x99\x82");
  EXPECT_EQ(printableMessage("\xc2\x9b" "2J"), "\\xc2\\x9b2J");  // CSI as a C1 control
  EXPECT_EQ(printableMessage("\xff\xfe"), "\\xff\\xfe");
  EXPECT_EQ(printableMessage("\xe2\x82"), "\\xe2\\x82");      // cut short
  EXPECT_EQ(printableMessage("\xc0\xaf"), "\\xc0\\xaf");      // overlong
  EXPECT_EQ(printableMessage("\xed\xa0\x80"), "\\xed\\xa0\\x80");  // a surrogate
}

TEST(Messages, LongTextIsCutWithTheCountLeftOut) {
  const std::string shown = printableMessage(std::string(10000, 'x'), 100);
  EXPECT_EQ(shown, std::string(100, 'x') + "... (9900 more bytes)");
  // Never inside a character.
  std::string euros;
  for (int i = 0; i < 50; ++i) euros += "\xe2\x82\xac";
  const std::string cut = printableMessage(euros, 10);
  EXPECT_EQ(cut, "\xe2\x82\xac\xe2\x82\xac\xe2\x82\xac\xe2\x82\xac... (138 more bytes)");
}

}  // namespace
}  // namespace strata

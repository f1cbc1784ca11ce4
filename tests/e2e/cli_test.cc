// Runs the real `lisfm` executable: help, version, usage errors.
#include <gtest/gtest.h>

#include "tests/common/test_utils.h"

namespace lisfm {
namespace {

using test::LisfmBinary;
using test::RunCommand;

TEST(Cli, HelpListsCommands) {
  std::string out;
  EXPECT_EQ(RunCommand(LisfmBinary() + " help", &out), 0);
  EXPECT_NE(out.find("evaluate"), std::string::npos) << out;
  EXPECT_EQ(RunCommand(LisfmBinary() + " version", &out), 0);
  EXPECT_NE(out.find("lisfm "), std::string::npos);
}

TEST(Cli, UnknownCommandSuggestsAndExits2) {
  std::string out;
  EXPECT_EQ(RunCommand(LisfmBinary() + " evalute", &out), 2);
  EXPECT_NE(out.find("did you mean 'evaluate'"), std::string::npos) << out;
  EXPECT_EQ(out.find("error:"), 0u) << out;
}

TEST(Cli, CommandHelpAndBadOptions) {
  std::string out;
  EXPECT_EQ(RunCommand(LisfmBinary() + " evaluate -h", &out), 0);
  EXPECT_NE(out.find("--reference_path"), std::string::npos) << out;
  // A typo of a former name (alias) suggests the current name.
  EXPECT_EQ(RunCommand(LisfmBinary() + " evaluate --refrence x", &out), 2);
  EXPECT_NE(out.find("did you mean '--reference_path'"), std::string::npos) << out;
  EXPECT_EQ(RunCommand(LisfmBinary() + " evaluate", &out), 2);
  EXPECT_NE(out.find("missing required option '--reference_path'"), std::string::npos) << out;
}

}  // namespace
}  // namespace lisfm

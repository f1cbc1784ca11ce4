#include "core/options.h"

#include <gtest/gtest.h>

#include <fstream>

#include "core/errors.h"
#include "core/logging.h"
#include "tests/common/test_utils.h"

namespace lisfm {
namespace {

struct Args {
  explicit Args(std::vector<std::string> a) : storage(std::move(a)) {
    for (auto& s : storage) ptrs.push_back(s.data());
  }
  int argc() { return static_cast<int>(ptrs.size()); }
  char** argv() { return ptrs.data(); }
  std::vector<std::string> storage;
  std::vector<char*> ptrs;
};

struct Fixture {
  double max_distance = 0.5;
  int iterations = 10;
  bool flag = false;
  std::string method = "point_to_plane";
  std::string input;
  OptionManager options{"lisfm icp", "test command"};
  Fixture() {
    options.AddDouble("Icp.max_distance", &max_distance, "m");
    options.AddInt("Icp.max_iterations", &iterations, "count");
    options.AddBool("Icp.use_flag", &flag, "a flag");
    options.AddChoice("method", &method, {"point_to_plane", "bayesian"}, "method");
    options.AddRequiredString("input_path", &input, "input");
  }
};

TEST(Options, ParsesSectionNamesAndTypes) {
  Fixture f;
  Args a({"lisfm icp", "--Icp.max_distance", "0.25", "--Icp.max_iterations=7", "--Icp.use_flag",
          "1", "--method", "bayesian", "--input_path", "x.pcd"});
  ASSERT_TRUE(f.options.Parse(a.argc(), a.argv()));
  EXPECT_DOUBLE_EQ(f.max_distance, 0.25);
  EXPECT_EQ(f.iterations, 7);
  EXPECT_TRUE(f.flag);
  EXPECT_EQ(f.method, "bayesian");
  EXPECT_EQ(f.input, "x.pcd");
  EXPECT_TRUE(f.options.IsSet("Icp.max_distance"));
}

TEST(Options, BareBooleanMeansTrue) {
  Fixture f;
  Args a({"lisfm icp", "--Icp.use_flag", "--input_path", "x"});
  ASSERT_TRUE(f.options.Parse(a.argc(), a.argv()));
  EXPECT_TRUE(f.flag);
  Fixture g;
  Args b({"lisfm icp", "--Icp.use_flag", "0", "--input_path", "x"});
  ASSERT_TRUE(g.options.Parse(b.argc(), b.argv()));
  EXPECT_FALSE(g.flag);
}

TEST(Options, UnknownOptionSuggestsNearestName) {
  Fixture f;
  Args a({"lisfm icp", "--Icp.max_distanse", "0.25", "--input_path", "x"});
  try {
    f.options.Parse(a.argc(), a.argv());
    FAIL() << "expected UsageError";
  } catch (const UsageError& e) {
    EXPECT_NE(std::string(e.what()).find("did you mean '--Icp.max_distance'"), std::string::npos)
        << e.what();
  }
}

TEST(Options, MissingRequiredAndBadValues) {
  {
    Fixture f;
    Args a({"lisfm icp"});
    EXPECT_THROW(f.options.Parse(a.argc(), a.argv()), UsageError);
  }
  {
    Fixture f;
    Args a({"lisfm icp", "--input_path", "x", "--Icp.max_iterations", "ten"});
    EXPECT_THROW(f.options.Parse(a.argc(), a.argv()), UsageError);
  }
  {
    Fixture f;
    Args a({"lisfm icp", "--input_path", "x", "--method", "gicp"});
    EXPECT_THROW(f.options.Parse(a.argc(), a.argv()), UsageError);
  }
}

TEST(Options, HelpListsEveryOptionWithDefault) {
  Fixture f;
  const std::string help = f.options.HelpText();
  EXPECT_NE(help.find("--Icp.max_distance"), std::string::npos);
  EXPECT_NE(help.find("(=0.5)"), std::string::npos);
  EXPECT_NE(help.find("(=10)"), std::string::npos);
  EXPECT_NE(help.find("--input_path"), std::string::npos);
  EXPECT_NE(help.find("(required)"), std::string::npos);
  Args a({"lisfm icp", "-h"});
  testing::internal::CaptureStdout();
  EXPECT_FALSE(f.options.Parse(a.argc(), a.argv()));
  EXPECT_NE(testing::internal::GetCapturedStdout().find("--Icp.max_iterations"), std::string::npos);
}

TEST(Options, ConfigFileNestedAndFlatCommandLineWins) {
  test::TempDir dir;
  test::WriteText(dir.File("c.yaml"),
                  "Icp:\n  max_distance: 2.0\n  max_iterations: 3\nmethod: bayesian\n"
                  "input_path: from_config.pcd\n");
  Fixture f;
  Args a({"lisfm icp", "--config_path", dir.File("c.yaml"), "--Icp.max_iterations", "9"});
  ASSERT_TRUE(f.options.Parse(a.argc(), a.argv()));
  EXPECT_DOUBLE_EQ(f.max_distance, 2.0);
  EXPECT_EQ(f.iterations, 9);  // command line overrides
  EXPECT_EQ(f.method, "bayesian");
  EXPECT_EQ(f.input, "from_config.pcd");  // required option satisfied by the file

  // Written config loads back to the same values.
  f.options.WriteConfig(dir.File("effective.yaml"));
  Fixture g;
  Args b({"lisfm icp", "--config_path", dir.File("effective.yaml")});
  ASSERT_TRUE(g.options.Parse(b.argc(), b.argv()));
  EXPECT_DOUBLE_EQ(g.max_distance, 2.0);
  EXPECT_EQ(g.iterations, 9);
  EXPECT_EQ(g.input, "from_config.pcd");
  SetLogLevel(LogLevel::kWarning);
}

TEST(Options, BadConfigFileNamesFileAndLine) {
  test::TempDir dir;
  test::WriteText(dir.File("bad.yaml"), "input_path: a\nIcp:\n  max_distanc: 1\n");
  Fixture f;
  Args a({"lisfm icp", "--config_path", dir.File("bad.yaml")});
  EXPECT_TRUE(test::ThrowsInputError([&] { f.options.Parse(a.argc(), a.argv()); },
                                     {"bad.yaml:line 3", "Icp.max_distance"}));
  test::WriteText(dir.File("broken.yaml"), "input_path: [a\n b: c\n");
  Fixture g;
  Args b({"lisfm icp", "--config_path", dir.File("broken.yaml")});
  EXPECT_THROW(g.options.Parse(b.argc(), b.argv()), InputError);
  Fixture h;
  Args c({"lisfm icp", "--config_path", dir.File("missing.yaml")});
  EXPECT_THROW(h.options.Parse(c.argc(), c.argv()), InputError);
}

TEST(Options, NearestName) {
  EXPECT_EQ(NearestName("evalute", {"evaluate", "simulate", "icp"}), "evaluate");
  EXPECT_EQ(NearestName("zzzzzzzz", {"evaluate", "icp"}), "");
}

}  // namespace
}  // namespace lisfm

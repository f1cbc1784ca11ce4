#include "core/options.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>

#include "core/errors.h"
#include "core/logging.h"
#include "core/option_check.h"
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
  // A map used as a key (valid YAML) names the file and the key's line.
  test::WriteText(dir.File("complex_key.yaml"), "input_path: a\nIcp:\n  ? {x: 1}\n  : 2\n");
  Fixture k;
  Args d({"lisfm icp", "--config_path", dir.File("complex_key.yaml")});
  EXPECT_TRUE(test::ThrowsInputError([&] { k.options.Parse(d.argc(), d.argv()); },
                                     {"complex_key.yaml:line 3", "found a map"}));
}

struct RangedFixture {
  double distance_m = 1.0;
  int iterations = 10;
  int threads = -1;
  int burn_in = 10;
  int num_samples = 100;
  uint64_t seed = 1;
  std::string mode = "a";
  enum class Color { kRed, kGreen } color = Color::kRed;
  OptionManager options{"lisfm test", "ranges and aliases"};
  RangedFixture() {
    options.AddDouble("Icp.max_distance_m", &distance_m, "m", OptionRange::GreaterThan(0));
    options.AddAlias("Icp.max_distance", "Icp.max_distance_m");
    options.AddInt("Icp.max_iterations", &iterations, "count", OptionRange::AtLeast(1));
    options.AddInt("num_threads", &threads, "threads", OptionRange::AtLeast(1).Or(-1));
    options.AddInt("burn_in", &burn_in, "samples", OptionRange::AtLeast(0));
    options.AddInt("num_samples", &num_samples, "samples", OptionRange::AtLeast(1));
    options.RequireLess("burn_in", "num_samples");
    options.AddUint64("seed", &seed, "seed");
    options.AddString("mode", &mode, "mode");
    options.AddCheck("mode", [this] { return mode == "a" || mode == "b" ? "" : "a or b"; });
    options.AddEnum("color", &color, {{"red", Color::kRed}, {"green", Color::kGreen}}, "colour");
  }
  // The message of the UsageError that Parse throws ("" when it succeeds).
  std::string ParseError(std::vector<std::string> args) {
    args.insert(args.begin(), "lisfm test");
    Args a(args);
    try {
      options.Parse(a.argc(), a.argv());
    } catch (const UsageError& e) {
      return e.what();
    }
    return "";
  }
};

TEST(OptionRange, TextContainsAndOutsideValues) {
  EXPECT_EQ(OptionRange().ToString(), "");
  EXPECT_EQ(OptionRange::AtLeast(1).ToString(), ">= 1");
  EXPECT_EQ(OptionRange::GreaterThan(0).ToString(), "> 0");
  EXPECT_EQ(OptionRange::GreaterThan(0).AndLessThan(2).ToString(), "in (0, 2)");
  EXPECT_EQ(OptionRange::Between(0, 1).ToString(), "in [0, 1]");
  EXPECT_EQ(OptionRange::AtLeast(1).Or(-1).ToString(), "-1 or >= 1");
  EXPECT_TRUE(OptionRange::AtLeast(1).Or(-1).Contains(-1));
  EXPECT_FALSE(OptionRange::AtLeast(1).Or(-1).Contains(0));
  EXPECT_FALSE(OptionRange::GreaterThan(0).Contains(0));
  EXPECT_TRUE(OptionRange::Between(0, 1).Contains(1));
  EXPECT_EQ(OptionRange::AtLeast(1).Or(-1).OutsideValues(true), std::vector<double>{0});
  EXPECT_EQ(OptionRange::Between(3, 64).OutsideValues(true), (std::vector<double>{2, 65}));
  const std::vector<double> open = OptionRange::GreaterThan(0).AndLessThan(2).OutsideValues(false);
  EXPECT_EQ(open, (std::vector<double>{0, 2}));
  const std::vector<double> closed = OptionRange::AtLeast(0.5).OutsideValues(false);
  ASSERT_EQ(closed.size(), 1u);
  EXPECT_LT(closed[0], 0.5);
  EXPECT_EQ(std::nextafter(closed[0], 1.0), 0.5);  // the nearest double below the bound
}

TEST(Options, OutOfRangeNamesOptionValueAndRange) {
  EXPECT_EQ(RangedFixture().ParseError({"--Icp.max_iterations", "0"}),
            "--Icp.max_iterations 0 is out of range: must be >= 1");
  EXPECT_EQ(RangedFixture().ParseError({"--Icp.max_distance_m", "-0.5"}),
            "--Icp.max_distance_m -0.5 is out of range: must be > 0");
  EXPECT_EQ(RangedFixture().ParseError({"--num_threads", "0"}),
            "--num_threads 0 is out of range: must be -1 or >= 1");
  EXPECT_EQ(RangedFixture().ParseError({"--num_threads", "-1"}), "");
  EXPECT_EQ(RangedFixture().ParseError({"--Icp.max_distance_m", "nan"}),
            "--Icp.max_distance_m nan is out of range: must be a finite number > 0");
  EXPECT_EQ(RangedFixture().ParseError({"--mode", "c"}),
            "--mode c is out of range: must be a or b");
  EXPECT_NE(RangedFixture().ParseError({"--seed", "-1"}), "");  // no wrap-around to 2^64 - 1
  EXPECT_EQ(RangedFixture().ParseError({"--seed", "7"}), "");
}

TEST(Options, RequireLessNamesTheOptionTheUserGave) {
  EXPECT_EQ(RangedFixture().ParseError({"--burn_in", "100"}),
            "--burn_in 100 is out of range: must be < --num_samples (100)");
  EXPECT_EQ(RangedFixture().ParseError({"--num_samples", "5"}),
            "--num_samples 5 is out of range: must be > --burn_in (10)");
  EXPECT_EQ(RangedFixture().ParseError({"--num_samples", "11"}), "");
}

TEST(Options, AliasSetsTheFieldAndGivingBothIsAUsageError) {
  RangedFixture old_name;
  EXPECT_EQ(old_name.ParseError({"--Icp.max_distance", "0.25"}), "");
  EXPECT_DOUBLE_EQ(old_name.distance_m, 0.25);
  EXPECT_TRUE(old_name.options.IsSet("Icp.max_distance_m"));
  RangedFixture new_name;
  EXPECT_EQ(new_name.ParseError({"--Icp.max_distance_m=0.5"}), "");
  EXPECT_DOUBLE_EQ(new_name.distance_m, 0.5);
  RangedFixture with_equals;
  EXPECT_EQ(with_equals.ParseError({"--Icp.max_distance=0.75"}), "");
  EXPECT_DOUBLE_EQ(with_equals.distance_m, 0.75);
  const std::string both =
      RangedFixture().ParseError({"--Icp.max_distance_m", "0.5", "--Icp.max_distance", "0.25"});
  EXPECT_NE(both.find("--Icp.max_distance_m and --Icp.max_distance are the same option"),
            std::string::npos)
      << both;
  // Out-of-range values name the option as the user spelled it.
  EXPECT_EQ(RangedFixture().ParseError({"--Icp.max_distance", "0"}),
            "--Icp.max_distance 0 is out of range: must be > 0");
  // Unknown names: an alias nearby suggests the current name.
  const std::string typo = RangedFixture().ParseError({"--Icp.max_distanse", "1"});
  EXPECT_NE(typo.find("did you mean '--Icp.max_distance_m'"), std::string::npos) << typo;
}

TEST(Options, AliasInConfigFileAndEffectiveConfigUsesTheName) {
  test::TempDir dir;
  test::WriteText(dir.File("c.yaml"), "Icp:\n  max_distance: 2.5\n");
  RangedFixture f;
  EXPECT_EQ(f.ParseError({"--config_path", dir.File("c.yaml")}), "");
  EXPECT_DOUBLE_EQ(f.distance_m, 2.5);
  f.options.WriteConfig(dir.File("effective.yaml"));
  std::ifstream in(dir.File("effective.yaml"));
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("Icp.max_distance_m: 2.5"), std::string::npos) << text;
  EXPECT_EQ(text.find("Icp.max_distance:"), std::string::npos) << text;

  test::WriteText(dir.File("both.yaml"), "Icp.max_distance: 2.5\nIcp.max_distance_m: 3\n");
  RangedFixture g;
  Args a({"lisfm test", "--config_path", dir.File("both.yaml")});
  EXPECT_THROW(g.options.Parse(a.argc(), a.argv()), InputError);
}

TEST(Options, OutOfRangeInConfigFileNamesFileAndLine) {
  test::TempDir dir;
  test::WriteText(dir.File("c.yaml"), "num_threads: -1\nIcp:\n  max_iterations: 0\n");
  RangedFixture f;
  Args a({"lisfm test", "--config_path", dir.File("c.yaml")});
  try {
    f.options.Parse(a.argc(), a.argv());
    FAIL() << "expected an InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(
                  "c.yaml:line 3: Icp.max_iterations 0 is out of range: must be >= 1"),
              std::string::npos)
        << e.what();
  }
}

TEST(Options, HelpShowsRangesAndAliases) {
  RangedFixture f;
  const std::string help = f.options.HelpText();
  EXPECT_NE(help.find("(=10, >= 1) count"), std::string::npos) << help;
  EXPECT_NE(help.find("(=1, > 0) m [alias: --Icp.max_distance]"), std::string::npos) << help;
  EXPECT_NE(help.find("(=-1, -1 or >= 1)"), std::string::npos) << help;
  EXPECT_NE(help.find("(=red) colour {red|green}"), std::string::npos) << help;
}

TEST(Options, EnumChoices) {
  RangedFixture f;
  EXPECT_EQ(f.ParseError({"--color", "green"}), "");
  EXPECT_EQ(f.color, RangedFixture::Color::kGreen);
  EXPECT_NE(RangedFixture().ParseError({"--color", "blue"}), "");
}

TEST(Options, ThrowUnlessValidNamesTheOptionBoundToTheFailingField) {
  RangedFixture f;
  ASSERT_EQ(f.ParseError({}), "");
  f.options.Set("Icp.max_distance", "-2");  // no range check in Set
  EXPECT_DOUBLE_EQ(f.distance_m, -2.0);
  EXPECT_NO_THROW(f.options.ThrowUnlessValid(true));
  const auto check = [&f]() -> bool {
    CHECK_OPTION_GT(f.distance_m, 0.0);
    return true;
  };
  try {
    f.options.ThrowUnlessValid(check());
    FAIL() << "expected a UsageError";
  } catch (const UsageError& e) {
    EXPECT_EQ(std::string(e.what()), "--Icp.max_distance -2 is out of range: must be > 0");
  }
  const std::vector<OptionInfo> infos = f.options.Options();
  const auto it = std::find_if(infos.begin(), infos.end(),
                               [](const OptionInfo& i) { return i.name == "Icp.max_distance_m"; });
  ASSERT_NE(it, infos.end());
  EXPECT_EQ(it->field, &f.distance_m);
  EXPECT_EQ(it->aliases, std::vector<std::string>{"Icp.max_distance"});
  EXPECT_TRUE(it->numeric);
  EXPECT_FALSE(it->integer);
}

struct CheckedOptions {
  int count = 3;
  double scale = 1.0;
  std::vector<double> bands = {1.0, 2.0};
  struct Inner {
    double sigma = 0.5;
    bool Check() const {
      CHECK_OPTION_GT(sigma, 0.0);
      return true;
    }
  } inner;
  bool Check() const {
    CHECK_OPTION_GE(count, 1);
    CHECK_OPTION_LT(scale, count);
    CHECK_OPTION_MSG(bands, !bands.empty(), "not empty");
    CHECK_OPTION_NESTED(inner);
    return true;
  }
};

TEST(OptionCheck, RecordsFieldValueAndRequirement) {
  CheckedOptions o;
  EXPECT_TRUE(o.Check());
  o.count = 0;
  EXPECT_FALSE(o.Check());
  EXPECT_EQ(LastOptionCheckFailure().ToString(), "count = 0 (must be >= 1)");
  EXPECT_EQ(LastOptionCheckFailure().field, &o.count);
  o.count = 2;
  o.scale = 2.5;
  EXPECT_FALSE(o.Check());
  EXPECT_EQ(LastOptionCheckFailure().ToString(), "scale = 2.5 (must be < count (2))");
  o.scale = std::numeric_limits<double>::infinity();
  EXPECT_FALSE(o.Check());  // not finite
  o.scale = 1.0;
  o.bands.clear();
  EXPECT_FALSE(o.Check());
  EXPECT_EQ(LastOptionCheckFailure().ToString(), "bands = [] (must be not empty)");
  o.bands = {1.0};
  o.inner.sigma = 0.0;
  EXPECT_FALSE(o.Check());
  EXPECT_EQ(LastOptionCheckFailure().ToString(), "inner.sigma = 0 (must be > 0)");
  EXPECT_EQ(LastOptionCheckFailure().field, &o.inner.sigma);
}

TEST(OptionCheck, ThrowCheckOptionsNamesTheField) {
  CheckedOptions o;
  o.count = -3;
  try {
    THROW_CHECK_OPTIONS(o);
    FAIL() << "expected an InternalError";
  } catch (const InternalError& e) {
    EXPECT_NE(std::string(e.what()).find("invalid o: count = -3 (must be >= 1)"),
              std::string::npos)
        << e.what();
  }
}

TEST(Options, StructCheckNamesTheOptionOfTheFailingField) {
  CheckedOptions o;
  OptionManager options("lisfm test", "struct check");
  options.AddInt("Test.count", &o.count, "count");
  options.AddDouble("Test.scale", &o.scale, "scale");
  options.AddStructCheck([&o] { return o.Check(); });
  Args good({"lisfm test", "--Test.scale", "2"});
  EXPECT_TRUE(options.Parse(good.argc(), good.argv()));
  OptionManager bad_options("lisfm test", "struct check");
  bad_options.AddInt("Test.count", &o.count, "count");
  bad_options.AddDouble("Test.scale", &o.scale, "scale");
  bad_options.AddStructCheck([&o] { return o.Check(); });
  Args bad({"lisfm test", "--Test.scale", "4"});
  try {
    bad_options.Parse(bad.argc(), bad.argv());
    FAIL() << "expected a UsageError";
  } catch (const UsageError& e) {
    EXPECT_EQ(std::string(e.what()), "--Test.scale 4 is out of range: must be < count (3)");
  }
}

TEST(Options, NearestName) {
  EXPECT_EQ(NearestName("evalute", {"evaluate", "simulate", "icp"}), "evaluate");
  EXPECT_EQ(NearestName("zzzzzzzz", {"evaluate", "icp"}), "");
}

}  // namespace
}  // namespace lisfm

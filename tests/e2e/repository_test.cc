// What a new user meets in a fresh checkout: the README and docs link only to
// files inside the repository, and the demo's default output folder is ignored
// by git (so `git status` stays clean after the README's first command).
#include <filesystem>
#include <regex>
#include <string>

#include <gtest/gtest.h>

#include "core/file_utils.h"
#include "tests/common/test_utils.h"

namespace lisfm {
namespace {

namespace fs = std::filesystem;

TEST(Repository, DocumentLinksStayInsideTheRepository) {
  const fs::path root = fs::canonical(test::SourceDir());
  std::vector<fs::path> documents = {root / "README.md"};
  for (const auto& entry : fs::directory_iterator(root / "docs")) {
    if (entry.path().extension() == ".md") documents.push_back(entry.path());
  }
  const std::regex link(R"(\]\(([^)\s]+)\))");
  size_t relative_links = 0;
  for (const fs::path& document : documents) {
    const std::string text = ReadFile(document.string());
    for (std::sregex_iterator it(text.begin(), text.end(), link), end; it != end; ++it) {
      std::string target = (*it)[1].str();
      if (target.rfind("http://", 0) == 0 || target.rfind("https://", 0) == 0 ||
          target[0] == '#') {
        continue;
      }
      target = target.substr(0, target.find('#'));
      ++relative_links;
      const fs::path resolved = (document.parent_path() / target).lexically_normal();
      const std::string relative = resolved.lexically_relative(root).string();
      EXPECT_TRUE(!relative.empty() && relative.rfind("..", 0) != 0)
          << document << " links outside the repository: " << target;
      EXPECT_TRUE(fs::exists(resolved)) << document << " links a missing file: " << target;
    }
  }
  EXPECT_GT(relative_links, 0u);  // README links docs/FORMATS.md
}

TEST(Repository, DemoOutputIsIgnoredByGit) {
  const std::string root = test::SourceDir();
  std::string out;
  if (test::RunCommand("git -C '" + root + "' rev-parse --is-inside-work-tree", &out) != 0) {
    GTEST_SKIP() << "not a git checkout: " << out;
  }
  // scripts/demo.sh's default output folder.
  EXPECT_NE(ReadFile(root + "/scripts/demo.sh").find("$LISFM_ROOT/demo_output"), std::string::npos);
  EXPECT_EQ(test::RunCommand("git -C '" + root + "' check-ignore -q demo_output/lio/trajectory.txt",
                             &out),
            0)
      << "demo_output/ is not ignored by git " << out;
}

}  // namespace
}  // namespace lisfm

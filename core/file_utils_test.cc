#include "core/file_utils.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "core/errors.h"
#include "tests/common/test_utils.h"

namespace lisfm {
namespace {

namespace fs = std::filesystem;

void Touch(const std::string& path, const std::string& text = "x") {
  std::ofstream(path) << text;
}

// Message of the exception `f` throws as E ("" when it throws nothing).
template <typename E, typename F>
std::string ErrorOf(F&& f) {
  try {
    f();
  } catch (const E& e) {
    return e.what();
  }
  return "";
}

TEST(OutputFolder, WritesToATemporaryFolderAndRenamesOnCommit) {
  test::TempDir dir;
  const std::string out = dir.File("out");
  {
    OutputFolder folder(out, /*overwrite=*/false);
    EXPECT_EQ(folder.final_path(), out);
    EXPECT_NE(folder.path(), out);
    EXPECT_TRUE(FileExists(folder.File(kOutputMarkerName)));
    EXPECT_FALSE(fs::exists(out));  // nothing under the final name before Commit()
    Touch(folder.File("result.txt"));
    folder.Commit();
  }
  EXPECT_TRUE(FileExists(JoinPaths(out, "result.txt")));
  EXPECT_TRUE(FileExists(JoinPaths(out, kOutputMarkerName)));
  EXPECT_EQ(std::distance(fs::directory_iterator(dir.path()), fs::directory_iterator()), 1);
}

TEST(OutputFolder, FailedRunLeavesNothing) {
  test::TempDir dir;
  const std::string out = dir.File("out");
  try {
    OutputFolder folder(out + "/", /*overwrite=*/false);  // a trailing '/' names the same folder
    Touch(folder.File("partial.txt"));
    throw InputError("a corrupt input in the middle of the run");
  } catch (const InputError&) {
  }
  EXPECT_TRUE(fs::is_empty(dir.path()));
}

TEST(OutputFolder, ExistingOutputNeedsOverwriteAndIsKeptUntilCommit) {
  test::TempDir dir;
  const std::string out = dir.File("out");
  {
    OutputFolder first(out, false);
    Touch(first.File("old.txt"));
    first.Commit();
  }
  EXPECT_NE(ErrorOf<UsageError>([&] { OutputFolder again(out, false); }).find("--overwrite 1"),
            std::string::npos);
  {
    OutputFolder failed(out, /*overwrite=*/true);  // never committed
  }
  EXPECT_TRUE(FileExists(JoinPaths(out, "old.txt")));
  {
    OutputFolder second(out, true);
    Touch(second.File("new.txt"));
    EXPECT_TRUE(FileExists(JoinPaths(out, "old.txt")));
    second.Commit();
  }
  EXPECT_FALSE(fs::exists(JoinPaths(out, "old.txt")));
  EXPECT_TRUE(FileExists(JoinPaths(out, "new.txt")));
}

TEST(OutputFolder, RefusesFoldersLisfmDidNotWriteAndFiles) {
  test::TempDir dir;
  const std::string mine = dir.File("mine");
  CreateDirs(mine);
  Touch(JoinPaths(mine, "thesis.tex"));
  const std::string message =
      ErrorOf<UsageError>([&] { OutputFolder folder(mine, /*overwrite=*/true, "--out"); });
  EXPECT_NE(message.find("--out " + mine), std::string::npos) << message;
  EXPECT_NE(message.find("lisfm did not write"), std::string::npos) << message;
  EXPECT_TRUE(FileExists(JoinPaths(mine, "thesis.tex")));

  const std::string file = dir.File("file.txt");
  Touch(file);
  EXPECT_NE(ErrorOf<UsageError>([&] { OutputFolder folder(file, true); }).find("is a file"),
            std::string::npos);
  EXPECT_TRUE(FileExists(file));
  EXPECT_NE(ErrorOf<UsageError>([&] { OutputFolder folder(".", true); }), "");
}

TEST(OutputFolder, AcceptsAnEmptyFolder) {
  test::TempDir dir;
  const std::string out = dir.File("empty");
  CreateDirs(out);
  OutputFolder folder(out, /*overwrite=*/false);
  Touch(folder.File("a.txt"));
  folder.Commit();
  EXPECT_TRUE(FileExists(JoinPaths(out, "a.txt")));
}

TEST(OutputFolder, UnwritableLocationFailsAtConstruction) {
  test::TempDir dir;
  const std::string file = dir.File("file.txt");
  Touch(file);
  const std::string out = file + "/sub/out";  // a parent is a file
  const std::string message = ErrorOf<InputError>([&] { OutputFolder folder(out, false); });
  EXPECT_NE(message.find(out), std::string::npos) << message;
  EXPECT_NE(message.find("cannot create"), std::string::npos) << message;
}

TEST(CheckOutputFileWritable, ChecksWithoutLeavingAFile) {
  test::TempDir dir;
  const std::string path = dir.File("sub/metrics.json");
  CheckOutputFileWritable(path, "--output_path");
  EXPECT_TRUE(DirExists(dir.File("sub")));
  EXPECT_TRUE(fs::is_empty(dir.File("sub")));
  EXPECT_NE(ErrorOf<UsageError>([&] { CheckOutputFileWritable(dir.path(), "--output_path"); }),
            "");
  Touch(dir.File("file"));
  EXPECT_NE(ErrorOf<InputError>(
                [&] { CheckOutputFileWritable(dir.File("file/x.json"), "--output_path"); }),
            "");
}

}  // namespace
}  // namespace lisfm

// File-system helpers: existence checks that throw InputError naming the path,
// atomic writes (temporary name + rename, so no half-written output is ever
// left looking complete), the output folders of commands (OutputFolder) and a
// line reader that tracks line numbers for error messages.
#pragma once

#include <fstream>
#include <string>
#include <vector>

namespace lisfm {

bool FileExists(const std::string& path);
bool DirExists(const std::string& path);
// Throws InputError("<path>: file not found") when `path` is not a readable file.
void CheckFileExists(const std::string& path, const std::string& what = "file");
void CheckDirExists(const std::string& path, const std::string& what = "folder");
// Creates `path` and its parents; throws InputError when that fails.
void CreateDirs(const std::string& path);
std::string JoinPaths(const std::string& a, const std::string& b);
std::string ReadFile(const std::string& path);

// Writes `contents` to `path` through `path.tmp-<pid>` and a rename.
void WriteFileAtomically(const std::string& path, const std::string& contents);

// An output file that only appears under its final name after Commit().
// Until then it is written to a temporary sibling, which the destructor
// removes if Commit() was never reached (e.g. an exception was thrown).
class AtomicOutputFile {
 public:
  explicit AtomicOutputFile(std::string path, bool binary = false);
  ~AtomicOutputFile();
  AtomicOutputFile(const AtomicOutputFile&) = delete;
  AtomicOutputFile& operator=(const AtomicOutputFile&) = delete;

  std::ofstream& stream() { return stream_; }
  const std::string& temp_path() const { return temp_path_; }
  // Flushes, checks the stream and renames to the final path. Throws on I/O error.
  void Commit();

 private:
  std::string path_;
  std::string temp_path_;
  std::ofstream stream_;
  bool committed_ = false;
};

// The file that marks a folder as written by lisfm (every OutputFolder holds
// one); `--overwrite 1` replaces only folders that carry it.
inline constexpr const char* kOutputMarkerName = ".lisfm_output";

// The output folder of one command run, written completely or not at all.
//
// The constructor runs before the work, so that an unusable output location
// fails at once instead of after hours of computation:
//  - `path` may not exist yet, or be an empty folder, or -- with `overwrite` --
//    a folder holding the marker file (an earlier lisfm output). A file, or a
//    non-empty folder without the marker, is refused (UsageError naming
//    `option` and the path); so is an existing output without `overwrite`.
//  - The temporary sibling `<path>.tmp-<pid>` is created (parents included)
//    with the marker inside; when that fails (no permission, a parent is a
//    file) it throws InputError naming the path.
// The command writes into path() (the temporary folder). Commit() replaces the
// earlier folder, if any, by a rename. Without Commit() (an exception, a
// failed run) the destructor removes the temporary folder: a failed run leaves
// neither a partial folder nor a changed earlier one. Not thread-safe.
class OutputFolder {
 public:
  OutputFolder(const std::string& path,
               bool overwrite,
               const std::string& option = "--output_path");
  ~OutputFolder();
  OutputFolder(const OutputFolder&) = delete;
  OutputFolder& operator=(const OutputFolder&) = delete;

  // The temporary folder to write into until Commit().
  const std::string& path() const { return temp_path_; }
  // `name` inside path().
  std::string File(const std::string& name) const;
  // The folder the outputs appear in after Commit().
  const std::string& final_path() const { return final_path_; }

  // Moves the temporary folder to final_path(), removing an earlier output
  // there. Throws InputError when that fails; the outputs then stay in path(),
  // which the message names.
  void Commit();

 private:
  std::string final_path_;
  bool overwrite_ = false;
  std::string temp_path_;
  bool committed_ = true;  // nothing to remove until the temporary folder exists
};

// For a command that writes one file (not a folder): before the work, checks
// that `path` is not a folder and that a file can be created beside it
// (parent folders are created). Throws UsageError / InputError naming `option`.
void CheckOutputFileWritable(const std::string& path, const std::string& option);

// Reads a text file line by line, keeping the 1-based line number for errors.
class LineReader {
 public:
  explicit LineReader(const std::string& path);
  // Next line without the trailing "\r\n"/"\n". Returns false at end of file.
  bool Next(std::string* line);
  int line_number() const { return line_number_; }
  const std::string& path() const { return path_; }
  // "line N" for InputError locations.
  std::string Where() const { return "line " + std::to_string(line_number_); }

 private:
  std::string path_;
  std::ifstream stream_;
  int line_number_ = 0;
};

// Splits on any of `delimiters`, skipping empty tokens when `skip_empty`.
std::vector<std::string> SplitString(const std::string& s,
                                     const std::string& delimiters,
                                     bool skip_empty = true);
std::string Trim(const std::string& s);
// Strict numeric parsing of a whole token; false on trailing garbage, NaN or overflow.
bool ParseDouble(const std::string& token, double* value);
bool ParseInt64(const std::string& token, int64_t* value);

}  // namespace lisfm

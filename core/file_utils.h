// File-system helpers: existence checks that throw InputError naming the path,
// atomic writes (temporary name + rename, so no half-written output is ever
// left looking complete) and a line reader that tracks line numbers for
// error messages.
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

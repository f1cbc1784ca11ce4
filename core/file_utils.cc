#include "core/file_utils.h"

#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <sstream>

#include "core/errors.h"

namespace lisfm {

namespace fs = std::filesystem;

bool FileExists(const std::string& path) {
  std::error_code ec;
  return fs::is_regular_file(path, ec);
}

bool DirExists(const std::string& path) {
  std::error_code ec;
  return fs::is_directory(path, ec);
}

void CheckFileExists(const std::string& path, const std::string& what) {
  if (path.empty()) throw InputError("no " + what + " path given");
  if (!FileExists(path)) {
    throw InputError(path, "", what + " not found" + (DirExists(path) ? " (it is a folder)" : ""));
  }
}

void CheckDirExists(const std::string& path, const std::string& what) {
  if (path.empty()) throw InputError("no " + what + " path given");
  if (!DirExists(path)) throw InputError(path, "", what + " not found");
}

void CreateDirs(const std::string& path) {
  std::error_code ec;
  fs::create_directories(path, ec);
  if (ec || !DirExists(path)) {
    throw InputError(path, "", "cannot create folder: " + ec.message());
  }
}

std::string JoinPaths(const std::string& a, const std::string& b) {
  return (fs::path(a) / fs::path(b)).string();
}

std::string ReadFile(const std::string& path) {
  CheckFileExists(path);
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path, "", "cannot open for reading");
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

void WriteFileAtomically(const std::string& path, const std::string& contents) {
  AtomicOutputFile out(path, true);
  out.stream() << contents;
  out.Commit();
}

AtomicOutputFile::AtomicOutputFile(std::string path, bool binary)
    : path_(std::move(path)),
      temp_path_(path_ + ".tmp-" + std::to_string(::getpid())) {
  stream_.open(temp_path_, binary ? std::ios::binary | std::ios::out : std::ios::out);
  if (!stream_) {
    throw InputError(path_, "", std::string("cannot open for writing: ") + std::strerror(errno));
  }
}

AtomicOutputFile::~AtomicOutputFile() {
  if (!committed_) {
    stream_.close();
    std::remove(temp_path_.c_str());
  }
}

void AtomicOutputFile::Commit() {
  stream_.flush();
  if (!stream_) throw InputError(path_, "", "write failed");
  stream_.close();
  std::error_code ec;
  fs::rename(temp_path_, path_, ec);
  if (ec) throw InputError(path_, "", "cannot rename temporary file: " + ec.message());
  committed_ = true;
}

namespace {

// `path` without trailing separators; refuses names that cannot be renamed
// into place ("", ".", "..", "/").
std::string OutputFolderPath(const std::string& path, const std::string& option) {
  std::string p = path;
  while (p.size() > 1 && p.back() == '/') p.pop_back();
  const std::string name = fs::path(p).filename().string();
  if (p.empty() || p == "/" || name.empty() || name == "." || name == "..") {
    throw UsageError(option + " '" + path + "': name the folder to create (not '.', '..' or '/')");
  }
  return p;
}

bool HasOutputMarker(const std::string& folder) {
  return FileExists(JoinPaths(folder, kOutputMarkerName));
}

bool IsEmptyFolder(const std::string& folder) {
  std::error_code ec;
  return fs::is_directory(folder, ec) && fs::is_empty(folder, ec) && !ec;
}

}  // namespace

OutputFolder::OutputFolder(const std::string& path, bool overwrite, const std::string& option)
    : final_path_(OutputFolderPath(path, option)), overwrite_(overwrite) {
  std::error_code ec;
  const fs::file_status status = fs::status(final_path_, ec);
  if (fs::exists(status)) {
    if (!fs::is_directory(status)) {
      throw UsageError(option + " " + final_path_ + " is a file; name a folder to create");
    }
    if (!IsEmptyFolder(final_path_)) {
      if (!HasOutputMarker(final_path_)) {
        throw UsageError(option + " " + final_path_ + " is a folder that lisfm did not write (no " +
                         kOutputMarkerName + " inside), so it is never replaced; choose a new " +
                         "folder or an empty one");
      }
      if (!overwrite_) {
        throw UsageError(option + " " + final_path_ +
                         " exists (an earlier lisfm output); choose a new folder or pass "
                         "--overwrite 1 to replace it");
      }
    }
  }
  temp_path_ = final_path_ + ".tmp-" + std::to_string(::getpid());
  fs::remove_all(temp_path_, ec);
  ec.clear();
  fs::create_directories(temp_path_, ec);
  if (ec || !DirExists(temp_path_)) {
    throw InputError(final_path_, "", "cannot create the output folder: " +
                                          (ec ? ec.message() : std::string("unknown error")));
  }
  try {
    WriteFileAtomically(File(kOutputMarkerName),
                        "This folder was written by lisfm; `--overwrite 1` may replace it.\n");
  } catch (...) {
    fs::remove_all(temp_path_, ec);
    throw;
  }
  committed_ = false;
}

OutputFolder::~OutputFolder() {
  if (committed_ || temp_path_.empty()) return;
  std::error_code ec;
  fs::remove_all(temp_path_, ec);
}

std::string OutputFolder::File(const std::string& name) const {
  return JoinPaths(temp_path_, name);
}

void OutputFolder::Commit() {
  THROW_CHECK(!committed_);
  const auto keep_and_fail = [&](const std::string& what) {
    committed_ = true;  // keep the finished outputs where they are
    throw InputError(final_path_, "", what + "; the finished outputs are in " + temp_path_);
  };
  std::error_code ec;
  if (fs::exists(final_path_, ec) && !IsEmptyFolder(final_path_)) {
    if (!fs::is_directory(final_path_, ec) || !HasOutputMarker(final_path_)) {
      keep_and_fail("appeared during the run and was not written by lisfm");
    }
    if (!overwrite_) keep_and_fail("an earlier lisfm output appeared during the run");
  }
  fs::remove_all(final_path_, ec);
  if (ec) keep_and_fail("cannot remove the earlier output: " + ec.message());
  fs::rename(temp_path_, final_path_, ec);
  if (ec) keep_and_fail("cannot move the output into place: " + ec.message());
  committed_ = true;
}

void CheckOutputFileWritable(const std::string& path, const std::string& option) {
  if (path.empty()) throw UsageError(option + " is empty");
  if (DirExists(path)) throw UsageError(option + " " + path + " is a folder; name a file");
  const std::string parent = fs::path(path).parent_path().string();
  if (!parent.empty()) CreateDirs(parent);
  AtomicOutputFile probe(path);  // opens a temporary sibling, removed unless committed
}

LineReader::LineReader(const std::string& path) : path_(path) {
  CheckFileExists(path);
  stream_.open(path);
  if (!stream_) throw InputError(path, "", "cannot open for reading");
}

bool LineReader::Next(std::string* line) {
  if (!std::getline(stream_, *line)) return false;
  ++line_number_;
  if (!line->empty() && line->back() == '\r') line->pop_back();
  return true;
}

std::vector<std::string> SplitString(const std::string& s,
                                     const std::string& delimiters,
                                     bool skip_empty) {
  std::vector<std::string> out;
  std::string cur;
  for (char c : s) {
    if (delimiters.find(c) != std::string::npos) {
      if (!skip_empty || !cur.empty()) out.push_back(cur);
      cur.clear();
    } else {
      cur.push_back(c);
    }
  }
  if (!skip_empty || !cur.empty()) out.push_back(cur);
  return out;
}

std::string Trim(const std::string& s) {
  const auto b = s.find_first_not_of(" \t\r\n");
  if (b == std::string::npos) return "";
  const auto e = s.find_last_not_of(" \t\r\n");
  return s.substr(b, e - b + 1);
}

bool ParseDouble(const std::string& token, double* value) {
  const std::string t = Trim(token);
  if (t.empty()) return false;
  char* end = nullptr;
  errno = 0;
  const double v = std::strtod(t.c_str(), &end);
  if (end != t.c_str() + t.size() || errno == ERANGE || !std::isfinite(v)) return false;
  *value = v;
  return true;
}

bool ParseInt64(const std::string& token, int64_t* value) {
  const std::string t = Trim(token);
  if (t.empty()) return false;
  char* end = nullptr;
  errno = 0;
  const long long v = std::strtoll(t.c_str(), &end, 10);
  if (end != t.c_str() + t.size() || errno == ERANGE) return false;
  *value = v;
  return true;
}

}  // namespace lisfm

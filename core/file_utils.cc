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

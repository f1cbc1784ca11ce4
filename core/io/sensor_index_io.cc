#include "core/io/sensor_index_io.h"

#include <fmt/format.h>

#include "core/errors.h"
#include "core/file_utils.h"

namespace lisfm {

std::vector<SensorFile> ReadSensorIndex(const std::string& path, const std::string& data_dir) {
  LineReader reader(path);
  std::vector<SensorFile> files;
  std::string line;
  while (reader.Next(&line)) {
    const std::string t = Trim(line);
    if (t.empty() || t[0] == '#') continue;
    const auto cols = SplitString(t, ",");
    if (cols.size() != 2) {
      throw InputError(path,
                       reader.Where(),
                       fmt::format("expected 2 columns (t_ns, filename), found {}", cols.size()));
    }
    SensorFile f;
    if (!ParseInt64(cols[0], &f.t_ns)) {
      throw InputError(path, reader.Where(), "bad time stamp '" + cols[0] + "' (integer ns)");
    }
    if (!files.empty() && f.t_ns <= files.back().t_ns) {
      throw InputError(
          path,
          reader.Where(),
          fmt::format("time stamps not increasing ({} after {})", f.t_ns, files.back().t_ns));
    }
    f.path = JoinPaths(data_dir, Trim(cols[1]));
    if (!FileExists(f.path)) throw InputError(path, reader.Where(), "missing file " + f.path);
    files.push_back(f);
  }
  return files;
}

}  // namespace lisfm

#include "importers/sequence.h"

#include <fmt/format.h>

#include "core/errors.h"
#include "core/file_utils.h"
#include "core/io/rig_io.h"

namespace lisfm {

std::vector<ImuSample> ReadImuCsv(const std::string& path) {
  LineReader reader(path);
  std::vector<ImuSample> samples;
  std::string line;
  while (reader.Next(&line)) {
    const std::string t = Trim(line);
    if (t.empty() || t[0] == '#') continue;
    const auto cols = SplitString(t, ", \t");
    if (cols.size() != 7) {
      throw InputError(path, reader.Where(),
                       fmt::format("expected 7 columns (t_ns, wx, wy, wz, ax, ay, az), found {}",
                                   cols.size()));
    }
    ImuSample s;
    if (!ParseInt64(cols[0], &s.t_ns)) {
      throw InputError(path, reader.Where(), "bad time stamp '" + cols[0] + "' (integer ns)");
    }
    double v[6];
    for (int i = 0; i < 6; ++i) {
      if (!ParseDouble(cols[i + 1], &v[i])) {
        throw InputError(path, reader.Where(), "bad number '" + cols[i + 1] + "'");
      }
    }
    s.gyro = Vec3(v[0], v[1], v[2]);
    s.accel = Vec3(v[3], v[4], v[5]);
    if (!samples.empty() && s.t_ns <= samples.back().t_ns) {
      throw InputError(path, reader.Where(),
                       fmt::format("time stamps not increasing ({} after {})", s.t_ns,
                                   samples.back().t_ns));
    }
    samples.push_back(s);
  }
  if (samples.empty()) throw InputError(path, "", "no IMU samples");
  return samples;
}

Sequence ReadSequence(const std::string& root) {
  CheckDirExists(root, "sequence folder");
  Sequence seq;
  seq.root = root;
  seq.rig = ReadRigYaml(JoinPaths(root, "rig.yaml"));
  seq.imu = ReadImuCsv(JoinPaths(root, "imu0/data.csv"));
  for (size_t k = 0; k < seq.rig.lidars.size(); ++k) {
    const std::string dir = JoinPaths(root, seq.rig.lidars[k].name);
    seq.lidar_scans.push_back(
        ReadSensorIndex(JoinPaths(dir, "data.csv"), JoinPaths(dir, "data")));
  }
  for (size_t k = 0; k < seq.rig.cameras.size(); ++k) {
    const std::string dir = JoinPaths(root, seq.rig.cameras[k].name);
    if (!DirExists(dir)) {
      seq.camera_frames.emplace_back();
      continue;
    }
    seq.camera_frames.push_back(
        ReadSensorIndex(JoinPaths(dir, "data.csv"), JoinPaths(dir, "data")));
  }
  const std::string gt = JoinPaths(root, "groundtruth.txt");
  if (FileExists(gt)) seq.groundtruth_path = gt;
  return seq;
}

}  // namespace lisfm

#include "importers/kitti.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <sstream>
#include <vector>

#include "core/errors.h"
#include "core/file_utils.h"
#include "core/geometry.h"
#include "core/io/cloud_io.h"
#include "core/io/rig_io.h"
#include "core/io/trajectory_io.h"
#include "core/point_cloud.h"
#include "core/rig.h"
#include "core/trajectory.h"

namespace lisfm {
namespace {

// 12 numbers of a 3x4 row-major matrix -> SE3 (rotation orthonormalised).
SE3 ParseMatrix34(const std::vector<std::string>& tokens,
                  const std::string& path,
                  const std::string& where) {
  if (tokens.size() != 12) {
    throw InputError(
        path, where, fmt::format("expected 12 numbers (3x4 matrix), found {}", tokens.size()));
  }
  Mat4 m = Mat4::Identity();
  for (int i = 0; i < 12; ++i) {
    double v = 0;
    if (!ParseDouble(tokens[i], &v)) {
      throw InputError(path, where, "bad number '" + tokens[i] + "'");
    }
    m(i / 4, i % 4) = v;
  }
  const Mat3 r = m.topLeftCorner<3, 3>();
  if ((r * r.transpose() - Mat3::Identity()).cwiseAbs().maxCoeff() > 1e-3 ||
      std::abs(r.determinant() - 1) > 1e-3) {
    throw InputError(path, where, "the 3x3 part is not a rotation");
  }
  const Eigen::JacobiSVD<Mat3> svd(r, Eigen::ComputeFullU | Eigen::ComputeFullV);
  return SE3(Mat3(svd.matrixU() * svd.matrixV().transpose()), Vec3(m.topRightCorner<3, 1>()));
}

SE3 ReadCalibTr(const std::string& path) {
  LineReader reader(path);
  std::string line;
  while (reader.Next(&line)) {
    std::vector<std::string> tokens = SplitString(line, " \t");
    if (tokens.empty() || tokens[0] != "Tr:") continue;
    tokens.erase(tokens.begin());
    return ParseMatrix34(tokens, path, reader.Where());
  }
  throw InputError(path, "Tr", "no 'Tr:' line (cam0_from_velo)");
}

}  // namespace

KittiImportSummary ImportKittiOdometry(const std::string& sequence_dir,
                                       const std::string& poses_path,
                                       TimestampNs time_origin_ns,
                                       const std::string& output_dir) {
  namespace fs = std::filesystem;
  const std::string velodyne = JoinPaths(sequence_dir, "velodyne");
  CheckDirExists(velodyne, "KITTI velodyne folder");
  std::vector<std::string> scans;
  for (const auto& e : fs::directory_iterator(velodyne)) {
    if (e.is_regular_file() && e.path().extension() == ".bin") scans.push_back(e.path().string());
  }
  std::sort(scans.begin(), scans.end());
  if (scans.empty()) throw InputError(velodyne, "", "no .bin scans");

  // times.txt
  const std::string times_path = JoinPaths(sequence_dir, "times.txt");
  CheckFileExists(times_path, "KITTI times.txt");
  std::vector<TimestampNs> stamps;
  {
    LineReader reader(times_path);
    std::string line;
    while (reader.Next(&line)) {
      if (Trim(line).empty()) continue;
      double t = 0;
      if (!ParseDouble(Trim(line), &t) || t < 0) {
        throw InputError(
            times_path, reader.Where(), "expected one time in s >= 0, found '" + line + "'");
      }
      const TimestampNs ns = time_origin_ns + std::llround(t * 1e9);
      if (!stamps.empty() && ns <= stamps.back()) {
        throw InputError(times_path, reader.Where(), "time not after the previous line's");
      }
      stamps.push_back(ns);
    }
  }
  if (stamps.size() != scans.size()) {
    throw InputError(
        times_path,
        "",
        fmt::format("{} times for {} scans in {}", stamps.size(), scans.size(), velodyne));
  }

  // calib.txt -> rig
  const std::string calib_path = JoinPaths(sequence_dir, "calib.txt");
  CheckFileExists(calib_path, "KITTI calib.txt");
  Rig rig;
  RigLidar lidar;
  lidar.name = "lidar0";
  lidar.type = LidarType::kSpinning;
  lidar.imu_from_lidar = ReadCalibTr(calib_path);
  lidar.rings = 64;  // Velodyne HDL-64E
  lidar.min_range = 2.5;
  lidar.max_range = 120.0;
  lidar.scan_rate = 10.0;
  rig.lidars.push_back(lidar);

  // poses
  std::string poses = poses_path;
  if (poses.empty() && FileExists(JoinPaths(sequence_dir, "poses.txt"))) {
    poses = JoinPaths(sequence_dir, "poses.txt");
  }
  std::vector<StampedPose> truth;
  if (!poses.empty()) {
    CheckFileExists(poses, "KITTI poses");
    LineReader reader(poses);
    std::string line;
    while (reader.Next(&line)) {
      const std::vector<std::string> tokens = SplitString(line, " \t");
      if (tokens.empty()) continue;
      if (truth.size() >= stamps.size()) {
        throw InputError(
            poses, reader.Where(), fmt::format("more poses than the {} scans", stamps.size()));
      }
      StampedPose p;
      p.t_ns = stamps[truth.size()];
      p.pose = ParseMatrix34(tokens, poses, reader.Where());
      truth.push_back(p);
    }
    if (truth.size() != stamps.size()) {
      throw InputError(
          poses, "", fmt::format("{} poses for {} scans", truth.size(), stamps.size()));
    }
  }

  KittiImportSummary summary;
  CreateDirs(JoinPaths(output_dir, "lidar0/data"));
  std::ostringstream index;
  index << "#timestamp [ns],filename\n";
  for (size_t i = 0; i < scans.size(); ++i) {
    std::ifstream in(scans[i], std::ios::binary);
    const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    if (!in.good() && !in.eof()) throw InputError(scans[i], "", "cannot read");
    if (bytes.size() % 16 != 0) {
      throw InputError(
          scans[i],
          "",
          fmt::format("{} bytes: not a multiple of 16 (float32 x y z reflectance)", bytes.size()));
    }
    PointCloud cloud;
    cloud.stamp_ns = stamps[i];
    const size_t n = bytes.size() / 16;
    cloud.points.reserve(n);
    for (size_t j = 0; j < n; ++j) {
      float v[4];
      std::memcpy(v, bytes.data() + 16 * j, 16);
      LidarPoint p;
      p.x = v[0];
      p.y = v[1];
      p.z = v[2];
      p.intensity = v[3];
      if (IsFinite(p)) cloud.points.push_back(p);
    }
    if (cloud.points.empty()) throw InputError(scans[i], "", "no finite point");
    WritePcd(
        JoinPaths(output_dir, "lidar0/data/" + std::to_string(stamps[i]) + ".pcd"), cloud, true);
    index << stamps[i] << "," << stamps[i] << ".pcd\n";
    summary.num_points += cloud.size();
    ++summary.num_scans;
  }
  WriteFileAtomically(JoinPaths(output_dir, "lidar0/data.csv"), index.str());
  WriteFileAtomically(JoinPaths(output_dir, "rig.yaml"),
                      RigToYaml(rig,
                                "KITTI odometry " + sequence_dir +
                                    ": body frame = camera 0; T_imu_lidar = calib.txt Tr"));
  if (!truth.empty()) {
    WriteTum(JoinPaths(output_dir, "groundtruth.txt"), Trajectory(truth));
    summary.num_poses = truth.size();
  }
  return summary;
}

}  // namespace lisfm

#include "core/io/image_codec.h"
#include "core/io/rgbd_io.h"

#include <fmt/format.h>
#include <yaml-cpp/yaml.h>

#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>
#include <opencv2/core.hpp>
#include <regex>
#include <sstream>
#include <utility>

#include "core/errors.h"
#include "core/file_utils.h"
#include "core/io/trajectory_io.h"
#include "core/option_check.h"

namespace lisfm {
namespace {

namespace fs = std::filesystem;

// |R^T R - I| (max entry) accepted for a rigid transform read from a file: KinectFusion's
// 7-Scenes poses are orthonormal to ~1e-7 and a rotation typed with 4 decimals is off by
// <= ~1.5e-4; a scale or shear that matters is far above. Accepted rotations are projected
// onto SO(3).
constexpr double kOrthonormalTolerance = 1e-3;
constexpr double kLastRowTolerance = 1e-6;

constexpr double kTumDepthUnitsPerM = 5000.0;    // TUM RGB-D file formats page
constexpr double kMmDepthUnitsPerM = 1000.0;     // 7-Scenes
constexpr double kSevenScenesRateHz = 30.0;      // Kinect v1
constexpr uint16_t kSevenScenesInvalid = 65535;  // 7-Scenes' other invalid depth value

// ---- small parsing helpers ----

// The folder containing `path` ("." for a relative name without one); a trailing
// separator does not count ("a/b/" -> "a").
std::string ParentDir(const std::string& path) {
  fs::path p = fs::path(path).lexically_normal();
  if (p.filename().empty()) p = p.parent_path();
  const std::string parent = p.parent_path().string();
  return parent.empty() ? "." : parent;
}

bool IsCommentOrBlank(const std::string& line) {
  const size_t first = line.find_first_not_of(" \t\r");
  return first == std::string::npos || line[first] == '#';
}

// The nearest rotation (SVD projection) of a near-orthonormal 3x3 block, or throws.
SE3 RigidFromMatrix(const Mat4& m, const std::string& path, const std::string& where) {
  if (!m.allFinite()) throw InputError(path, where, "the 4x4 matrix has a non-finite entry");
  const Mat3 r = m.topLeftCorner<3, 3>();
  const double orth = (r.transpose() * r - Mat3::Identity()).cwiseAbs().maxCoeff();
  if (orth > kOrthonormalTolerance || r.determinant() <= 0) {
    throw InputError(path,
                     where,
                     fmt::format("the rotation block is not a rotation: |R^T R - I| = {:.3g} "
                                 "(must be <= {:g}), det = {:.6g} (must be > 0)",
                                 orth,
                                 kOrthonormalTolerance,
                                 r.determinant()));
  }
  const Eigen::Vector4d last = m.row(3).transpose();
  if ((last - Eigen::Vector4d(0, 0, 0, 1)).cwiseAbs().maxCoeff() > kLastRowTolerance) {
    throw InputError(
        path,
        where,
        fmt::format(
            "last row must be 0 0 0 1, found {} {} {} {}", last(0), last(1), last(2), last(3)));
  }
  const Eigen::JacobiSVD<Mat3> svd(r, Eigen::ComputeFullU | Eigen::ComputeFullV);
  const Mat3 rotation = svd.matrixU() * svd.matrixV().transpose();
  return SE3(rotation, Vec3(m.topRightCorner<3, 1>()));
}

// Reads `rows` lines of `cols` whitespace-separated numbers (comments and blank lines
// skipped; nothing may follow).
Eigen::MatrixXd ReadMatrixText(const std::string& path, int rows, int cols) {
  CheckFileExists(path);
  LineReader reader(path);
  Eigen::MatrixXd m(rows, cols);
  int row = 0;
  std::string line;
  while (reader.Next(&line)) {
    if (IsCommentOrBlank(line)) continue;
    if (row == rows) {
      throw InputError(
          path, reader.Where(), fmt::format("expected {} rows of numbers, found more", rows));
    }
    const std::vector<std::string> tokens = SplitString(line, " \t\r,");
    if (static_cast<int>(tokens.size()) != cols) {
      throw InputError(
          path, reader.Where(), fmt::format("expected {} numbers, found {}", cols, tokens.size()));
    }
    for (int c = 0; c < cols; ++c) {
      double v = 0;
      if (!ParseDouble(tokens[c], &v)) {
        throw InputError(path,
                         reader.Where(),
                         fmt::format("column {}: expected a number, found '{}'", c + 1, tokens[c]));
      }
      m(row, c) = v;
    }
    ++row;
  }
  if (row != rows) {
    throw InputError(path,
                     fmt::format("line {}", reader.line_number()),
                     fmt::format("expected {} rows of numbers, found {}", rows, row));
  }
  return m;
}

void CheckIntrinsics(const RgbdIntrinsics& k, const std::string& path) {
  if (!(k.fx > 0 && k.fy > 0 && std::isfinite(k.fx) && std::isfinite(k.fy) && std::isfinite(k.cx) &&
        std::isfinite(k.cy))) {
    throw InputError(path,
                     "intrinsics",
                     fmt::format("focal lengths must be finite and > 0, found fx = {}, fy = {} "
                                 "(cx = {}, cy = {})",
                                 k.fx,
                                 k.fy,
                                 k.cx,
                                 k.cy));
  }
  if (k.width <= 0 || k.height <= 0) {
    throw InputError(
        path, "resolution", fmt::format("must be > 0, found {} x {}", k.width, k.height));
  }
}

// A lisfm camera.yaml: intrinsics, resolution, optional depth_scale and T_cam_imu.
struct CameraYaml {
  RgbdIntrinsics intrinsics;
  double depth_units_per_m = 0;  // 0 when absent
  std::optional<SE3> cam_from_imu;
};

std::string LineOf(const YAML::Node& node) {
  if (!node.IsDefined()) return "";
  const YAML::Mark mark = node.Mark();
  if (mark.is_null()) return "";
  return fmt::format(" (line {})", mark.line + 1);
}

std::vector<double> YamlNumbers(const YAML::Node& node,
                                size_t count,
                                const std::string& path,
                                const std::string& field) {
  if (!node.IsSequence() || node.size() != count) {
    throw InputError(path,
                     "field " + field,
                     fmt::format("expected a list of {} numbers{}", count, LineOf(node)));
  }
  std::vector<double> values(count);
  for (size_t i = 0; i < count; ++i) {
    if (!node[i].IsScalar() || !ParseDouble(Trim(node[i].Scalar()), &values[i])) {
      throw InputError(path,
                       "field " + field,
                       fmt::format("entry {}: expected a number{}", i + 1, LineOf(node[i])));
    }
  }
  return values;
}

CameraYaml ReadCameraYaml(const std::string& path) {
  CheckFileExists(path);
  YAML::Node root;
  try {
    root = YAML::Load(ReadFile(path));
  } catch (const YAML::ParserException& e) {
    throw InputError(path, fmt::format("line {}", e.mark.line + 1), e.msg);
  }
  if (!root.IsMap()) throw InputError(path, "line 1", "expected a YAML map");
  CameraYaml out;
  const YAML::Node k = root["intrinsics"];
  if (!k.IsDefined()) throw InputError(path, "field intrinsics", "missing ([fx, fy, cx, cy])");
  const std::vector<double> kv = YamlNumbers(k, 4, path, "intrinsics");
  out.intrinsics.fx = kv[0];
  out.intrinsics.fy = kv[1];
  out.intrinsics.cx = kv[2];
  out.intrinsics.cy = kv[3];
  const YAML::Node res = root["resolution"];
  if (!res.IsDefined()) throw InputError(path, "field resolution", "missing ([width, height])");
  const std::vector<double> rv = YamlNumbers(res, 2, path, "resolution");
  if (rv[0] != std::floor(rv[0]) || rv[1] != std::floor(rv[1]) || rv[0] > 1e5 || rv[1] > 1e5) {
    throw InputError(path,
                     "field resolution",
                     fmt::format("expected whole pixel counts, found [{}, {}]", rv[0], rv[1]));
  }
  out.intrinsics.width = static_cast<int>(rv[0]);
  out.intrinsics.height = static_cast<int>(rv[1]);
  CheckIntrinsics(out.intrinsics, path);
  const YAML::Node scale = root["depth_scale"];
  if (scale.IsDefined() && !scale.IsNull()) {
    double v = 0;
    if (!scale.IsScalar() || !ParseDouble(Trim(scale.Scalar()), &v)) {
      throw InputError(
          path,
          "field depth_scale",
          "expected a number (depth units per metre, 1000 for millimetres)" + LineOf(scale));
    }
    if (!(v > 0)) {
      throw InputError(
          path,
          "field depth_scale",
          fmt::format("must be > 0 (depth units per metre), found {}{}", v, LineOf(scale)));
    }
    out.depth_units_per_m = v;
  }
  const YAML::Node t = root["T_cam_imu"];
  if (t.IsDefined() && !t.IsNull()) {
    if (!t.IsSequence() || t.size() != 4) {
      throw InputError(path, "field T_cam_imu", "expected 4 rows of 4 numbers" + LineOf(t));
    }
    Mat4 m;
    for (int r = 0; r < 4; ++r) {
      const std::vector<double> row =
          YamlNumbers(t[r], 4, path, fmt::format("T_cam_imu row {}", r + 1));
      for (int c = 0; c < 4; ++c) m(r, c) = row[c];
    }
    out.cam_from_imu = RigidFromMatrix(m, path, "field T_cam_imu");
  }
  return out;
}

// The resolution of an image file, from its pixels (OpenCV decodes the whole file).
cv::Size ImageSize(const std::string& path) {
  std::string why;
  const cv::Mat image = ReadImageFile(path, ImageReadMode::kUnchanged, &why);
  if (image.empty()) throw InputError(path, "image", "cannot be read as an image: " + why);
  return image.size();
}

// Intrinsics from an override file: a camera.yaml (.yaml/.yml) or a 3x3 K text file whose
// resolution is that of `depth_for_size`.
RgbdIntrinsics ReadIntrinsicsFile(const std::string& path, const std::string& depth_for_size) {
  const std::string ext = fs::path(path).extension().string();
  if (ext == ".yaml" || ext == ".yml") return ReadCameraYaml(path).intrinsics;
  const Eigen::MatrixXd k = ReadMatrixText(path, 3, 3);
  if (k(1, 0) != 0 || k(2, 0) != 0 || k(2, 1) != 0 || k(2, 2) != 1) {
    throw InputError(
        path, "K", "expected an upper-triangular 3x3 camera matrix with last row 0 0 1");
  }
  RgbdIntrinsics out;
  out.fx = k(0, 0);
  out.fy = k(1, 1);
  out.cx = k(0, 2);
  out.cy = k(1, 2);
  const cv::Size size = ImageSize(depth_for_size);
  out.width = size.width;
  out.height = size.height;
  CheckIntrinsics(out, path);
  return out;
}

void CheckIncreasing(const std::vector<RgbdFrameInfo>& frames,
                     const std::string& path,
                     const std::vector<int>& lines) {
  for (size_t i = 1; i < frames.size(); ++i) {
    if (frames[i].t_ns <= frames[i - 1].t_ns) {
      throw InputError(path,
                       fmt::format("line {}", lines[i]),
                       fmt::format("time stamps must be strictly increasing, found {} after {}",
                                   FormatNsAsSeconds(frames[i].t_ns),
                                   FormatNsAsSeconds(frames[i - 1].t_ns)));
    }
  }
}

void RequireFrameFile(const std::string& file,
                      const std::string& list_path,
                      const std::string& where,
                      const std::string& what) {
  if (!FileExists(file)) {
    throw InputError(list_path, where, fmt::format("{} image {} not found", what, file));
  }
}

// Pose of every frame from a TUM trajectory, interpolated with `max_gap_ns`; composed on
// the right with `camera_from_tracked^-1` (identity when the file already holds cameras).
void AttachPoses(const Trajectory& trajectory,
                 const SE3& tracked_from_camera,
                 int64_t max_gap_ns,
                 std::vector<RgbdFrameInfo>* frames) {
  for (RgbdFrameInfo& f : *frames) {
    const std::optional<SE3> pose = trajectory.Interpolate(f.t_ns, max_gap_ns);
    if (pose) f.world_from_camera = *pose * tracked_from_camera;
  }
}

// ---- lisfm sequence ----

RgbdSequence ReadLisfm(const std::string& path, const RgbdReadOptions& options) {
  // Either the sequence folder or its rgbd0/ folder.
  std::string dir = JoinPaths(path, "rgbd0");
  std::string sequence_dir = path;
  if (!FileExists(JoinPaths(dir, "data.csv"))) {
    if (FileExists(JoinPaths(path, "data.csv"))) {
      dir = path;
      sequence_dir = ParentDir(path);
    } else {
      throw InputError(JoinPaths(dir, "data.csv"),
                       "file",
                       "not found (a lisfm RGB-D sequence has rgbd0/data.csv, written by "
                       "`lisfm simulate --rgbd 1`)");
    }
  }
  RgbdSequence seq;
  seq.layout = RgbdLayout::kLisfm;
  seq.path = path;
  const std::string csv = JoinPaths(dir, "data.csv");
  const std::string camera_path = JoinPaths(dir, "camera.yaml");
  const CameraYaml camera = ReadCameraYaml(camera_path);
  seq.intrinsics = camera.intrinsics;
  seq.intrinsics_source = camera_path;
  seq.depth_m_per_unit = camera.depth_units_per_m > 0 ? 1.0 / camera.depth_units_per_m : 0.0;
  if (options.depth_units_per_m > 0) seq.depth_m_per_unit = 1.0 / options.depth_units_per_m;
  if (seq.depth_m_per_unit <= 0) {
    throw InputError(camera_path,
                     "field depth_scale",
                     "missing (depth units per metre, 1000 for millimetres); unknown depth "
                     "scale");
  }

  LineReader reader(csv);
  std::vector<int> lines;
  std::string line;
  while (reader.Next(&line)) {
    if (IsCommentOrBlank(line)) continue;
    const std::vector<std::string> tokens = SplitString(line, ",", false);
    if (tokens.size() != 3) {
      throw InputError(
          csv,
          reader.Where(),
          fmt::format("expected 3 columns (timestamp [ns],rgb,depth), found {}", tokens.size()));
    }
    RgbdFrameInfo f;
    if (!ParseInt64(Trim(tokens[0]), &f.t_ns)) {
      throw InputError(
          csv, reader.Where(), "column 1: expected a timestamp in ns, found '" + tokens[0] + "'");
    }
    f.color_path = JoinPaths(dir, Trim(tokens[1]));
    f.depth_path = JoinPaths(dir, Trim(tokens[2]));
    RequireFrameFile(f.color_path, csv, reader.Where(), "colour");
    RequireFrameFile(f.depth_path, csv, reader.Where(), "depth");
    seq.frames.push_back(std::move(f));
    lines.push_back(reader.line_number());
  }
  if (seq.frames.empty()) throw InputError(csv, "file", "no frames");
  CheckIncreasing(seq.frames, csv, lines);
  if (!options.intrinsics_path.empty()) {
    seq.intrinsics = ReadIntrinsicsFile(options.intrinsics_path, seq.frames[0].depth_path);
    seq.intrinsics_source = options.intrinsics_path;
  }

  const std::string gt_path = JoinPaths(sequence_dir, "groundtruth.txt");
  if (FileExists(gt_path)) {
    if (!camera.cam_from_imu) {
      throw InputError(
          camera_path, "field T_cam_imu", "missing: needed to give camera poses from " + gt_path);
    }
    AttachPoses(ReadTum(gt_path),
                camera.cam_from_imu->Inverse(),
                SecondsToNs(options.pose_max_gap_s),
                &seq.frames);
    seq.pose_source = gt_path + " * " + camera_path + " T_cam_imu^-1";
  }
  return seq;
}

// ---- TUM RGB-D ----

struct StampedFile {
  TimestampNs t_ns = 0;
  std::string path;
  int line = 0;
};

std::vector<StampedFile> ReadTumList(const std::string& dir, const std::string& name) {
  const std::string list = JoinPaths(dir, name);
  CheckFileExists(list);
  LineReader reader(list);
  std::vector<StampedFile> out;
  std::string line;
  while (reader.Next(&line)) {
    if (IsCommentOrBlank(line)) continue;
    const std::vector<std::string> tokens = SplitString(line, " \t\r");
    if (tokens.size() != 2) {
      throw InputError(
          list,
          reader.Where(),
          fmt::format("expected 2 columns (timestamp filename), found {}", tokens.size()));
    }
    StampedFile f;
    if (!ParseSecondsToNs(tokens[0], &f.t_ns)) {
      throw InputError(list,
                       reader.Where(),
                       "column 1: expected a time stamp in seconds, found '" + tokens[0] + "'");
    }
    f.path = JoinPaths(dir, tokens[1]);
    f.line = reader.line_number();
    RequireFrameFile(f.path, list, reader.Where(), name == "rgb.txt" ? "colour" : "depth");
    if (!out.empty() && f.t_ns <= out.back().t_ns) {
      throw InputError(list,
                       reader.Where(),
                       fmt::format("time stamps must be strictly increasing, found {} after {}",
                                   tokens[0],
                                   FormatNsAsSeconds(out.back().t_ns)));
    }
    out.push_back(std::move(f));
  }
  if (out.empty()) throw InputError(list, "file", "no images listed");
  return out;
}

RgbdSequence ReadTumRgbd(const std::string& path, const RgbdReadOptions& options) {
  RgbdSequence seq;
  seq.layout = RgbdLayout::kTum;
  seq.path = path;
  const std::vector<StampedFile> rgb = ReadTumList(path, "rgb.txt");
  const std::vector<StampedFile> depth = ReadTumList(path, "depth.txt");

  // Greedy association on |dt| with unique pairs (the benchmark's associate.py).
  const int64_t max_dt_ns = SecondsToNs(options.association_max_dt_s);
  std::vector<std::pair<int64_t, std::pair<size_t, size_t>>> candidates;
  size_t lo = 0;
  for (size_t i = 0; i < rgb.size(); ++i) {
    while (lo < depth.size() && depth[lo].t_ns < rgb[i].t_ns - max_dt_ns) ++lo;
    for (size_t j = lo; j < depth.size() && depth[j].t_ns <= rgb[i].t_ns + max_dt_ns; ++j) {
      candidates.push_back({std::llabs(depth[j].t_ns - rgb[i].t_ns), {i, j}});
    }
  }
  std::sort(candidates.begin(), candidates.end());
  std::vector<bool> rgb_used(rgb.size(), false), depth_used(depth.size(), false);
  std::vector<std::pair<size_t, size_t>> pairs;
  for (const auto& c : candidates) {
    const auto [i, j] = c.second;
    if (rgb_used[i] || depth_used[j]) continue;
    rgb_used[i] = depth_used[j] = true;
    pairs.push_back({i, j});
  }
  if (pairs.empty()) {
    throw InputError(JoinPaths(path, "depth.txt"),
                     "file",
                     fmt::format("no depth image within {} s of a colour image of rgb.txt",
                                 options.association_max_dt_s));
  }
  std::sort(pairs.begin(), pairs.end());
  for (const auto& [i, j] : pairs) {
    RgbdFrameInfo f;
    f.t_ns = rgb[i].t_ns;
    f.color_path = rgb[i].path;
    f.depth_path = depth[j].path;
    seq.frames.push_back(std::move(f));
  }

  const std::string camera_path = JoinPaths(path, "camera.yaml");
  double units_per_m = kTumDepthUnitsPerM;
  if (!options.intrinsics_path.empty()) {
    seq.intrinsics = ReadIntrinsicsFile(options.intrinsics_path, seq.frames[0].depth_path);
    seq.intrinsics_source = options.intrinsics_path;
  } else if (FileExists(camera_path)) {
    const CameraYaml camera = ReadCameraYaml(camera_path);
    seq.intrinsics = camera.intrinsics;
    seq.intrinsics_source = camera_path;
    if (camera.depth_units_per_m > 0) units_per_m = camera.depth_units_per_m;
  } else {
    seq.intrinsics = {525.0, 525.0, 319.5, 239.5, 640, 480};
    seq.intrinsics_source = "TUM ROS default";
  }
  if (options.depth_units_per_m > 0) units_per_m = options.depth_units_per_m;
  seq.depth_m_per_unit = 1.0 / units_per_m;

  const std::string gt_path = JoinPaths(path, "groundtruth.txt");
  if (FileExists(gt_path)) {
    AttachPoses(
        ReadTum(gt_path), SE3::Identity(), SecondsToNs(options.pose_max_gap_s), &seq.frames);
    seq.pose_source = gt_path;
  }
  return seq;
}

// ---- 7-Scenes ----

bool HasSevenScenesFrames(const std::string& dir) {
  if (!DirExists(dir)) return false;
  static const std::regex kDepth(R"(frame-(\d+)\.depth\.png)");
  for (const fs::directory_entry& e : fs::directory_iterator(dir)) {
    if (std::regex_match(e.path().filename().string(), kDepth)) return true;
  }
  return false;
}

RgbdSequence ReadSevenScenes(const std::string& path, const RgbdReadOptions& options) {
  std::string frames_dir = path;
  if (!HasSevenScenesFrames(frames_dir)) frames_dir = JoinPaths(path, "frames");
  if (!HasSevenScenesFrames(frames_dir)) {
    throw InputError(
        path, "folder", "no frame-XXXXXX.depth.png here or in frames/ (7-Scenes layout)");
  }
  RgbdSequence seq;
  seq.layout = RgbdLayout::kSevenScenes;
  seq.path = path;
  static const std::regex kDepth(R"(frame-(\d+)\.depth\.png)");
  std::map<int64_t, std::string> depth_by_index;
  for (const fs::directory_entry& e : fs::directory_iterator(frames_dir)) {
    std::smatch m;
    const std::string name = e.path().filename().string();
    if (!std::regex_match(name, m, kDepth)) continue;
    int64_t index = 0;
    if (!ParseInt64(m[1].str(), &index) || index > 1000000000) {
      throw InputError(JoinPaths(frames_dir, name), "file name", "frame number out of range");
    }
    if (!depth_by_index.emplace(index, name).second) {
      throw InputError(
          JoinPaths(frames_dir, name),
          "file name",
          fmt::format("frame number {} appears twice ({})", index, depth_by_index[index]));
    }
  }
  for (const auto& [index, depth_name] : depth_by_index) {
    const std::string stem =
        depth_name.substr(0, depth_name.size() - std::string(".depth.png").size());
    RgbdFrameInfo f;
    f.t_ns = SecondsToNs(static_cast<double>(index) / kSevenScenesRateHz);
    f.depth_path = JoinPaths(frames_dir, depth_name);
    f.color_path = JoinPaths(frames_dir, stem + ".color.png");
    if (!FileExists(f.color_path)) f.color_path = JoinPaths(frames_dir, stem + ".color.jpg");
    if (!FileExists(f.color_path)) {
      throw InputError(f.depth_path,
                       "frame",
                       fmt::format("colour image {} (or .color.png) not found", f.color_path));
    }
    const std::string pose_path = JoinPaths(frames_dir, stem + ".pose.txt");
    if (FileExists(pose_path)) {
      const Eigen::MatrixXd m = ReadMatrixText(pose_path, 4, 4);
      f.world_from_camera = RigidFromMatrix(Mat4(m), pose_path, "pose");
    }
    seq.frames.push_back(std::move(f));
  }
  if (std::any_of(seq.frames.begin(), seq.frames.end(), [](const RgbdFrameInfo& f) {
        return f.world_from_camera.has_value();
      })) {
    seq.pose_source = JoinPaths(frames_dir, "frame-XXXXXX.pose.txt");
  }

  if (!options.intrinsics_path.empty()) {
    seq.intrinsics = ReadIntrinsicsFile(options.intrinsics_path, seq.frames[0].depth_path);
    seq.intrinsics_source = options.intrinsics_path;
  } else {
    std::vector<std::string> candidates = {JoinPaths(path, "camera-intrinsics.txt"),
                                           JoinPaths(frames_dir, "camera-intrinsics.txt")};
    candidates.push_back(JoinPaths(ParentDir(frames_dir), "camera-intrinsics.txt"));
    for (const std::string& c : candidates) {
      if (FileExists(c)) {
        seq.intrinsics = ReadIntrinsicsFile(c, seq.frames[0].depth_path);
        seq.intrinsics_source = c;
        break;
      }
    }
    if (seq.intrinsics_source.empty()) {
      throw InputError(JoinPaths(path, "camera-intrinsics.txt"),
                       "file",
                       "not found (7-Scenes depth intrinsics, a 3x3 K; also looked in " +
                           frames_dir + " and its parent)");
    }
  }
  seq.depth_m_per_unit =
      1.0 / (options.depth_units_per_m > 0 ? options.depth_units_per_m : kMmDepthUnitsPerM);
  return seq;
}

RgbdLayout DetectLayout(const std::string& path) {
  if (FileExists(JoinPaths(path, "rgbd0/data.csv")) ||
      (FileExists(JoinPaths(path, "data.csv")) && FileExists(JoinPaths(path, "camera.yaml")))) {
    return RgbdLayout::kLisfm;
  }
  if (FileExists(JoinPaths(path, "rgb.txt")) && FileExists(JoinPaths(path, "depth.txt"))) {
    return RgbdLayout::kTum;
  }
  if (HasSevenScenesFrames(path) || HasSevenScenesFrames(JoinPaths(path, "frames"))) {
    return RgbdLayout::kSevenScenes;
  }
  throw InputError(path,
                   "folder",
                   "no RGB-D layout found: expected rgbd0/data.csv (lisfm sequence), rgb.txt + "
                   "depth.txt (TUM RGB-D) or frame-XXXXXX.depth.png (7-Scenes)");
}

}  // namespace

std::string RgbdLayoutName(RgbdLayout layout) {
  switch (layout) {
    case RgbdLayout::kAuto:
      return "auto";
    case RgbdLayout::kLisfm:
      return "lisfm";
    case RgbdLayout::kTum:
      return "tum";
    case RgbdLayout::kSevenScenes:
      return "7scenes";
  }
  return "?";
}

RgbdLayout ParseRgbdLayout(const std::string& name) {
  for (RgbdLayout l :
       {RgbdLayout::kAuto, RgbdLayout::kLisfm, RgbdLayout::kTum, RgbdLayout::kSevenScenes}) {
    if (name == RgbdLayoutName(l)) return l;
  }
  throw UsageError("unknown RGB-D layout '" + name + "': must be auto, lisfm, tum or 7scenes");
}

RgbdIntrinsics DownsampleIntrinsics(const RgbdIntrinsics& intrinsics, int factor) {
  THROW_CHECK_GE(factor, 1);
  RgbdIntrinsics out = intrinsics;
  out.fx /= factor;
  out.fy /= factor;
  out.cx /= factor;
  out.cy /= factor;
  out.width = (intrinsics.width + factor - 1) / factor;
  out.height = (intrinsics.height + factor - 1) / factor;
  return out;
}

size_t RgbdSequence::NumGivenPoses() const {
  return static_cast<size_t>(
      std::count_if(frames.begin(), frames.end(), [](const RgbdFrameInfo& f) {
        return f.world_from_camera.has_value();
      }));
}

Trajectory RgbdSequence::GivenTrajectory() const {
  std::vector<StampedPose> poses;
  for (const RgbdFrameInfo& f : frames) {
    if (f.world_from_camera) poses.push_back({f.t_ns, *f.world_from_camera});
  }
  return Trajectory(std::move(poses));
}

bool RgbdReadOptions::Check() const {
  CHECK_OPTION_GE(depth_units_per_m, 0.0);
  CHECK_OPTION_GT(association_max_dt_s, 0.0);
  CHECK_OPTION_LE(association_max_dt_s, 10.0);
  CHECK_OPTION_GT(pose_max_gap_s, 0.0);
  CHECK_OPTION_LE(pose_max_gap_s, 1000.0);
  return true;
}

RgbdSequence ReadRgbdSequence(const std::string& path, const RgbdReadOptions& options) {
  THROW_CHECK_MSG(options.Check(), LastOptionCheckFailure().ToString());
  CheckDirExists(path, "RGB-D folder");
  const RgbdLayout layout =
      options.layout == RgbdLayout::kAuto ? DetectLayout(path) : options.layout;
  switch (layout) {
    case RgbdLayout::kLisfm:
      return ReadLisfm(path, options);
    case RgbdLayout::kTum:
      return ReadTumRgbd(path, options);
    case RgbdLayout::kSevenScenes:
      return ReadSevenScenes(path, options);
    case RgbdLayout::kAuto:
      break;
  }
  throw InternalError("unreachable RGB-D layout");
}

RgbdImage LoadRgbdFrame(const RgbdSequence& sequence, size_t index, int factor) {
  THROW_CHECK_LT(index, sequence.frames.size());
  THROW_CHECK_GE(factor, 1);
  THROW_CHECK_GT(sequence.depth_m_per_unit, 0.0);
  const RgbdFrameInfo& f = sequence.frames[index];
  for (const std::string* path : {&f.depth_path, &f.color_path}) {
    if (!FileExists(*path)) throw InputError(*path, "image", "not found");
  }
  std::string why;
  const cv::Mat depth = ReadImageFile(f.depth_path, ImageReadMode::kUnchanged, &why);
  if (depth.empty()) {
    throw InputError(f.depth_path, "image", "cannot be read as an image: " + why);
  }
  if (depth.type() != CV_16UC1) {
    throw InputError(f.depth_path,
                     "image",
                     fmt::format("expected a 16-bit single-channel depth image, found {} "
                                 "channel(s) of {} bits",
                                 depth.channels(),
                                 8 * static_cast<int>(depth.elemSize1())));
  }
  const cv::Mat color = ReadImageFile(f.color_path, ImageReadMode::kColor, &why);
  if (color.empty()) {
    throw InputError(f.color_path, "image", "cannot be read as an image: " + why);
  }
  if (color.size() != depth.size()) {
    throw InputError(f.color_path,
                     "image",
                     fmt::format("colour is {} x {} but depth {} is {} x {}",
                                 color.cols,
                                 color.rows,
                                 f.depth_path,
                                 depth.cols,
                                 depth.rows));
  }
  const RgbdIntrinsics& k = sequence.intrinsics;
  if (depth.cols != k.width || depth.rows != k.height) {
    throw InputError(f.depth_path,
                     "image",
                     fmt::format("is {} x {} but the intrinsics ({}) are for {} x {}",
                                 depth.cols,
                                 depth.rows,
                                 sequence.intrinsics_source,
                                 k.width,
                                 k.height));
  }
  const bool seven_scenes = sequence.layout == RgbdLayout::kSevenScenes;
  const float scale = static_cast<float>(sequence.depth_m_per_unit);
  RgbdImage out;
  out.width = (depth.cols + factor - 1) / factor;
  out.height = (depth.rows + factor - 1) / factor;
  out.depth_m.resize(static_cast<size_t>(out.width) * out.height);
  out.rgb.resize(out.depth_m.size() * 3);
  for (int y = 0; y < out.height; ++y) {
    const uint16_t* d = depth.ptr<uint16_t>(y * factor);
    const cv::Vec3b* c = color.ptr<cv::Vec3b>(y * factor);
    for (int x = 0; x < out.width; ++x) {
      const size_t i = static_cast<size_t>(y) * out.width + x;
      const uint16_t raw = d[x * factor];
      out.depth_m[i] = (raw == 0 || (seven_scenes && raw == kSevenScenesInvalid))
                           ? 0.f
                           : static_cast<float>(raw) * scale;
      const cv::Vec3b& bgr = c[x * factor];
      out.rgb[3 * i + 0] = bgr[2];
      out.rgb[3 * i + 1] = bgr[1];
      out.rgb[3 * i + 2] = bgr[0];
    }
  }
  return out;
}

}  // namespace lisfm

#include "colmap_ext/sfm/sfm_evaluation.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>
#include <unordered_map>

#include "colmap_ext/io/model_io.h"
#include "colmap_ext/sfm/sequence_reference.h"
#include "core/errors.h"
#include "core/file_utils.h"
#include "core/logging.h"
#include "core/option_check.h"

namespace lisfm {
namespace colmap {
namespace {

namespace fs = std::filesystem;

constexpr double kRadToDeg = 180.0 / M_PI;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();

std::string Basename(const std::string& name) {
  const size_t slash = name.find_last_of('/');
  return slash == std::string::npos ? name : name.substr(slash + 1);
}

bool EndsWith(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() &&
         s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

std::string Lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

// Angle (rad) between two vectors, stable near 0 and pi; NaN for a zero vector.
double VectorAngle(const Vec3& a, const Vec3& b) {
  if (a.norm() == 0.0 || b.norm() == 0.0) return kNaN;
  return std::atan2(a.cross(b).norm(), a.dot(b));
}

// "X-2" < "X-10": runs of digits compare as numbers.
bool NaturalLess(const std::string& a, const std::string& b) {
  size_t i = 0, j = 0;
  while (i < a.size() && j < b.size()) {
    const bool da = std::isdigit(static_cast<unsigned char>(a[i])) != 0;
    const bool db = std::isdigit(static_cast<unsigned char>(b[j])) != 0;
    if (da && db) {
      size_t ie = i, je = j;
      while (ie < a.size() && std::isdigit(static_cast<unsigned char>(a[ie]))) ++ie;
      while (je < b.size() && std::isdigit(static_cast<unsigned char>(b[je]))) ++je;
      std::string na = a.substr(i, ie - i), nb = b.substr(j, je - j);
      na.erase(0, std::min(na.find_first_not_of('0'), na.size()));
      nb.erase(0, std::min(nb.find_first_not_of('0'), nb.size()));
      if (na.size() != nb.size()) return na.size() < nb.size();
      if (na != nb) return na < nb;
      i = ie;
      j = je;
    } else {
      if (a[i] != b[j]) return a[i] < b[j];
      ++i;
      ++j;
    }
  }
  return a.size() - i < b.size() - j;
}

// Whitespace-separated tokens of a text file with the line of each token.
struct Tokens {
  std::vector<std::string> values;
  std::vector<int> lines;
};

Tokens Tokenize(const std::string& path, bool skip_hash_comments) {
  LineReader reader(path);
  Tokens tokens;
  std::string line;
  while (reader.Next(&line)) {
    if (skip_hash_comments) {
      const size_t hash = line.find('#');
      if (hash != std::string::npos) line.resize(hash);
    }
    for (const std::string& t : SplitString(line, " \t\r")) {
      tokens.values.push_back(t);
      tokens.lines.push_back(reader.line_number());
    }
  }
  return tokens;
}

// Sequential reader over Tokens that throws InputError naming the line.
class TokenCursor {
 public:
  TokenCursor(std::string path, Tokens tokens)
      : path_(std::move(path)), tokens_(std::move(tokens)) {}
  bool AtEnd() const { return index_ >= tokens_.values.size(); }
  double Double(const std::string& what) {
    const std::string& t = Next(what);
    double v = 0;
    if (!ParseDouble(t, &v)) Fail(what, "'" + t + "'", index_ - 1);
    return v;
  }
  int64_t Int(const std::string& what) {
    const std::string& t = Next(what);
    int64_t v = 0;
    if (!ParseInt64(t, &v)) Fail(what, "'" + t + "'", index_ - 1);
    return v;
  }
  [[noreturn]] void Fail(const std::string& expected, const std::string& found, size_t index) const {
    const std::string where =
        index < tokens_.lines.size() ? "line " + std::to_string(tokens_.lines[index])
                                     : "end of file";
    throw InputError(path_, where, "expected " + expected + ", found " + found);
  }
  size_t index() const { return index_; }

 private:
  const std::string& Next(const std::string& what) {
    if (AtEnd()) Fail(what, "end of file", index_);
    return tokens_.values[index_++];
  }
  std::string path_;
  Tokens tokens_;
  size_t index_ = 0;
};

bool IsRotation(const Mat3& r) {
  // 1e-4: Strecha and Bundler files store rotations with 6-10 significant digits.
  return (r.transpose() * r - Mat3::Identity()).norm() < 1e-4 && r.determinant() > 0;
}

// Nearest rotation (SVD) so that printed values become an exact rotation.
Mat3 Orthonormalize(const Mat3& r) {
  Eigen::JacobiSVD<Mat3> svd(r, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Mat3 u = svd.matrixU();
  const Mat3 v = svd.matrixV();
  if ((u * v.transpose()).determinant() < 0) u.col(2) *= -1;
  return u * v.transpose();
}


// Geodesic L1 mean of rotations (Weiszfeld iterations on SO(3), Hartley et
// al., "L1 rotation averaging using the Weiszfeld algorithm", CVPR 2011),
// started at the chordal L2 mean. A majority of identical rotations is
// returned exactly (to ~1e-15 rad), which an L2 mean would pull off.
Quat GeodesicMedian(const std::vector<Quat>& rotations) {
  Quat q = so3::Average(rotations);
  for (int iteration = 0; iteration < 200; ++iteration) {
    Vec3 numerator = Vec3::Zero();
    double denominator = 0.0;
    for (const Quat& r : rotations) {
      const Vec3 v = so3::Log(q.conjugate() * r);
      const double w = 1.0 / std::max(v.norm(), 1e-15);
      numerator += w * v;
      denominator += w;
    }
    const Vec3 step = numerator / denominator;
    q = (q * so3::Exp(step)).normalized();
    if (step.norm() < 1e-15) break;
  }
  return q;
}

// Name lookup: full name first; the basename otherwise (it must be unique),
// unless both the name and every indexed name carry a folder: then the folder
// is part of the identity (camK/data/<ns>.png of a multi-camera rig share
// basenames across cameras) and an absent full name is absent.
class NameIndex {
 public:
  explicit NameIndex(const std::vector<NamedPose>& poses) {
    for (size_t i = 0; i < poses.size(); ++i) {
      full_[poses[i].name] = i;
      if (!HasFolder(poses[i].name)) all_have_folders_ = false;
      const std::string base = Basename(poses[i].name);
      auto it = base_.find(base);
      if (it == base_.end()) {
        base_[base] = i;
      } else {
        it->second = kAmbiguous;
      }
    }
  }
  // Index or -1 when absent; throws InputError for an ambiguous basename.
  long Find(const std::string& name) const {
    const auto full = full_.find(name);
    if (full != full_.end()) return static_cast<long>(full->second);
    if (all_have_folders_ && HasFolder(name)) return -1;
    const auto base = base_.find(Basename(name));
    if (base == base_.end()) return -1;
    if (base->second == kAmbiguous) {
      throw InputError("image name '" + name + "' matches several images by its basename '" +
                       Basename(name) + "'; use full names");
    }
    return static_cast<long>(base->second);
  }

 private:
  static bool HasFolder(const std::string& name) { return name.find('/') != std::string::npos; }

  static constexpr size_t kAmbiguous = std::numeric_limits<size_t>::max();
  bool all_have_folders_ = true;
  std::unordered_map<std::string, size_t> full_;
  std::unordered_map<std::string, size_t> base_;
};

}  // namespace

std::string ReferenceFormatName(ReferenceFormat format) {
  switch (format) {
    case ReferenceFormat::kAuto:
      return "auto";
    case ReferenceFormat::kColmap:
      return "colmap";
    case ReferenceFormat::kStrecha:
      return "strecha";
    case ReferenceFormat::kBundler:
      return "bundler";
    case ReferenceFormat::kSequence:
      return "sequence";
  }
  return "";
}

bool ParseReferenceFormat(const std::string& name, ReferenceFormat* format) {
  for (ReferenceFormat f : {ReferenceFormat::kAuto, ReferenceFormat::kColmap,
                            ReferenceFormat::kStrecha, ReferenceFormat::kBundler,
                            ReferenceFormat::kSequence}) {
    if (name == ReferenceFormatName(f)) {
      *format = f;
      return true;
    }
  }
  return false;
}

namespace {

std::vector<std::string> CameraFiles(const std::string& folder) {
  std::vector<std::string> files;
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator(folder, ec)) {
    if (entry.is_regular_file() && EndsWith(entry.path().filename().string(), ".camera")) {
      files.push_back(entry.path().string());
    }
  }
  std::sort(files.begin(), files.end());
  return files;
}

std::string StrechaFolder(const std::string& folder) {
  if (!CameraFiles(folder).empty()) return folder;
  const std::string sub = JoinPaths(folder, "gt_dense_cameras");
  if (DirExists(sub) && !CameraFiles(sub).empty()) return sub;
  return "";
}

}  // namespace

ReferenceFormat DetectReferenceFormat(const std::string& path) {
  if (DirExists(path)) {
    if (IsSequenceFolderWithGroundTruth(path)) return ReferenceFormat::kSequence;
    if (HasModel(path, ModelFormat::kBinary) || HasModel(path, ModelFormat::kText)) {
      return ReferenceFormat::kColmap;
    }
    if (!StrechaFolder(path).empty()) return ReferenceFormat::kStrecha;
    throw InputError(path, "",
                     "expected a COLMAP model folder, a folder of Strecha *.camera files or a "
                     "simulated sequence folder (rig.yaml, groundtruth.txt, truth/), found none");
  }
  if (FileExists(path)) {
    if (Lower(fs::path(path).extension().string()) == ".out") return ReferenceFormat::kBundler;
    throw InputError(path, "", "expected a Bundler .out file or a folder, found another file");
  }
  throw InputError(path, "", "reference not found");
}

std::vector<NamedPose> PosesFromReconstruction(const Reconstruction& reconstruction) {
  std::vector<NamedPose> poses;
  poses.reserve(reconstruction.NumImages());
  for (const Image& image : reconstruction.Images()) {
    NamedPose pose;
    pose.name = image.name;
    pose.cam_from_world = image.CamFromWorld();
    if (reconstruction.ExistsCamera(image.camera_id)) {
      pose.camera = reconstruction.GetCamera(image.camera_id);
    }
    poses.push_back(pose);
  }
  return poses;
}

NamedPose ReadStrechaCamera(const std::string& path) {
  CheckFileExists(path, "Strecha camera file");
  TokenCursor cursor(path, Tokenize(path, false));
  double v[26];
  for (int i = 0; i < 26; ++i) v[i] = cursor.Double("number " + std::to_string(i + 1) + " of 26");
  if (!cursor.AtEnd()) cursor.Fail("26 numbers", "more", cursor.index());
  Mat3 k, r;
  k << v[0], v[1], v[2], v[3], v[4], v[5], v[6], v[7], v[8];
  r << v[12], v[13], v[14], v[15], v[16], v[17], v[18], v[19], v[20];
  const Vec3 c(v[21], v[22], v[23]);
  if (!IsRotation(r)) {
    throw InputError(path, "numbers 13-21", "expected a rotation matrix R, found one with |R^T R - I| >= 1e-4 or det < 0");
  }
  if (!(k(0, 0) > 0 && k(1, 1) > 0) || v[24] <= 0 || v[25] <= 0) {
    throw InputError(path, "numbers 1-9, 25-26",
                     "expected positive focal lengths and image size");
  }
  NamedPose pose;
  std::string name = fs::path(path).filename().string();
  pose.name = name.substr(0, name.size() - std::string(".camera").size());
  // P = K [R^T | -R^T C]: R is world_from_cam.
  const Mat3 cam_from_world = Orthonormalize(r).transpose();
  pose.cam_from_world = SE3(cam_from_world, -cam_from_world * c);
  pose.camera.model_id = static_cast<int>(CameraModelId::kPinhole);
  pose.camera.width = static_cast<uint64_t>(v[24]);
  pose.camera.height = static_cast<uint64_t>(v[25]);
  pose.camera.params = {k(0, 0), k(1, 1), k(0, 2), k(1, 2)};
  return pose;
}

std::vector<NamedPose> ReadStrechaCameras(const std::string& folder) {
  CheckDirExists(folder, "Strecha camera folder");
  const std::string dir = StrechaFolder(folder);
  if (dir.empty()) {
    throw InputError(folder, "", "expected *.camera files (here or in gt_dense_cameras/), found none");
  }
  std::vector<NamedPose> poses;
  for (const std::string& file : CameraFiles(dir)) poses.push_back(ReadStrechaCamera(file));
  return poses;
}

BundlerModel ReadBundlerFile(const std::string& path) {
  CheckFileExists(path, "Bundler file");
  {
    std::ifstream in(path);
    std::string first;
    std::getline(in, first);
    if (first.rfind("# Bundle file", 0) != 0) {
      throw InputError(path, "line 1", "expected '# Bundle file v0.3', found '" + first + "'");
    }
  }
  TokenCursor cursor(path, Tokenize(path, true));
  const int64_t num_cameras = cursor.Int("the number of cameras");
  const int64_t num_points = cursor.Int("the number of points");
  if (num_cameras < 0 || num_points < 0) cursor.Fail("non-negative counts", "a negative one", 0);
  BundlerModel model;
  model.cameras.resize(static_cast<size_t>(num_cameras));
  for (auto& camera : model.cameras) {
    camera.focal_px = cursor.Double("camera focal length");
    camera.k1 = cursor.Double("camera k1");
    camera.k2 = cursor.Double("camera k2");
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) camera.rotation(r, c) = cursor.Double("rotation entry");
    }
    for (int i = 0; i < 3; ++i) camera.translation(i) = cursor.Double("translation entry");
    if (camera.focal_px != 0.0 && !IsRotation(camera.rotation)) {
      cursor.Fail("a rotation matrix", "a matrix with |R^T R - I| >= 1e-4 or det < 0",
                  cursor.index() - 4);
    }
    if (camera.focal_px != 0.0) camera.rotation = Orthonormalize(camera.rotation);
  }
  model.points.resize(static_cast<size_t>(num_points));
  for (auto& point : model.points) {
    for (int i = 0; i < 3; ++i) point.xyz(i) = cursor.Double("point coordinate");
    for (int i = 0; i < 3; ++i) {
      const int64_t c = cursor.Int("colour component");
      if (c < 0 || c > 255) cursor.Fail("a colour in 0..255", std::to_string(c), cursor.index() - 1);
      point.color[static_cast<size_t>(i)] = static_cast<uint8_t>(c);
    }
    const int64_t n = cursor.Int("the view list length");
    if (n < 0) cursor.Fail("a non-negative view list length", std::to_string(n), cursor.index() - 1);
    point.observations.resize(static_cast<size_t>(n));
    for (auto& obs : point.observations) {
      const int64_t cam = cursor.Int("camera index");
      if (cam < 0 || cam >= num_cameras) {
        cursor.Fail("a camera index in 0.." + std::to_string(num_cameras - 1), std::to_string(cam),
                    cursor.index() - 1);
      }
      obs.camera_index = static_cast<int>(cam);
      obs.key_index = static_cast<int>(cursor.Int("key index"));
      obs.xy.x() = cursor.Double("image x");
      obs.xy.y() = cursor.Double("image y");
    }
  }
  if (!cursor.AtEnd()) cursor.Fail("end of file after " + std::to_string(num_points) + " points", "more data", cursor.index());
  return model;
}

SE3 BundlerCamFromWorld(const BundlerCamera& camera) {
  const Mat3 flip = Vec3(1, -1, -1).asDiagonal();
  return SE3(Mat3(flip * camera.rotation), Vec3(flip * camera.translation));
}

bool BundlerProject(const BundlerCamera& camera, const Vec3& xyz, Vec2* xy) {
  const Vec3 p_cam = camera.rotation * xyz + camera.translation;
  if (p_cam.z() >= 0) return false;  // Bundler cameras look down -z
  const Vec2 p = -p_cam.head<2>() / p_cam.z();
  const double r2 = p.squaredNorm();
  *xy = camera.focal_px * (1.0 + camera.k1 * r2 + camera.k2 * r2 * r2) * p;
  return true;
}

std::vector<std::string> BundlerImageNames(const std::string& out_path,
                                           const std::string& list_path,
                                           size_t num_cameras) {
  const fs::path dir = fs::path(out_path).parent_path();
  std::string source = list_path;
  if (source.empty() && FileExists((dir / "list.txt").string())) source = (dir / "list.txt").string();
  std::vector<std::string> names;
  if (!source.empty()) {
    LineReader reader(source);
    std::string line;
    while (reader.Next(&line)) {
      const auto tokens = SplitString(line, " \t\r");
      if (!tokens.empty()) names.push_back(tokens[0]);
    }
  } else {
    source = (dir / "images").string();
    if (!DirExists(source)) {
      throw InputError(out_path, "",
                       "expected an image list (list.txt beside it or given) or an images/ folder "
                       "beside it to name the Bundler cameras, found neither");
    }
    std::error_code ec;
    for (const auto& entry : fs::directory_iterator(source, ec)) {
      const std::string ext = Lower(entry.path().extension().string());
      if (entry.is_regular_file() && (ext == ".jpg" || ext == ".jpeg" || ext == ".png")) {
        names.push_back(entry.path().filename().string());
      }
    }
    std::sort(names.begin(), names.end(), NaturalLess);
  }
  if (names.size() != num_cameras) {
    throw InputError(source, "",
                     "expected " + std::to_string(num_cameras) + " image names (one per camera of " +
                         out_path + "), found " + std::to_string(names.size()));
  }
  return names;
}

std::vector<NamedPose> ReadBundlerPoses(const std::string& out_path,
                                        const std::string& list_path) {
  const BundlerModel model = ReadBundlerFile(out_path);
  const std::vector<std::string> names =
      BundlerImageNames(out_path, list_path, model.cameras.size());
  std::vector<NamedPose> poses;
  for (size_t i = 0; i < model.cameras.size(); ++i) {
    const BundlerCamera& camera = model.cameras[i];
    if (camera.focal_px == 0.0) continue;
    NamedPose pose;
    pose.name = names[i];
    pose.cam_from_world = BundlerCamFromWorld(camera);
    pose.camera.model_id = static_cast<int>(CameraModelId::kRadial);
    pose.camera.params = {camera.focal_px, 0.0, 0.0, camera.k1, camera.k2};
    poses.push_back(pose);
  }
  return poses;
}

std::vector<NamedPose> ReadReferencePoses(const std::string& path,
                                          ReferenceFormat format,
                                          const std::string& bundler_list_path) {
  if (format == ReferenceFormat::kAuto) format = DetectReferenceFormat(path);
  switch (format) {
    case ReferenceFormat::kColmap:
      return PosesFromReconstruction(ReadModel(path));
    case ReferenceFormat::kStrecha:
      return ReadStrechaCameras(path);
    case ReferenceFormat::kBundler:
      return ReadBundlerPoses(path, bundler_list_path);
    case ReferenceFormat::kSequence:
      return ReadSequenceReference(path).poses;
    case ReferenceFormat::kAuto:
      break;
  }
  throw InternalError("ReadReferencePoses: unresolved reference format");
}

bool SfmEvaluationOptions::Check() const {
  CHECK_OPTION_MSG(auc_thresholds_deg,
                   !auc_thresholds_deg.empty() &&
                       std::all_of(auc_thresholds_deg.begin(), auc_thresholds_deg.end(),
                                   [](double t) { return t > 0 && std::isfinite(t); }),
                   "a non-empty list of thresholds > 0");
  return true;
}

double RelativePoseErrorDeg(const SE3& cam1_from_world_est,
                            const SE3& cam2_from_world_est,
                            const SE3& cam1_from_world_ref,
                            const SE3& cam2_from_world_ref,
                            double* rotation_error_deg,
                            double* translation_error_deg) {
  const SE3 rel_est = cam2_from_world_est * cam1_from_world_est.Inverse();
  const SE3 rel_ref = cam2_from_world_ref * cam1_from_world_ref.Inverse();
  const double r = kRadToDeg * so3::AngularDistance(rel_est.rotation(), rel_ref.rotation());
  double t = kRadToDeg * VectorAngle(rel_est.translation(), rel_ref.translation());
  // Coincident centres in one model: the direction is undefined, the worst case.
  if (!std::isfinite(t)) t = 180.0;
  if (rotation_error_deg != nullptr) *rotation_error_deg = r;
  if (translation_error_deg != nullptr) *translation_error_deg = t;
  return std::max(r, t);
}

std::vector<double> PoseAuc(const std::vector<double>& errors_deg,
                            const std::vector<double>& thresholds_deg) {
  std::vector<double> errors = errors_deg;
  std::sort(errors.begin(), errors.end());
  const size_t n = errors.size();
  std::vector<double> aucs;
  for (double threshold : thresholds_deg) {
    THROW_CHECK_GT(threshold, 0.0);
    if (n == 0) {
      aucs.push_back(0.0);
      continue;
    }
    // Trapezoid integral of the step-free recall curve through (0, 0) and
    // (e_k, (k + 1) / n), extended flat to the threshold.
    double area = 0.0, prev_e = 0.0, prev_r = 0.0;
    for (size_t k = 0; k < n && errors[k] <= threshold; ++k) {
      const double r = static_cast<double>(k + 1) / static_cast<double>(n);
      area += 0.5 * (prev_r + r) * (errors[k] - prev_e);
      prev_e = errors[k];
      prev_r = r;
    }
    area += prev_r * (threshold - prev_e);
    aucs.push_back(area / threshold);
  }
  return aucs;
}

SfmEvaluation EvaluatePoses(const std::vector<NamedPose>& estimate,
                            const std::vector<NamedPose>& reference,
                            const SfmEvaluationOptions& options) {
  THROW_CHECK(options.Check());
  SfmEvaluation ev;
  ev.num_reference_images = reference.size();
  ev.num_estimated_images = estimate.size();
  ev.auc_thresholds_deg = options.auc_thresholds_deg;

  // Association: reference index -> estimate index (-1 = not registered).
  const NameIndex estimate_index(estimate);
  const NameIndex reference_index(reference);
  std::vector<long> match(reference.size(), -1);
  std::vector<bool> estimate_used(estimate.size(), false);
  for (size_t i = 0; i < reference.size(); ++i) {
    const long j = estimate_index.Find(reference[i].name);
    if (j >= 0 && !estimate_used[static_cast<size_t>(j)]) {
      match[i] = j;
      estimate_used[static_cast<size_t>(j)] = true;
      ++ev.num_registered;
    }
  }
  for (size_t j = 0; j < estimate.size(); ++j) {
    if (!estimate_used[j] && reference_index.Find(estimate[j].name) < 0) ++ev.num_unmatched_estimated;
  }
  if (ev.num_registered == 0) {
    throw InputError("no estimated image matches a reference image by name (" +
                     std::to_string(estimate.size()) + " estimated, " +
                     std::to_string(reference.size()) + " reference images)");
  }

  // Alignment reference_from_estimate.
  std::vector<Vec3> est_centres, ref_centres;
  std::vector<Quat> world_rotations;  // ref_world_from_est_world candidates
  for (size_t i = 0; i < reference.size(); ++i) {
    if (match[i] < 0) continue;
    const SE3& est = estimate[static_cast<size_t>(match[i])].cam_from_world;
    const SE3& ref = reference[i].cam_from_world;
    est_centres.push_back(est.Inverse().translation());
    ref_centres.push_back(ref.Inverse().translation());
    world_rotations.push_back(ref.rotation().conjugate() * est.rotation());
  }
  bool rotation_only = false;
  if (options.alignment == AlignmentType::kNone) {
    ev.alignment = "none";
  } else if (est_centres.size() < 3) {
    rotation_only = true;
  } else {
    try {
      ev.reference_from_estimate = AlignPositions(est_centres, ref_centres, options.alignment);
      ev.alignment = AlignmentTypeName(options.alignment);
    } catch (const InputError& e) {
      LogWarning("model evaluation: {}; falling back to a rotation-only alignment", e.what());
      rotation_only = true;
    }
  }
  // Rotation errors use their own alignment, the geodesic L1 mean of
  // R_ref^T R_est: with close camera centres the centre-based rotation is
  // poorly conditioned and would mix position noise into rotation errors.
  const Quat world_rotation = options.alignment == AlignmentType::kNone
                                  ? Quat::Identity()
                                  : GeodesicMedian(world_rotations);
  if (rotation_only) {
    ev.alignment = "rotation_only";
    ev.reference_from_estimate = Sim3();
    ev.reference_from_estimate.pose.SetRotation(world_rotation);
  }

  std::vector<double> rotation_errors, position_errors;
  for (size_t i = 0; i < reference.size(); ++i) {
    ImageEvaluation image;
    image.name = reference[i].name;
    image.registered = match[i] >= 0;
    image.rotation_error_deg = kNaN;
    image.position_error = kNaN;
    if (image.registered) {
      const SE3& est = estimate[static_cast<size_t>(match[i])].cam_from_world;
      const SE3& ref = reference[i].cam_from_world;
      // cam_from_ref_world = cam_from_est_world * est_world_from_ref_world.
      const Quat est_aligned = est.rotation() * world_rotation.conjugate();
      image.rotation_error_deg = kRadToDeg * so3::AngularDistance(est_aligned, ref.rotation());
      rotation_errors.push_back(image.rotation_error_deg);
      if (!rotation_only) {
        const Vec3 aligned_centre = ev.reference_from_estimate * est.Inverse().translation();
        image.position_error = (aligned_centre - ref.Inverse().translation()).norm();
        position_errors.push_back(image.position_error);
      }
    }
    ev.images.push_back(image);
  }
  ev.rotation_error_deg = ComputeErrorStats(rotation_errors);
  ev.position_error = ComputeErrorStats(position_errors);

  // Relative poses over all reference pairs.
  std::vector<double> pair_errors, relative_rotation, relative_translation;
  for (size_t i = 0; i < reference.size(); ++i) {
    for (size_t j = i + 1; j < reference.size(); ++j) {
      ++ev.num_pairs;
      if (match[i] < 0 || match[j] < 0) {
        pair_errors.push_back(kInf);
        continue;
      }
      double r = 0, t = 0;
      pair_errors.push_back(RelativePoseErrorDeg(
          estimate[static_cast<size_t>(match[i])].cam_from_world,
          estimate[static_cast<size_t>(match[j])].cam_from_world, reference[i].cam_from_world,
          reference[j].cam_from_world, &r, &t));
      relative_rotation.push_back(r);
      relative_translation.push_back(t);
    }
  }
  ev.relative_rotation_error_deg = ComputeErrorStats(relative_rotation);
  ev.relative_translation_error_deg = ComputeErrorStats(relative_translation);
  ev.auc = PoseAuc(pair_errors, options.auc_thresholds_deg);
  return ev;
}

}  // namespace colmap
}  // namespace lisfm

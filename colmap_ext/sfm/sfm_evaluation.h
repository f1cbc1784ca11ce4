// Evaluation of SfM camera poses against reference cameras (`lisfm model_evaluator`,
// scripts/compare_colmap.sh).
//
// References: a COLMAP model folder (model_io.h), the Strecha et al. 2008
// `gt_dense_cameras/*.camera` folder, a Bundler v0.3 `.out` file, or a
// simulated sequence folder (the true camera poses, sequence_reference.h).
//
// Conventions: every pose is cam_from_world in COLMAP's camera frame (x right,
// y down, z forward); camera centres C = -R^T t. Reference and estimate each
// live in their own world frame; the alignment reference_from_estimate maps the
// estimate's world into the reference's (core/evaluation.h, DESIGN.md
// "Alignment in evaluation"). Position errors are in reference units (metres
// for Strecha, arbitrary for COLMAP / Bundler references), angles in degrees.
//
// Association is by image name: the full name when it occurs in the other set,
// otherwise the basename (the part after the last '/'), which must then be
// unique in both sets.
//
// Metrics (per associated image): position error = |C_ref - T * C_est| after
// the Sim(3)/SE(3) alignment T of the camera centres (Umeyama, no RANSAC);
// rotation error = angle of R_ref * (R_est * A^T)^T where A is the geodesic
// L1 mean of R_ref^T R_est over the images (robust, and well conditioned even
// when the centres are close together, unlike T's rotation); mean, median,
// max. Relative-pose AUC (alignment-free, the convention of GLOMAP's and
// COLMAP's benchmark scripts, SuperGlue's `pose_auc`): for every pair (i, j)
// of reference images, error = max(angle of the relative rotation error,
// angle between the relative translation directions) in degrees, infinite
// when i or j is not in the estimate; AUC(t) = integral_0^t recall(e) de / t.
//
// Failures: malformed reference files throw InputError naming the file and
// line/record; fewer than 3 associated images (or collinear camera centres)
// fall back to a rotation-only alignment (position errors NaN); no associated
// image at all throws InputError.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "colmap_ext/io/camera_models.h"
#include "colmap_ext/io/reconstruction.h"
#include "core/evaluation.h"
#include "core/geometry.h"

namespace lisfm {
namespace colmap {

// One camera of a reference or estimated model.
struct NamedPose {
  std::string name;     // image name (relative path or basename)
  SE3 cam_from_world;   // COLMAP camera frame, world of its model
  Camera camera;        // intrinsics when the source has them (model_id kInvalid otherwise)
};

enum class ReferenceFormat { kAuto, kColmap, kStrecha, kBundler, kSequence };

// "auto", "colmap", "strecha", "bundler", "sequence".
std::string ReferenceFormatName(ReferenceFormat format);
// False for an unknown name.
bool ParseReferenceFormat(const std::string& name, ReferenceFormat* format);
// A folder with rig.yaml and groundtruth.txt (a simulated sequence folder,
// sequence_reference.h) -> kSequence; a folder with a COLMAP model -> kColmap;
// a folder with *.camera files (or a `gt_dense_cameras` subfolder holding
// them) -> kStrecha; a `.out` file -> kBundler. Throws InputError naming `path` when none applies.
ReferenceFormat DetectReferenceFormat(const std::string& path);

// The registered images of a COLMAP model (file order).
std::vector<NamedPose> PosesFromReconstruction(const Reconstruction& reconstruction);

// Strecha `.camera` files (26 numbers: K row-major, 3 distortion zeros, R
// row-major, C, width height; P = K [R^T | -R^T C], R = world_from_cam).
// Name = file name without ".camera" ("0000.jpg.camera" -> "0000.jpg").
// camera = PINHOLE (fx, fy, cx, cy) exactly as stored (full resolution, the
// file's own pixel convention). Throws InputError for a malformed file
// (naming it and the number index) or a non-rotation R.
NamedPose ReadStrechaCamera(const std::string& path);
// Every *.camera file in `folder` (or in `folder`/gt_dense_cameras), sorted by name.
std::vector<NamedPose> ReadStrechaCameras(const std::string& folder);

// Bundler v0.3 (`# Bundle file v0.3`, "num_cameras num_points", per camera
// `f k1 k2`, R (3 rows), t; per point X, RGB, `n (camera key x y)*`). Image
// coordinates are relative to the image centre with y up; the camera looks
// down -z: P = R X + t, p = -P.xy / P.z, pixel = f (1 + k1 |p|^2 + k2 |p|^4) p.
struct BundlerCamera {
  double focal_px = 0;  // 0 = camera not reconstructed
  double k1 = 0;
  double k2 = 0;
  Mat3 rotation = Mat3::Identity();  // Bundler camera_from_world
  Vec3 translation = Vec3::Zero();
};
struct BundlerObservation {
  int camera_index = 0;
  int key_index = 0;
  Vec2 xy = Vec2::Zero();  // pixels from the image centre, y up
};
struct BundlerPoint {
  Vec3 xyz = Vec3::Zero();
  std::array<uint8_t, 3> color{{0, 0, 0}};  // RGB
  std::vector<BundlerObservation> observations;
};
struct BundlerModel {
  std::vector<BundlerCamera> cameras;
  std::vector<BundlerPoint> points;
};
// Throws InputError naming the file and "line N" for a malformed file or an
// observation of a camera index out of range.
BundlerModel ReadBundlerFile(const std::string& path);
// COLMAP cam_from_world of a Bundler camera: diag(1, -1, -1) * [R | t].
SE3 BundlerCamFromWorld(const BundlerCamera& camera);
// Bundler's projection (image centre relative, y up); false behind the camera.
bool BundlerProject(const BundlerCamera& camera, const Vec3& xyz, Vec2* xy);
// Image names of the Bundler cameras, in camera order: the first token of each
// line of `list_path` (Bundler's list.txt) when given; else `list.txt` beside
// the .out file; else the image files (.jpg/.jpeg/.png, any case) of the
// `images` folder beside it in natural order (numbers compared as numbers:
// X-2 before X-10). Throws InputError when the count differs from
// `num_cameras` or no source exists.
std::vector<std::string> BundlerImageNames(const std::string& out_path,
                                           const std::string& list_path,
                                           size_t num_cameras);
// The reconstructed Bundler cameras (focal_px > 0) with their names; camera =
// RADIAL (f, 0, 0, k1, k2): the principal point is unknown without the images,
// so it is 0 here (poses are what is evaluated).
std::vector<NamedPose> ReadBundlerPoses(const std::string& out_path,
                                        const std::string& list_path);

// Reads a reference of any format (kAuto: DetectReferenceFormat).
// `bundler_list_path` is only used for Bundler files.
std::vector<NamedPose> ReadReferencePoses(const std::string& path,
                                          ReferenceFormat format,
                                          const std::string& bundler_list_path = "");

struct SfmEvaluationOptions {
  // kSim3 for scale-free models, kSE3 for metric ones; kNone compares as given.
  AlignmentType alignment = AlignmentType::kSim3;
  // AUC thresholds (deg), each > 0.
  std::vector<double> auc_thresholds_deg = {1.0, 5.0, 10.0};
  bool Check() const;
};

struct ImageEvaluation {
  std::string name;          // reference name
  bool registered = false;   // present in the estimate
  double rotation_error_deg = 0;  // NaN when not registered
  double position_error = 0;      // reference units; NaN when not registered or rotation-only
};

struct SfmEvaluation {
  size_t num_reference_images = 0;
  size_t num_estimated_images = 0;
  size_t num_registered = 0;       // reference images present in the estimate
  size_t num_unmatched_estimated = 0;  // estimated images absent from the reference
  // Alignment actually used: the requested one, or "rotation_only" when fewer
  // than 3 images associate or their centres are collinear.
  std::string alignment;
  // From the camera centres; scale 1 unless sim3. With "rotation_only" its
  // rotation is the rotation alignment A (see the file comment).
  Sim3 reference_from_estimate;
  std::vector<ImageEvaluation> images;  // one per reference image, reference order
  ErrorStats rotation_error_deg;  // over registered images
  ErrorStats position_error;      // over registered images (count 0 when rotation-only)
  // Relative pose errors over all reference pairs (unregistered pairs count as
  // infinite for the AUC but are excluded from these statistics).
  size_t num_pairs = 0;
  ErrorStats relative_rotation_error_deg;
  ErrorStats relative_translation_error_deg;
  std::vector<double> auc_thresholds_deg;
  std::vector<double> auc;  // in [0, 1], one per threshold
};

// Angle (deg) between the relative poses cam2_from_cam1 of two models: the
// max of the rotation error angle and the translation-direction angle.
// Exposed for tests.
double RelativePoseErrorDeg(const SE3& cam1_from_world_est,
                            const SE3& cam2_from_world_est,
                            const SE3& cam1_from_world_ref,
                            const SE3& cam2_from_world_ref,
                            double* rotation_error_deg = nullptr,
                            double* translation_error_deg = nullptr);
// Area under the recall curve up to each threshold, divided by the threshold
// (SuperGlue / GLOMAP `pose_auc`). Infinite errors lower the recall.
std::vector<double> PoseAuc(const std::vector<double>& errors_deg,
                            const std::vector<double>& thresholds_deg);

// Associates by name, aligns and scores `estimate` against `reference`.
// Throws InputError when no image associates or names are ambiguous.
SfmEvaluation EvaluatePoses(const std::vector<NamedPose>& estimate,
                            const std::vector<NamedPose>& reference,
                            const SfmEvaluationOptions& options);

}  // namespace colmap
}  // namespace lisfm

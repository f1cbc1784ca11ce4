// COLMAP SQLite database (REFERENCES.md section 1), written in the COLMAP 3.8
// schema (`PRAGMA user_version = 3800`) that the Debian `colmap` reads:
//   cameras(camera_id, model, width, height, params f64 blob, prior_focal_length)
//   images(image_id, name, camera_id, prior_qw..qz, prior_tx..tz)
//   keypoints / descriptors(image_id, rows, cols, data)   f32 N x {2,4,6} / u8 N x 128
//   matches(pair_id, rows, cols, data)                    u32 N x 2
//   two_view_geometries(pair_id, rows, cols, data, config, F, E, H, qvec, tvec)
// plus a `pose_priors` table in the COLMAP 3.11-3.13 layout (image_id,
// position 3 f64, coordinate_system, position_covariance 9 f64), which 3.8
// ignores and newer COLMAP reads (4.x migrates it). No rigs/frames tables are
// written (3.8 target); they are read when present (3.12+ databases), and so
// are pose_priors in the 3.10, 3.11 and 4.x layouts.
//
// Pose priors: `prior_q*` hold the cam_from_world rotation (qw, qx, qy, qz);
// `prior_t*` and pose_priors.position hold the camera centre in world
// coordinates (how 3.8's spatial_matcher and model_aligner read them). A
// position with x = y = 0 (which 3.8's spatial_matcher skips, with ignore_z
// on by default) is written with x = kPriorOriginOffset instead.
//
// Pairs: pair_id = 2147483647 * min(id1, id2) + max(id1, id2). Reading a pair
// as (id1, id2) with id1 > id2 swaps the match columns, transposes F and E,
// inverts H and the relative pose, as COLMAP does.
//
// Blobs are raw row-major little-endian. Failures (all InputError naming the
// database file): a file that is not SQLite, an SQLite file without the
// COLMAP tables or with tables missing required columns (unknown schema), a
// blob whose size does not match rows x cols x element size or the fixed
// size (naming the table and record), invalid ids. Never a crash.
// One Database object is not thread-safe; use one per thread.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "colmap_ext/io/camera_models.h"
#include "colmap_ext/io/reconstruction.h"
#include "core/types.h"

struct sqlite3;
struct sqlite3_stmt;

namespace lisfm {
namespace colmap {

using image_pair_t = uint64_t;
constexpr uint64_t kMaxNumImages = 2147483647;  // image ids are < this
constexpr double kPriorOriginOffset = 1e-6;     // m, see the header comment

image_pair_t ImagePairToPairId(image_t image_id1, image_t image_id2);
void PairIdToImagePair(image_pair_t pair_id, image_t* image_id1, image_t* image_id2);
// True when COLMAP stores the pair as (image_id2, image_id1).
inline bool SwapImagePair(image_t image_id1, image_t image_id2) {
  return image_id1 > image_id2;
}

using KeypointsBlob = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
using DescriptorsBlob =
    Eigen::Matrix<uint8_t, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
using MatchesBlob = Eigen::Matrix<uint32_t, Eigen::Dynamic, 2, Eigen::RowMajor>;

// COLMAP's PosePrior::CoordinateSystem (3.11+).
enum class PriorCoordinateSystem : int { kUndefined = -1, kWgs84 = 0, kCartesian = 1 };

// An images row with its priors.
struct DbImage {
  image_t image_id = kInvalidImageId;
  std::string name;
  camera_t camera_id = kInvalidCameraId;
  bool has_prior_rotation = false;
  Vec4 prior_qvec = Vec4(1, 0, 0, 0);  // cam_from_world (qw, qx, qy, qz)
  bool has_prior_position = false;
  Vec3 prior_position = Vec3::Zero();  // camera centre in world (m, or lat/lon/alt)
  // Row-major 3x3 position covariance (m^2); NaN = unset (COLMAP's convention).
  Mat3 prior_position_covariance = Mat3::Constant(std::numeric_limits<double>::quiet_NaN());
  PriorCoordinateSystem prior_coordinate_system = PriorCoordinateSystem::kCartesian;
};

// COLMAP's TwoViewGeometry::ConfigurationType.
enum class TwoViewConfig : int {
  kUndefined = 0,
  kDegenerate = 1,
  kCalibrated = 2,
  kUncalibrated = 3,
  kPlanar = 4,
  kPanoramic = 5,
  kPlanarOrPanoramic = 6,
  kWatermark = 7,
  kMultiple = 8,
};

struct TwoViewGeometry {
  int config = static_cast<int>(TwoViewConfig::kUndefined);
  MatchesBlob inlier_matches;        // (point2D idx in image 1, in image 2)
  Mat3 F = Mat3::Zero();             // x2^T F x1 = 0 (pixels)
  Mat3 E = Mat3::Zero();             // normalised coordinates
  Mat3 H = Mat3::Zero();             // x2 ~ H x1
  Vec4 qvec = Vec4(1, 0, 0, 0);      // cam2_from_cam1 rotation (qw, qx, qy, qz)
  Vec3 tvec = Vec3::Zero();          // cam2_from_cam1 translation
  // The same geometry seen from image 2 (swapped matches, F^T, E^T, H^-1,
  // inverse relative pose).
  TwoViewGeometry Inverse() const;
};

// 3.12+ rig tables (read only).
struct DbRigSensor {
  SensorId sensor;
  bool has_pose = false;
  Vec4 qvec = Vec4(1, 0, 0, 0);  // sensor_from_rig
  Vec3 tvec = Vec3::Zero();
};
struct DbRig {
  uint32_t rig_id = 0;
  SensorId ref_sensor;
  std::vector<DbRigSensor> sensors;  // non-reference sensors
};
struct DbFrame {
  uint32_t frame_id = 0;
  uint32_t rig_id = 0;
  std::vector<FrameData> data;
};

// What Open() found.
struct DatabaseSchema {
  int user_version = 0;
  bool images_have_prior_columns = true;  // false for COLMAP >= 3.10 databases
  // "none", "3.10" (image_id, position, coordinate_system), "3.11"
  // (+ position_covariance) or "4.0" (pose_prior_id, corr_data_id, ...).
  std::string pose_priors_layout = "none";
  bool has_rigs = false;  // rigs, rig_sensors, frames, frame_data
  std::vector<std::string> tables;
};

class Database {
 public:
  enum class OpenMode {
    kReadOnly,   // the file must exist and be a COLMAP database; never written,
                 // and no -wal/-shm files are left beside it (if writable)
    kReadWrite,  // same, writable
    kCreate,     // create the file and the 3.8 tables if missing
  };

  Database(const std::string& path, OpenMode mode);
  ~Database();
  Database(const Database&) = delete;
  Database& operator=(const Database&) = delete;

  const std::string& path() const { return path_; }
  const DatabaseSchema& schema() const { return schema_; }

  // Rows in `table` (0 for a missing table); total rows of a blob table.
  size_t CountRows(const std::string& table) const;
  size_t SumRowsColumn(const std::string& table) const;
  size_t NumCameras() const { return CountRows("cameras"); }
  size_t NumImages() const { return CountRows("images"); }

  // ---- cameras ----
  // Inserts a camera; with use_camera_id the given id, otherwise a new one
  // (returned). Throws InputError for invalid parameters or a taken id.
  camera_t WriteCamera(const Camera& camera, bool use_camera_id = false);
  void UpdateCamera(const Camera& camera);
  bool ExistsCamera(camera_t camera_id) const;
  Camera ReadCamera(camera_t camera_id) const;  // InputError when missing
  std::vector<Camera> ReadAllCameras() const;

  // ---- images ----
  image_t WriteImage(const DbImage& image, bool use_image_id = false);
  void UpdateImage(const DbImage& image);
  bool ExistsImage(image_t image_id) const;
  DbImage ReadImage(image_t image_id) const;
  std::vector<DbImage> ReadAllImages() const;
  // kInvalidImageId when no image has this name.
  image_t FindImageId(const std::string& name) const;

  // ---- features (replace existing rows) ----
  void WriteKeypoints(image_t image_id, const KeypointsBlob& keypoints);
  void WriteDescriptors(image_t image_id, const DescriptorsBlob& descriptors);
  // Empty (0 x 6 / 0 x 128) when the image has no row.
  KeypointsBlob ReadKeypoints(image_t image_id) const;
  DescriptorsBlob ReadDescriptors(image_t image_id) const;
  bool ExistsKeypoints(image_t image_id) const;

  // ---- matches / geometries, in the caller's (id1, id2) order ----
  void WriteMatches(image_t image_id1, image_t image_id2, const MatchesBlob& matches);
  MatchesBlob ReadMatches(image_t image_id1, image_t image_id2) const;
  bool ExistsMatches(image_t image_id1, image_t image_id2) const;
  std::vector<std::pair<image_pair_t, MatchesBlob>> ReadAllMatches() const;
  // pair_id -> number of raw matches (the `rows` column; no blob is read).
  std::unordered_map<image_pair_t, size_t> ReadAllNumMatches() const;
  void WriteTwoViewGeometry(image_t image_id1,
                            image_t image_id2,
                            const TwoViewGeometry& geometry);
  TwoViewGeometry ReadTwoViewGeometry(image_t image_id1, image_t image_id2) const;
  bool ExistsTwoViewGeometry(image_t image_id1, image_t image_id2) const;
  // As stored (image_id1 < image_id2 of the pair id).
  std::vector<std::pair<image_pair_t, TwoViewGeometry>> ReadAllTwoViewGeometries() const;
  // Remove the matches and the two-view geometry of one pair / of all pairs
  // (COLMAP's ClearMatches / ClearTwoViewGeometries).
  void DeleteMatchesAndGeometry(image_t image_id1, image_t image_id2);
  void ClearMatches();
  void ClearTwoViewGeometries();

  // ---- newer schema elements (empty when absent) ----
  std::vector<DbRig> ReadRigs() const;
  std::vector<DbFrame> ReadFrames() const;

  // Bulk writes: everything between Begin and End is one transaction.
  void BeginTransaction();
  void EndTransaction();
  void RollbackTransaction();

 private:
  struct Stmt;
  void Exec(const std::string& sql) const;
  std::unique_ptr<Stmt> Prepare(const std::string& sql) const;
  void InspectSchema();
  void CreateTables();
  std::vector<std::string> Columns(const std::string& table) const;
  bool HasTable(const std::string& table) const;
  [[noreturn]] void Fail(const std::string& where, const std::string& message) const;
  void WritePosePrior(const DbImage& image);
  void ReadPosePriors(std::vector<DbImage>* images) const;
  DbImage ReadImageRow(Stmt& stmt) const;

  std::string path_;
  sqlite3* db_ = nullptr;
  bool read_only_ = false;
  DatabaseSchema schema_;
};

// RAII transaction: Commit() ends it; leaving the scope without Commit()
// (e.g. by an exception) rolls it back.
class DatabaseTransaction {
 public:
  explicit DatabaseTransaction(Database* database);
  ~DatabaseTransaction();
  void Commit();

 private:
  Database* database_;
  bool done_ = false;
};

}  // namespace colmap
}  // namespace lisfm

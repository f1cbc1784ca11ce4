#include "colmap_ext/io/database.h"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <unordered_map>

#include <sqlite3.h>

#include "core/errors.h"
#include "core/file_utils.h"
#include "core/logging.h"

namespace lisfm {
namespace colmap {

// ---- pair ids ----

image_pair_t ImagePairToPairId(image_t image_id1, image_t image_id2) {
  THROW_CHECK_LT(image_id1, kMaxNumImages);
  THROW_CHECK_LT(image_id2, kMaxNumImages);
  if (SwapImagePair(image_id1, image_id2)) std::swap(image_id1, image_id2);
  return kMaxNumImages * static_cast<image_pair_t>(image_id1) + image_id2;
}

void PairIdToImagePair(image_pair_t pair_id, image_t* image_id1, image_t* image_id2) {
  *image_id2 = static_cast<image_t>(pair_id % kMaxNumImages);
  *image_id1 = static_cast<image_t>((pair_id - *image_id2) / kMaxNumImages);
}

TwoViewGeometry TwoViewGeometry::Inverse() const {
  TwoViewGeometry inv = *this;
  if (inlier_matches.rows() > 0) {
    inv.inlier_matches.col(0) = inlier_matches.col(1);
    inv.inlier_matches.col(1) = inlier_matches.col(0);
  }
  inv.F = F.transpose();
  inv.E = E.transpose();
  inv.H = H.determinant() != 0.0 ? Mat3(H.inverse()) : H;
  if (qvec.norm() == 0.0) {
    inv.tvec = -tvec;
  } else {
    const Quat q(qvec(0), qvec(1), qvec(2), qvec(3));
    const Quat q_inv = q.normalized().conjugate();
    inv.qvec = Vec4(q_inv.w(), q_inv.x(), q_inv.y(), q_inv.z());
    inv.tvec = -(q_inv * tvec);
  }
  return inv;
}

// ---- statements ----

struct Database::Stmt {
  const Database* db = nullptr;
  sqlite3_stmt* stmt = nullptr;
  std::string sql;
  ~Stmt() { sqlite3_finalize(stmt); }
  int Step() {
    const int rc = sqlite3_step(stmt);
    if (rc != SQLITE_ROW && rc != SQLITE_DONE) {
      db->Fail("", "SQLite error in '" + sql.substr(0, 60) + "': " + sqlite3_errmsg(db->db_));
    }
    return rc;
  }
  void Reset() {
    sqlite3_reset(stmt);
    sqlite3_clear_bindings(stmt);
  }
  void BindInt(int i, int64_t v) { Check(sqlite3_bind_int64(stmt, i, v)); }
  void BindNull(int i) { Check(sqlite3_bind_null(stmt, i)); }
  void BindDouble(int i, double v) { Check(sqlite3_bind_double(stmt, i, v)); }
  void BindText(int i, const std::string& s) {
    Check(sqlite3_bind_text(stmt, i, s.c_str(), static_cast<int>(s.size()), SQLITE_TRANSIENT));
  }
  void BindBlob(int i, const void* data, size_t bytes) {
    // A zero-length blob (not NULL), as COLMAP writes for empty matrices.
    Check(sqlite3_bind_blob64(stmt, i, bytes > 0 ? data : "", bytes, SQLITE_STATIC));
  }
  void Check(int rc) {
    if (rc != SQLITE_OK) db->Fail("", std::string("SQLite bind failed: ") + sqlite3_errmsg(db->db_));
  }
  int64_t Int(int col) { return sqlite3_column_int64(stmt, col); }
  double Double(int col) { return sqlite3_column_double(stmt, col); }
  bool IsNull(int col) { return sqlite3_column_type(stmt, col) == SQLITE_NULL; }
  std::string Text(int col) {
    const unsigned char* t = sqlite3_column_text(stmt, col);
    return t == nullptr ? std::string() : std::string(reinterpret_cast<const char*>(t));
  }
  const void* Blob(int col) { return sqlite3_column_blob(stmt, col); }
  size_t Bytes(int col) { return static_cast<size_t>(sqlite3_column_bytes(stmt, col)); }
};

void Database::Fail(const std::string& where, const std::string& message) const {
  throw InputError(path_, where, message);
}

std::unique_ptr<Database::Stmt> Database::Prepare(const std::string& sql) const {
  auto s = std::make_unique<Stmt>();
  s->db = this;
  s->sql = sql;
  const int rc = sqlite3_prepare_v2(db_, sql.c_str(), -1, &s->stmt, nullptr);
  if (rc != SQLITE_OK) {
    Fail("", std::string(rc == SQLITE_NOTADB ? "not a COLMAP database: " : "SQLite error: ") +
                 sqlite3_errmsg(db_) + " (in '" + sql.substr(0, 60) + "')");
  }
  return s;
}

void Database::Exec(const std::string& sql) const {
  char* error = nullptr;
  const int rc = sqlite3_exec(db_, sql.c_str(), nullptr, nullptr, &error);
  if (rc != SQLITE_OK) {
    const std::string message = error != nullptr ? error : sqlite3_errstr(rc);
    sqlite3_free(error);
    Fail("", std::string(rc == SQLITE_NOTADB ? "not a COLMAP database: " : "SQLite error: ") +
                 message);
  }
}

// ---- open / schema ----

namespace {

// The COLMAP 3.8 tables, column text as stock COLMAP creates them.
const char* const kCreateTables[] = {
    "CREATE TABLE IF NOT EXISTS cameras   (camera_id            INTEGER  PRIMARY KEY "
    "AUTOINCREMENT  NOT NULL,    model                INTEGER                             "
    "NOT NULL,    width                INTEGER                             NOT NULL,    "
    "height               INTEGER                             NOT NULL,    params          "
    "     BLOB,    prior_focal_length   INTEGER                             NOT NULL)",
    "CREATE TABLE IF NOT EXISTS images   (image_id   INTEGER  PRIMARY KEY AUTOINCREMENT  "
    "NOT NULL,    name       TEXT                                NOT NULL UNIQUE,    "
    "camera_id  INTEGER                             NOT NULL,    prior_qw   REAL,    "
    "prior_qx   REAL,    prior_qy   REAL,    prior_qz   REAL,    prior_tx   REAL,    "
    "prior_ty   REAL,    prior_tz   REAL,CONSTRAINT image_id_check CHECK(image_id >= 0 and "
    "image_id < 2147483647),FOREIGN KEY(camera_id) REFERENCES cameras(camera_id))",
    "CREATE UNIQUE INDEX IF NOT EXISTS index_name ON images(name)",
    "CREATE TABLE IF NOT EXISTS keypoints   (image_id  INTEGER  PRIMARY KEY  NOT NULL,    "
    "rows      INTEGER               NOT NULL,    cols      INTEGER               NOT "
    "NULL,    data      BLOB,FOREIGN KEY(image_id) REFERENCES images(image_id) ON DELETE "
    "CASCADE)",
    "CREATE TABLE IF NOT EXISTS descriptors   (image_id  INTEGER  PRIMARY KEY  NOT NULL,    "
    "rows      INTEGER               NOT NULL,    cols      INTEGER               NOT "
    "NULL,    data      BLOB,FOREIGN KEY(image_id) REFERENCES images(image_id) ON DELETE "
    "CASCADE)",
    "CREATE TABLE IF NOT EXISTS matches   (pair_id  INTEGER  PRIMARY KEY  NOT NULL,    rows  "
    "   INTEGER               NOT NULL,    cols     INTEGER               NOT NULL,    data  "
    "   BLOB)",
    "CREATE TABLE IF NOT EXISTS two_view_geometries   (pair_id  INTEGER  PRIMARY KEY  NOT "
    "NULL,    rows     INTEGER               NOT NULL,    cols     INTEGER               NOT "
    "NULL,    data     BLOB,    config   INTEGER               NOT NULL,    F        BLOB,  "
    "  E        BLOB,    H        BLOB,    qvec     BLOB,    tvec     BLOB)",
    // COLMAP 3.11-3.13 pose priors (ignored by 3.8).
    "CREATE TABLE IF NOT EXISTS pose_priors   (image_id   INTEGER  PRIMARY KEY  NOT NULL,    "
    "position   BLOB,    coordinate_system   INTEGER               NOT NULL,    "
    "position_covariance   BLOB,FOREIGN KEY(image_id) REFERENCES images(image_id) ON DELETE "
    "CASCADE)",
};

struct RequiredTable {
  const char* name;
  std::vector<std::string> columns;
};

const RequiredTable kRequired[] = {
    {"cameras", {"camera_id", "model", "width", "height", "params", "prior_focal_length"}},
    {"images", {"image_id", "name", "camera_id"}},
    {"keypoints", {"image_id", "rows", "cols", "data"}},
    {"descriptors", {"image_id", "rows", "cols", "data"}},
    {"matches", {"pair_id", "rows", "cols", "data"}},
    {"two_view_geometries", {"pair_id", "rows", "cols", "data", "config"}},
};

const char* const kPriorColumns[] = {"prior_qw", "prior_qx", "prior_qy", "prior_qz",
                                     "prior_tx", "prior_ty", "prior_tz"};

bool Contains(const std::vector<std::string>& v, const std::string& s) {
  return std::find(v.begin(), v.end(), s) != v.end();
}

std::string Join(const std::vector<std::string>& v) {
  std::string s;
  for (const auto& x : v) s += (s.empty() ? "" : ", ") + x;
  return s.empty() ? "none" : s;
}

}  // namespace

Database::Database(const std::string& path, OpenMode mode) : path_(path) {
  read_only_ = mode == OpenMode::kReadOnly;
  if (mode != OpenMode::kCreate) CheckFileExists(path, "database");
  // Reading a WAL-mode database (journal_mode=WAL, as stock COLMAP 3.8 leaves
  // the databases it writes) creates `-wal` and `-shm` files beside it, and
  // only a connection that may write removes them when the last one closes.
  // So a read-only Database on a writable file uses a read-write connection
  // that refuses every write (PRAGMA query_only): the files disappear on close
  // as with any writer. A file we may not write is opened read-only (SQLite
  // may then leave them).
  const bool query_only = read_only_ && ::access(path.c_str(), W_OK) == 0;
  int flags = read_only_ && !query_only ? SQLITE_OPEN_READONLY : SQLITE_OPEN_READWRITE;
  if (mode == OpenMode::kCreate) flags |= SQLITE_OPEN_CREATE;
  const int rc = sqlite3_open_v2(path.c_str(), &db_, flags | SQLITE_OPEN_NOMUTEX, nullptr);
  if (rc != SQLITE_OK) {
    const std::string message = db_ != nullptr ? sqlite3_errmsg(db_) : sqlite3_errstr(rc);
    sqlite3_close_v2(db_);
    db_ = nullptr;
    Fail("", "cannot open database: " + message);
  }
  // Processes that open one database at once (the ranks of an mpirun) can find
  // it locked for a moment (a WAL database's shared-memory setup and the last
  // closer's checkpoint): wait up to 60 s for the lock instead of failing.
  sqlite3_busy_timeout(db_, 60000);
  try {
    if (query_only) Exec("PRAGMA query_only = ON");
    InspectSchema();
    if (!read_only_) {
      Exec("PRAGMA foreign_keys=ON");
      Exec("PRAGMA synchronous=OFF");
      if (schema_.tables.empty()) {
        CreateTables();
        Exec("PRAGMA user_version = 3800");
        InspectSchema();
      }
    }
  } catch (...) {
    sqlite3_close_v2(db_);
    db_ = nullptr;
    throw;
  }
}

Database::~Database() {
  if (db_ != nullptr) sqlite3_close_v2(db_);
}

std::vector<std::string> Database::Columns(const std::string& table) const {
  std::vector<std::string> columns;
  auto stmt = Prepare("PRAGMA table_info(" + table + ")");
  while (stmt->Step() == SQLITE_ROW) columns.push_back(stmt->Text(1));
  return columns;
}

bool Database::HasTable(const std::string& table) const {
  return Contains(schema_.tables, table);
}

void Database::InspectSchema() {
  schema_ = DatabaseSchema();
  {
    auto stmt = Prepare("SELECT name FROM sqlite_master WHERE type='table' ORDER BY name");
    while (stmt->Step() == SQLITE_ROW) {
      const std::string name = stmt->Text(0);
      if (name != "sqlite_sequence") schema_.tables.push_back(name);
    }
  }
  {
    auto stmt = Prepare("PRAGMA user_version");
    if (stmt->Step() == SQLITE_ROW) schema_.user_version = static_cast<int>(stmt->Int(0));
  }
  if (schema_.tables.empty()) {
    if (read_only_) {
      Fail("", "not a COLMAP database: expected tables cameras, images, keypoints, "
               "descriptors, matches, two_view_geometries, found an empty database");
    }
    return;  // a new database; CreateTables() follows
  }
  if (!HasTable("cameras") || !HasTable("images")) {
    Fail("", "not a COLMAP database: expected tables cameras and images, found " +
                 Join(schema_.tables));
  }
  for (size_t i = 0; i < sizeof(kRequired) / sizeof(kRequired[0]); ++i) {
    const RequiredTable& table = kRequired[i];
    if (!HasTable(table.name)) {
      if (read_only_) continue;  // a writable database gets the missing table
      Exec(kCreateTables[i < 2 ? i : i + 1]);  // kCreateTables[2] is the name index
      schema_.tables.push_back(table.name);
      continue;
    }
    const std::vector<std::string> columns = Columns(table.name);
    for (const std::string& column : table.columns) {
      if (!Contains(columns, column)) {
        Fail("table " + std::string(table.name),
             "unknown COLMAP schema: expected column '" + column + "', found columns " +
                 Join(columns));
      }
    }
  }
  const std::vector<std::string> image_columns = Columns("images");
  int num_prior = 0;
  for (const char* c : kPriorColumns) num_prior += Contains(image_columns, c) ? 1 : 0;
  if (num_prior != 0 && num_prior != 7) {
    Fail("table images", "unknown COLMAP schema: expected all or none of prior_qw..prior_tz, "
                         "found " + std::to_string(num_prior) + " of them");
  }
  schema_.images_have_prior_columns = num_prior == 7;
  if (!read_only_ && !HasTable("pose_priors")) {
    Exec(kCreateTables[7]);  // priors are written both ways
    schema_.tables.push_back("pose_priors");
  }
  if (HasTable("pose_priors")) {
    const std::vector<std::string> c = Columns("pose_priors");
    if (Contains(c, "pose_prior_id") && Contains(c, "corr_data_id") && Contains(c, "position")) {
      schema_.pose_priors_layout = "4.0";
    } else if (Contains(c, "image_id") && Contains(c, "position") &&
               Contains(c, "coordinate_system")) {
      schema_.pose_priors_layout = Contains(c, "position_covariance") ? "3.11" : "3.10";
    } else {
      Fail("table pose_priors", "unknown COLMAP schema: expected image_id, position, "
                                "coordinate_system (3.10-3.13) or pose_prior_id, corr_data_id "
                                "(4.x), found " + Join(c));
    }
  }
  schema_.has_rigs = HasTable("rigs") && HasTable("rig_sensors") && HasTable("frames") &&
                     HasTable("frame_data");
}

void Database::CreateTables() {
  Exec("BEGIN");
  for (const char* sql : kCreateTables) Exec(sql);
  Exec("COMMIT");
}

size_t Database::CountRows(const std::string& table) const {
  if (!HasTable(table)) return 0;
  auto stmt = Prepare("SELECT COUNT(*) FROM " + table);
  stmt->Step();
  return static_cast<size_t>(stmt->Int(0));
}

size_t Database::SumRowsColumn(const std::string& table) const {
  if (!HasTable(table)) return 0;
  auto stmt = Prepare("SELECT SUM(rows) FROM " + table);
  stmt->Step();
  return static_cast<size_t>(stmt->Int(0));
}

void Database::BeginTransaction() { Exec("BEGIN TRANSACTION"); }
void Database::EndTransaction() { Exec("END TRANSACTION"); }
void Database::RollbackTransaction() { Exec("ROLLBACK TRANSACTION"); }

DatabaseTransaction::DatabaseTransaction(Database* database) : database_(database) {
  database_->BeginTransaction();
}
DatabaseTransaction::~DatabaseTransaction() {
  if (!done_) {
    try {
      database_->RollbackTransaction();
    } catch (...) {
    }
  }
}
void DatabaseTransaction::Commit() {
  database_->EndTransaction();
  done_ = true;
}

// ---- cameras ----

camera_t Database::WriteCamera(const Camera& camera, bool use_camera_id) {
  if (!camera.VerifyParams()) {
    Fail("camera " + std::to_string(camera.camera_id),
         "expected a COLMAP model with " + std::to_string(CameraModelNumParams(camera.model_id)) +
             " finite parameters, found model " + std::to_string(camera.model_id) + " with " +
             std::to_string(camera.params.size()));
  }
  if (use_camera_id && ExistsCamera(camera.camera_id)) {
    Fail("camera " + std::to_string(camera.camera_id), "camera id already exists");
  }
  auto stmt = Prepare(
      "INSERT INTO cameras(camera_id, model, width, height, params, prior_focal_length) "
      "VALUES(?, ?, ?, ?, ?, ?)");
  if (use_camera_id) {
    stmt->BindInt(1, camera.camera_id);
  } else {
    stmt->BindNull(1);
  }
  stmt->BindInt(2, camera.model_id);
  stmt->BindInt(3, static_cast<int64_t>(camera.width));
  stmt->BindInt(4, static_cast<int64_t>(camera.height));
  stmt->BindBlob(5, camera.params.data(), camera.params.size() * sizeof(double));
  stmt->BindInt(6, camera.has_prior_focal_length ? 1 : 0);
  stmt->Step();
  return static_cast<camera_t>(sqlite3_last_insert_rowid(db_));
}

void Database::UpdateCamera(const Camera& camera) {
  if (!camera.VerifyParams()) {
    Fail("camera " + std::to_string(camera.camera_id), "invalid camera parameters");
  }
  auto stmt = Prepare(
      "UPDATE cameras SET model=?, width=?, height=?, params=?, prior_focal_length=? WHERE "
      "camera_id=?");
  stmt->BindInt(1, camera.model_id);
  stmt->BindInt(2, static_cast<int64_t>(camera.width));
  stmt->BindInt(3, static_cast<int64_t>(camera.height));
  stmt->BindBlob(4, camera.params.data(), camera.params.size() * sizeof(double));
  stmt->BindInt(5, camera.has_prior_focal_length ? 1 : 0);
  stmt->BindInt(6, camera.camera_id);
  stmt->Step();
}

bool Database::ExistsCamera(camera_t camera_id) const {
  auto stmt = Prepare("SELECT 1 FROM cameras WHERE camera_id = ?");
  stmt->BindInt(1, camera_id);
  return stmt->Step() == SQLITE_ROW;
}

namespace {
Camera CameraFromRow(const std::string& path, int64_t id, int64_t model, int64_t width,
                     int64_t height, const void* blob, size_t bytes, int64_t prior) {
  const std::string where = "table cameras, camera_id " + std::to_string(id);
  Camera camera;
  camera.camera_id = static_cast<camera_t>(id);
  camera.model_id = static_cast<int>(model);
  if (!ExistsCameraModel(camera.model_id)) {
    throw InputError(path, where, "expected a camera model id in 0-10, found " + std::to_string(model));
  }
  const size_t expected = CameraModelNumParams(camera.model_id) * sizeof(double);
  if (bytes != expected) {
    throw InputError(path, where,
                     "params blob: expected " + std::to_string(expected) + " bytes for " +
                         camera.ModelName() + ", found " + std::to_string(bytes));
  }
  if (width < 0 || height < 0) throw InputError(path, where, "negative image size");
  camera.width = static_cast<uint64_t>(width);
  camera.height = static_cast<uint64_t>(height);
  camera.params.resize(expected / sizeof(double));
  if (bytes > 0) std::memcpy(camera.params.data(), blob, bytes);
  camera.has_prior_focal_length = prior != 0;
  return camera;
}
}  // namespace

std::vector<Camera> Database::ReadAllCameras() const {
  std::vector<Camera> cameras;
  auto stmt = Prepare(
      "SELECT camera_id, model, width, height, params, prior_focal_length FROM cameras "
      "ORDER BY camera_id");
  while (stmt->Step() == SQLITE_ROW) {
    cameras.push_back(CameraFromRow(path_, stmt->Int(0), stmt->Int(1), stmt->Int(2),
                                    stmt->Int(3), stmt->Blob(4), stmt->Bytes(4), stmt->Int(5)));
  }
  return cameras;
}

Camera Database::ReadCamera(camera_t camera_id) const {
  auto stmt = Prepare(
      "SELECT camera_id, model, width, height, params, prior_focal_length FROM cameras "
      "WHERE camera_id = ?");
  stmt->BindInt(1, camera_id);
  if (stmt->Step() != SQLITE_ROW) {
    Fail("table cameras", "expected camera_id " + std::to_string(camera_id) + ", found none");
  }
  return CameraFromRow(path_, stmt->Int(0), stmt->Int(1), stmt->Int(2), stmt->Int(3),
                       stmt->Blob(4), stmt->Bytes(4), stmt->Int(5));
}

// ---- images ----

image_t Database::WriteImage(const DbImage& image, bool use_image_id) {
  if (use_image_id && image.image_id >= kMaxNumImages) {
    Fail("image " + std::to_string(image.image_id), "expected an image id < 2147483647");
  }
  if (image.name.empty()) Fail("table images", "expected a non-empty image name");
  if (FindImageId(image.name) != kInvalidImageId) {
    Fail("table images", "image name '" + image.name + "' already exists");
  }
  if (!ExistsCamera(image.camera_id)) {
    Fail("image " + image.name,
         "expected an existing camera_id, found " + std::to_string(image.camera_id));
  }
  if (use_image_id && ExistsImage(image.image_id)) {
    Fail("image " + std::to_string(image.image_id), "image id already exists");
  }
  DbImage stored = image;
  if (stored.has_prior_position && stored.prior_position.x() == 0.0 &&
      stored.prior_position.y() == 0.0) {
    stored.prior_position.x() = kPriorOriginOffset;
  }
  std::unique_ptr<Stmt> stmt;
  if (schema_.images_have_prior_columns) {
    stmt = Prepare(
        "INSERT INTO images(image_id, name, camera_id, prior_qw, prior_qx, prior_qy, prior_qz, "
        "prior_tx, prior_ty, prior_tz) VALUES(?, ?, ?, ?, ?, ?, ?, ?, ?, ?)");
    for (int k = 0; k < 4; ++k) {
      if (stored.has_prior_rotation) {
        stmt->BindDouble(4 + k, stored.prior_qvec(k));
      } else {
        stmt->BindNull(4 + k);
      }
    }
    for (int k = 0; k < 3; ++k) {
      if (stored.has_prior_position) {
        stmt->BindDouble(8 + k, stored.prior_position(k));
      } else {
        stmt->BindNull(8 + k);
      }
    }
  } else {
    stmt = Prepare("INSERT INTO images(image_id, name, camera_id) VALUES(?, ?, ?)");
  }
  if (use_image_id) {
    stmt->BindInt(1, stored.image_id);
  } else {
    stmt->BindNull(1);
  }
  stmt->BindText(2, stored.name);
  stmt->BindInt(3, stored.camera_id);
  stmt->Step();
  stored.image_id = static_cast<image_t>(sqlite3_last_insert_rowid(db_));
  WritePosePrior(stored);
  return stored.image_id;
}

void Database::WritePosePrior(const DbImage& image) {
  if (!image.has_prior_position || !HasTable("pose_priors")) return;
  if (schema_.pose_priors_layout == "4.0") {
    LogWarning("{}: pose_priors in the COLMAP 4 layout are not written", path_);
    return;
  }
  const bool with_covariance = schema_.pose_priors_layout == "3.11";
  auto stmt = Prepare(with_covariance
                          ? "INSERT OR REPLACE INTO pose_priors(image_id, position, "
                            "coordinate_system, position_covariance) VALUES(?, ?, ?, ?)"
                          : "INSERT OR REPLACE INTO pose_priors(image_id, position, "
                            "coordinate_system) VALUES(?, ?, ?)");
  stmt->BindInt(1, image.image_id);
  stmt->BindBlob(2, image.prior_position.data(), 3 * sizeof(double));
  stmt->BindInt(3, static_cast<int>(image.prior_coordinate_system));
  Eigen::Matrix<double, 3, 3, Eigen::RowMajor> cov = image.prior_position_covariance;
  if (with_covariance) stmt->BindBlob(4, cov.data(), 9 * sizeof(double));
  stmt->Step();
}

void Database::UpdateImage(const DbImage& image) {
  if (!ExistsImage(image.image_id)) {
    Fail("table images", "expected image_id " + std::to_string(image.image_id) + ", found none");
  }
  DbImage stored = image;
  if (stored.has_prior_position && stored.prior_position.x() == 0.0 &&
      stored.prior_position.y() == 0.0) {
    stored.prior_position.x() = kPriorOriginOffset;
  }
  if (schema_.images_have_prior_columns) {
    auto stmt = Prepare(
        "UPDATE images SET name=?, camera_id=?, prior_qw=?, prior_qx=?, prior_qy=?, "
        "prior_qz=?, prior_tx=?, prior_ty=?, prior_tz=? WHERE image_id=?");
    stmt->BindText(1, stored.name);
    stmt->BindInt(2, stored.camera_id);
    for (int k = 0; k < 4; ++k) {
      if (stored.has_prior_rotation) {
        stmt->BindDouble(3 + k, stored.prior_qvec(k));
      } else {
        stmt->BindNull(3 + k);
      }
    }
    for (int k = 0; k < 3; ++k) {
      if (stored.has_prior_position) {
        stmt->BindDouble(7 + k, stored.prior_position(k));
      } else {
        stmt->BindNull(7 + k);
      }
    }
    stmt->BindInt(10, stored.image_id);
    stmt->Step();
  } else {
    auto stmt = Prepare("UPDATE images SET name=?, camera_id=? WHERE image_id=?");
    stmt->BindText(1, stored.name);
    stmt->BindInt(2, stored.camera_id);
    stmt->BindInt(3, stored.image_id);
    stmt->Step();
  }
  if (!stored.has_prior_position && HasTable("pose_priors") &&
      schema_.pose_priors_layout != "4.0") {
    auto stmt = Prepare("DELETE FROM pose_priors WHERE image_id = ?");
    stmt->BindInt(1, stored.image_id);
    stmt->Step();
  }
  WritePosePrior(stored);
}

bool Database::ExistsImage(image_t image_id) const {
  auto stmt = Prepare("SELECT 1 FROM images WHERE image_id = ?");
  stmt->BindInt(1, image_id);
  return stmt->Step() == SQLITE_ROW;
}

image_t Database::FindImageId(const std::string& name) const {
  auto stmt = Prepare("SELECT image_id FROM images WHERE name = ?");
  stmt->BindText(1, name);
  if (stmt->Step() != SQLITE_ROW) return kInvalidImageId;
  return static_cast<image_t>(stmt->Int(0));
}

DbImage Database::ReadImageRow(Stmt& stmt) const {
  DbImage image;
  const int64_t id = stmt.Int(0);
  if (id < 0 || id >= static_cast<int64_t>(kMaxNumImages)) {
    Fail("table images", "expected image_id in [0, 2147483647), found " + std::to_string(id));
  }
  image.image_id = static_cast<image_t>(id);
  image.name = stmt.Text(1);
  image.camera_id = static_cast<camera_t>(stmt.Int(2));
  if (schema_.images_have_prior_columns) {
    bool all_q = true, all_t = true;
    for (int k = 0; k < 4; ++k) all_q &= !stmt.IsNull(3 + k);
    for (int k = 0; k < 3; ++k) all_t &= !stmt.IsNull(7 + k);
    if (all_q) {
      image.has_prior_rotation = true;
      for (int k = 0; k < 4; ++k) image.prior_qvec(k) = stmt.Double(3 + k);
    }
    if (all_t) {
      image.has_prior_position = true;
      for (int k = 0; k < 3; ++k) image.prior_position(k) = stmt.Double(7 + k);
    }
  }
  return image;
}

namespace {
std::string ImageSelect(bool with_priors) {
  return with_priors ? "SELECT image_id, name, camera_id, prior_qw, prior_qx, prior_qy, "
                       "prior_qz, prior_tx, prior_ty, prior_tz FROM images"
                     : "SELECT image_id, name, camera_id FROM images";
}
}  // namespace

void Database::ReadPosePriors(std::vector<DbImage>* images) const {
  if (schema_.pose_priors_layout == "none" || images->empty()) return;
  std::unordered_map<image_t, size_t> index;
  for (size_t i = 0; i < images->size(); ++i) index[(*images)[i].image_id] = i;
  const bool v4 = schema_.pose_priors_layout == "4.0";
  const bool with_cov = schema_.pose_priors_layout != "3.10";
  std::string sql =
      v4 ? "SELECT corr_data_id, position, coordinate_system, position_covariance, "
           "corr_sensor_type FROM pose_priors"
         : std::string("SELECT image_id, position, coordinate_system") +
               (with_cov ? ", position_covariance" : "") + " FROM pose_priors";
  auto stmt = Prepare(sql);
  while (stmt->Step() == SQLITE_ROW) {
    const int64_t id = stmt->Int(0);
    const std::string where = "table pose_priors, image_id " + std::to_string(id);
    if (v4 && stmt->Int(4) != 0) continue;  // not a camera prior
    const auto it = index.find(static_cast<image_t>(id));
    if (it == index.end()) continue;
    DbImage& image = (*images)[it->second];
    if (stmt->Bytes(1) != 3 * sizeof(double)) {
      if (stmt->Bytes(1) == 0) continue;
      Fail(where, "position blob: expected 24 bytes, found " + std::to_string(stmt->Bytes(1)));
    }
    Vec3 position;
    std::memcpy(position.data(), stmt->Blob(1), 3 * sizeof(double));
    if (!image.has_prior_position) {
      image.has_prior_position = true;
      image.prior_position = position;
    }
    image.prior_coordinate_system = static_cast<PriorCoordinateSystem>(stmt->Int(2));
    if (with_cov && stmt->Bytes(3) > 0) {
      if (stmt->Bytes(3) != 9 * sizeof(double)) {
        Fail(where, "position_covariance blob: expected 72 bytes, found " +
                        std::to_string(stmt->Bytes(3)));
      }
      Eigen::Matrix<double, 3, 3, Eigen::RowMajor> cov;
      std::memcpy(cov.data(), stmt->Blob(3), 9 * sizeof(double));
      image.prior_position_covariance = cov;
    }
  }
}

DbImage Database::ReadImage(image_t image_id) const {
  auto stmt = Prepare(ImageSelect(schema_.images_have_prior_columns) + " WHERE image_id = ?");
  stmt->BindInt(1, image_id);
  if (stmt->Step() != SQLITE_ROW) {
    Fail("table images", "expected image_id " + std::to_string(image_id) + ", found none");
  }
  std::vector<DbImage> images{ReadImageRow(*stmt)};
  ReadPosePriors(&images);
  return images[0];
}

std::vector<DbImage> Database::ReadAllImages() const {
  std::vector<DbImage> images;
  auto stmt = Prepare(ImageSelect(schema_.images_have_prior_columns) + " ORDER BY image_id");
  while (stmt->Step() == SQLITE_ROW) images.push_back(ReadImageRow(*stmt));
  ReadPosePriors(&images);
  return images;
}

// ---- features ----

namespace {
template <typename Matrix>
Matrix ReadMatrix(const std::string& path, const std::string& where, int64_t rows, int64_t cols,
                  const void* blob, size_t bytes) {
  using Scalar = typename Matrix::Scalar;
  if (rows < 0 || cols < 0 || rows > (int64_t{1} << 40) || cols > (int64_t{1} << 20)) {
    throw InputError(path, where, "invalid blob shape " + std::to_string(rows) + " x " +
                                      std::to_string(cols));
  }
  const size_t expected = static_cast<size_t>(rows * cols) * sizeof(Scalar);
  if (bytes != expected) {
    throw InputError(path, where,
                     "data blob: expected " + std::to_string(expected) + " bytes for " +
                         std::to_string(rows) + " x " + std::to_string(cols) + " values, found " +
                         std::to_string(bytes));
  }
  Matrix m(rows, cols);
  if (bytes > 0) std::memcpy(m.data(), blob, bytes);
  return m;
}
}  // namespace

void Database::WriteKeypoints(image_t image_id, const KeypointsBlob& keypoints) {
  THROW_CHECK_MSG(keypoints.cols() == 2 || keypoints.cols() == 4 || keypoints.cols() == 6,
                  "keypoints need 2, 4 or 6 columns, got " << keypoints.cols());
  auto stmt = Prepare("INSERT OR REPLACE INTO keypoints(image_id, rows, cols, data) VALUES(?, ?, ?, ?)");
  stmt->BindInt(1, image_id);
  stmt->BindInt(2, keypoints.rows());
  stmt->BindInt(3, keypoints.cols());
  stmt->BindBlob(4, keypoints.data(), keypoints.size() * sizeof(float));
  stmt->Step();
}

void Database::WriteDescriptors(image_t image_id, const DescriptorsBlob& descriptors) {
  auto stmt =
      Prepare("INSERT OR REPLACE INTO descriptors(image_id, rows, cols, data) VALUES(?, ?, ?, ?)");
  stmt->BindInt(1, image_id);
  stmt->BindInt(2, descriptors.rows());
  stmt->BindInt(3, descriptors.cols());
  stmt->BindBlob(4, descriptors.data(), descriptors.size());
  stmt->Step();
}

KeypointsBlob Database::ReadKeypoints(image_t image_id) const {
  if (!HasTable("keypoints")) return KeypointsBlob(0, 6);
  auto stmt = Prepare("SELECT rows, cols, data FROM keypoints WHERE image_id = ?");
  stmt->BindInt(1, image_id);
  if (stmt->Step() != SQLITE_ROW) return KeypointsBlob(0, 6);
  const std::string where = "table keypoints, image_id " + std::to_string(image_id);
  const int64_t cols = stmt->Int(1);
  if (cols != 2 && cols != 4 && cols != 6 && !(cols == 0 && stmt->Int(0) == 0)) {
    Fail(where, "expected 2, 4 or 6 columns, found " + std::to_string(cols));
  }
  return ReadMatrix<KeypointsBlob>(path_, where, stmt->Int(0), cols, stmt->Blob(2), stmt->Bytes(2));
}

DescriptorsBlob Database::ReadDescriptors(image_t image_id) const {
  if (!HasTable("descriptors")) return DescriptorsBlob(0, 128);
  auto stmt = Prepare("SELECT rows, cols, data FROM descriptors WHERE image_id = ?");
  stmt->BindInt(1, image_id);
  if (stmt->Step() != SQLITE_ROW) return DescriptorsBlob(0, 128);
  return ReadMatrix<DescriptorsBlob>(path_,
                                     "table descriptors, image_id " + std::to_string(image_id),
                                     stmt->Int(0), stmt->Int(1), stmt->Blob(2), stmt->Bytes(2));
}

bool Database::ExistsKeypoints(image_t image_id) const {
  if (!HasTable("keypoints")) return false;
  auto stmt = Prepare("SELECT 1 FROM keypoints WHERE image_id = ?");
  stmt->BindInt(1, image_id);
  return stmt->Step() == SQLITE_ROW;
}

// ---- matches ----

namespace {
MatchesBlob SwapColumns(const MatchesBlob& m) {
  MatchesBlob s(m.rows(), 2);
  if (m.rows() > 0) {
    s.col(0) = m.col(1);
    s.col(1) = m.col(0);
  }
  return s;
}
std::string PairWhere(const char* table, image_pair_t pair_id) {
  image_t a, b;
  PairIdToImagePair(pair_id, &a, &b);
  return std::string("table ") + table + ", pair_id " + std::to_string(pair_id) + " (images " +
         std::to_string(a) + ", " + std::to_string(b) + ")";
}
MatchesBlob ReadMatchesRow(const std::string& path, const std::string& where, int64_t rows,
                           int64_t cols, const void* blob, size_t bytes) {
  if (rows == 0 && bytes == 0) return MatchesBlob(0, 2);
  if (cols != 2) throw InputError(path, where, "expected 2 columns, found " + std::to_string(cols));
  using Dyn = Eigen::Matrix<uint32_t, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
  return ReadMatrix<Dyn>(path, where, rows, cols, blob, bytes);
}
}  // namespace

void Database::WriteMatches(image_t image_id1, image_t image_id2, const MatchesBlob& matches) {
  const image_pair_t pair_id = ImagePairToPairId(image_id1, image_id2);
  const MatchesBlob stored = SwapImagePair(image_id1, image_id2) ? SwapColumns(matches) : matches;
  auto stmt = Prepare("INSERT OR REPLACE INTO matches(pair_id, rows, cols, data) VALUES(?, ?, ?, ?)");
  stmt->BindInt(1, static_cast<int64_t>(pair_id));
  stmt->BindInt(2, stored.rows());
  stmt->BindInt(3, 2);
  stmt->BindBlob(4, stored.data(), stored.size() * sizeof(uint32_t));
  stmt->Step();
}

MatchesBlob Database::ReadMatches(image_t image_id1, image_t image_id2) const {
  const image_pair_t pair_id = ImagePairToPairId(image_id1, image_id2);
  if (!HasTable("matches")) return MatchesBlob(0, 2);
  auto stmt = Prepare("SELECT rows, cols, data FROM matches WHERE pair_id = ?");
  stmt->BindInt(1, static_cast<int64_t>(pair_id));
  if (stmt->Step() != SQLITE_ROW) return MatchesBlob(0, 2);
  const MatchesBlob m = ReadMatchesRow(path_, PairWhere("matches", pair_id), stmt->Int(0),
                                       stmt->Int(1), stmt->Blob(2), stmt->Bytes(2));
  return SwapImagePair(image_id1, image_id2) ? SwapColumns(m) : m;
}

bool Database::ExistsMatches(image_t image_id1, image_t image_id2) const {
  if (!HasTable("matches")) return false;
  auto stmt = Prepare("SELECT 1 FROM matches WHERE pair_id = ?");
  stmt->BindInt(1, static_cast<int64_t>(ImagePairToPairId(image_id1, image_id2)));
  return stmt->Step() == SQLITE_ROW;
}

std::vector<std::pair<image_pair_t, MatchesBlob>> Database::ReadAllMatches() const {
  std::vector<std::pair<image_pair_t, MatchesBlob>> all;
  if (!HasTable("matches")) return all;
  auto stmt = Prepare("SELECT pair_id, rows, cols, data FROM matches ORDER BY pair_id");
  while (stmt->Step() == SQLITE_ROW) {
    const auto pair_id = static_cast<image_pair_t>(stmt->Int(0));
    all.emplace_back(pair_id, ReadMatchesRow(path_, PairWhere("matches", pair_id), stmt->Int(1),
                                             stmt->Int(2), stmt->Blob(3), stmt->Bytes(3)));
  }
  return all;
}

std::unordered_map<image_pair_t, size_t> Database::ReadAllNumMatches() const {
  std::unordered_map<image_pair_t, size_t> counts;
  if (!HasTable("matches")) return counts;
  auto stmt = Prepare("SELECT pair_id, rows FROM matches");
  while (stmt->Step() == SQLITE_ROW) {
    const int64_t rows = stmt->Int(1);
    if (rows < 0) {
      throw InputError(path_, PairWhere("matches", static_cast<image_pair_t>(stmt->Int(0))),
                       "expected a non-negative row count, found " + std::to_string(rows));
    }
    counts[static_cast<image_pair_t>(stmt->Int(0))] = static_cast<size_t>(rows);
  }
  return counts;
}

// ---- two-view geometries ----

namespace {
const char* const kTwoViewSelect =
    "SELECT pair_id, rows, cols, data, config, F, E, H, qvec, tvec FROM two_view_geometries";

// NULL or empty reads as zero (COLMAP 3.8); any other size is an error.
template <int N>
Eigen::Matrix<double, N, 1> ReadFixed(const std::string& path, const std::string& where,
                                      const char* column, const void* blob, size_t bytes) {
  Eigen::Matrix<double, N, 1> v = Eigen::Matrix<double, N, 1>::Zero();
  if (bytes == 0) return v;
  if (bytes != N * sizeof(double)) {
    throw InputError(path, where, std::string(column) + " blob: expected " +
                                      std::to_string(N * sizeof(double)) + " bytes, found " +
                                      std::to_string(bytes));
  }
  std::memcpy(v.data(), blob, bytes);
  return v;
}

Mat3 RowMajor3(const Eigen::Matrix<double, 9, 1>& v) {
  Mat3 m;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) m(r, c) = v(3 * r + c);
  return m;
}
}  // namespace

void Database::DeleteMatchesAndGeometry(image_t image_id1, image_t image_id2) {
  const std::string id = std::to_string(ImagePairToPairId(image_id1, image_id2));
  Exec("DELETE FROM matches WHERE pair_id = " + id);
  Exec("DELETE FROM two_view_geometries WHERE pair_id = " + id);
}

void Database::ClearMatches() { Exec("DELETE FROM matches"); }

void Database::ClearTwoViewGeometries() { Exec("DELETE FROM two_view_geometries"); }

void Database::WriteTwoViewGeometry(image_t image_id1,
                                    image_t image_id2,
                                    const TwoViewGeometry& geometry) {
  const image_pair_t pair_id = ImagePairToPairId(image_id1, image_id2);
  const TwoViewGeometry g = SwapImagePair(image_id1, image_id2) ? geometry.Inverse() : geometry;
  auto stmt = Prepare(
      "INSERT OR REPLACE INTO two_view_geometries(pair_id, rows, cols, data, config, F, E, H, "
      "qvec, tvec) VALUES(?, ?, ?, ?, ?, ?, ?, ?, ?, ?)");
  stmt->BindInt(1, static_cast<int64_t>(pair_id));
  stmt->BindInt(2, g.inlier_matches.rows());
  stmt->BindInt(3, 2);
  stmt->BindBlob(4, g.inlier_matches.data(), g.inlier_matches.size() * sizeof(uint32_t));
  stmt->BindInt(5, g.config);
  const Eigen::Matrix<double, 3, 3, Eigen::RowMajor> F = g.F, E = g.E, H = g.H;
  stmt->BindBlob(6, F.data(), 72);
  stmt->BindBlob(7, E.data(), 72);
  stmt->BindBlob(8, H.data(), 72);
  stmt->BindBlob(9, g.qvec.data(), 32);
  stmt->BindBlob(10, g.tvec.data(), 24);
  stmt->Step();
}

namespace {
TwoViewGeometry ReadTwoViewRow(const std::string& path, const std::string& where, int64_t rows,
                               int64_t cols, const void* data, size_t data_bytes, int64_t config,
                               const void* const* blobs, const size_t* bytes) {
  TwoViewGeometry g;
  g.inlier_matches = ReadMatchesRow(path, where, rows, cols, data, data_bytes);
  g.config = static_cast<int>(config);
  g.F = RowMajor3(ReadFixed<9>(path, where, "F", blobs[0], bytes[0]));
  g.E = RowMajor3(ReadFixed<9>(path, where, "E", blobs[1], bytes[1]));
  g.H = RowMajor3(ReadFixed<9>(path, where, "H", blobs[2], bytes[2]));
  g.qvec = ReadFixed<4>(path, where, "qvec", blobs[3], bytes[3]);
  g.tvec = ReadFixed<3>(path, where, "tvec", blobs[4], bytes[4]);
  return g;
}
}  // namespace

TwoViewGeometry Database::ReadTwoViewGeometry(image_t image_id1, image_t image_id2) const {
  const image_pair_t pair_id = ImagePairToPairId(image_id1, image_id2);
  TwoViewGeometry g;
  g.qvec.setZero();
  if (!HasTable("two_view_geometries")) return g;
  auto stmt = Prepare(std::string(kTwoViewSelect) + " WHERE pair_id = ?");
  stmt->BindInt(1, static_cast<int64_t>(pair_id));
  if (stmt->Step() != SQLITE_ROW) return g;
  const void* blobs[5];
  size_t bytes[5];
  for (int k = 0; k < 5; ++k) {
    blobs[k] = stmt->Blob(5 + k);
    bytes[k] = stmt->Bytes(5 + k);
  }
  g = ReadTwoViewRow(path_, PairWhere("two_view_geometries", pair_id), stmt->Int(1), stmt->Int(2),
                     stmt->Blob(3), stmt->Bytes(3), stmt->Int(4), blobs, bytes);
  return SwapImagePair(image_id1, image_id2) ? g.Inverse() : g;
}

bool Database::ExistsTwoViewGeometry(image_t image_id1, image_t image_id2) const {
  if (!HasTable("two_view_geometries")) return false;
  auto stmt = Prepare("SELECT 1 FROM two_view_geometries WHERE pair_id = ?");
  stmt->BindInt(1, static_cast<int64_t>(ImagePairToPairId(image_id1, image_id2)));
  return stmt->Step() == SQLITE_ROW;
}

std::vector<std::pair<image_pair_t, TwoViewGeometry>> Database::ReadAllTwoViewGeometries() const {
  std::vector<std::pair<image_pair_t, TwoViewGeometry>> all;
  if (!HasTable("two_view_geometries")) return all;
  auto stmt = Prepare(std::string(kTwoViewSelect) + " ORDER BY pair_id");
  while (stmt->Step() == SQLITE_ROW) {
    const auto pair_id = static_cast<image_pair_t>(stmt->Int(0));
    const void* blobs[5];
    size_t bytes[5];
    for (int k = 0; k < 5; ++k) {
      blobs[k] = stmt->Blob(5 + k);
      bytes[k] = stmt->Bytes(5 + k);
    }
    all.emplace_back(pair_id, ReadTwoViewRow(path_, PairWhere("two_view_geometries", pair_id),
                                             stmt->Int(1), stmt->Int(2), stmt->Blob(3),
                                             stmt->Bytes(3), stmt->Int(4), blobs, bytes));
  }
  return all;
}

// ---- rigs / frames (COLMAP 3.12+) ----

std::vector<DbRig> Database::ReadRigs() const {
  std::vector<DbRig> rigs;
  if (!schema_.has_rigs) return rigs;
  std::unordered_map<uint32_t, size_t> index;
  auto stmt = Prepare("SELECT rig_id, ref_sensor_id, ref_sensor_type FROM rigs ORDER BY rig_id");
  while (stmt->Step() == SQLITE_ROW) {
    DbRig rig;
    rig.rig_id = static_cast<uint32_t>(stmt->Int(0));
    rig.ref_sensor.id = static_cast<uint32_t>(stmt->Int(1));
    rig.ref_sensor.type = static_cast<SensorType>(stmt->Int(2));
    index[rig.rig_id] = rigs.size();
    rigs.push_back(rig);
  }
  auto sensors = Prepare("SELECT rig_id, sensor_id, sensor_type, sensor_from_rig FROM rig_sensors");
  while (sensors->Step() == SQLITE_ROW) {
    const auto rig_id = static_cast<uint32_t>(sensors->Int(0));
    const std::string where = "table rig_sensors, rig_id " + std::to_string(rig_id);
    const auto it = index.find(rig_id);
    if (it == index.end()) Fail(where, "expected an existing rig_id, found none");
    DbRigSensor s;
    s.sensor.id = static_cast<uint32_t>(sensors->Int(1));
    s.sensor.type = static_cast<SensorType>(sensors->Int(2));
    if (sensors->Bytes(3) > 0) {
      const Eigen::Matrix<double, 7, 1> pose =
          ReadFixed<7>(path_, where, "sensor_from_rig", sensors->Blob(3), sensors->Bytes(3));
      s.has_pose = true;
      s.qvec = pose.head<4>();
      s.tvec = pose.tail<3>();
    }
    rigs[it->second].sensors.push_back(s);
  }
  return rigs;
}

std::vector<DbFrame> Database::ReadFrames() const {
  std::vector<DbFrame> frames;
  if (!schema_.has_rigs) return frames;
  std::unordered_map<uint32_t, size_t> index;
  auto stmt = Prepare("SELECT frame_id, rig_id FROM frames ORDER BY frame_id");
  while (stmt->Step() == SQLITE_ROW) {
    DbFrame f;
    f.frame_id = static_cast<uint32_t>(stmt->Int(0));
    f.rig_id = static_cast<uint32_t>(stmt->Int(1));
    index[f.frame_id] = frames.size();
    frames.push_back(f);
  }
  auto data = Prepare("SELECT frame_id, data_id, sensor_id, sensor_type FROM frame_data");
  while (data->Step() == SQLITE_ROW) {
    const auto frame_id = static_cast<uint32_t>(data->Int(0));
    const auto it = index.find(frame_id);
    if (it == index.end()) {
      Fail("table frame_data, frame_id " + std::to_string(frame_id),
           "expected an existing frame_id, found none");
    }
    FrameData d;
    d.data_id = static_cast<uint64_t>(data->Int(1));
    d.sensor.id = static_cast<uint32_t>(data->Int(2));
    d.sensor.type = static_cast<SensorType>(data->Int(3));
    frames[it->second].data.push_back(d);
  }
  return frames;
}

}  // namespace colmap
}  // namespace lisfm

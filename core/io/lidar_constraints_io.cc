#include "core/io/lidar_constraints_io.h"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <utility>

#include <Eigen/Eigenvalues>
#include <fmt/format.h>

#include "core/errors.h"
#include "core/file_utils.h"

namespace lisfm {
namespace {

constexpr int kNumFieldsLisfm = 2 + 7 + 21;
constexpr int kNumFieldsGtsfm = 2 + 12 + 36;
constexpr int kNumFieldsGtsfmWithCounts = kNumFieldsGtsfm + 25;
constexpr double kUnitTolerance = 1e-6;      // quaternion norm / R^T R - I
constexpr double kSymmetryTolerance = 1e-9;  // relative to max |C_ij|

enum class Format { kUnknown, kLisfm, kGtsfm };

class RecordParser {
 public:
  RecordParser(const LineReader& reader, const std::vector<std::string>& fields)
      : reader_(reader), fields_(fields) {}

  [[noreturn]] void Fail(const std::string& message) const {
    throw InputError(reader_.path(), reader_.Where(), message);
  }

  double Number(size_t k) const {
    double value = 0.0;
    if (!ParseDouble(fields_[k], &value) || !std::isfinite(value)) {
      Fail(fmt::format("field {}: expected a finite number, found '{}'", k + 1, fields_[k]));
    }
    return value;
  }

  int64_t Stamp(size_t k) const {
    int64_t value = 0;
    if (!ParseInt64(fields_[k], &value)) {
      Fail(fmt::format("field {}: expected an integer stamp in ns, found '{}'", k + 1,
                       fields_[k]));
    }
    return value;
  }

  // A keyframe index; numpy.savetxt writes it as a float ("2.0e+00").
  int64_t Index(size_t k) const {
    const double value = Number(k);
    if (value < 0.0 || value > 9.0e15 || value != std::floor(value)) {
      Fail(fmt::format("field {}: expected a non-negative integer keyframe index, found '{}'",
                       k + 1, fields_[k]));
    }
    return static_cast<int64_t>(value);
  }

  void CheckPositiveDefinite(const Mat6& covariance) const {
    Eigen::SelfAdjointEigenSolver<Mat6> solver(covariance, Eigen::EigenvaluesOnly);
    const double min_eigenvalue = solver.eigenvalues().minCoeff();
    if (solver.info() != Eigen::Success || !(min_eigenvalue > 0.0)) {
      Fail(fmt::format("expected a positive-definite covariance, found minimum eigenvalue {:.6g}",
                       min_eigenvalue));
    }
  }

  LidarConstraintRecord ParseLisfm() const {
    LidarConstraintRecord record;
    record.has_stamps = true;
    record.t_i_ns = Stamp(0);
    record.t_j_ns = Stamp(1);
    if (record.t_i_ns == record.t_j_ns) {
      Fail(fmt::format("expected two different stamps, found {} twice", record.t_i_ns));
    }
    const Vec3 t(Number(2), Number(3), Number(4));
    Quat q(Number(8), Number(5), Number(6), Number(7));  // file order qx qy qz qw
    const double norm = q.norm();
    if (std::abs(norm - 1.0) > kUnitTolerance) {
      Fail(fmt::format("expected a unit quaternion (|q| - 1 within {}), found |q| = {:.9g}",
                       kUnitTolerance, norm));
    }
    q.normalize();
    record.i_from_j = SE3(q, t);
    size_t k = 9;
    for (int r = 0; r < 6; ++r) {
      for (int c = r; c < 6; ++c) {
        record.covariance(r, c) = record.covariance(c, r) = Number(k++);
      }
    }
    CheckPositiveDefinite(record.covariance);
    return record;
  }

  LidarConstraintRecord ParseGtsfm() const {
    LidarConstraintRecord record;
    record.has_stamps = false;
    record.index_i = Index(0);
    record.index_j = Index(1);
    if (record.index_i == record.index_j) {
      Fail(fmt::format("expected two different keyframe indices, found {} twice",
                       record.index_i));
    }
    Eigen::Matrix<double, 3, 4> rt;
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 4; ++c) rt(r, c) = Number(2 + 4 * r + c);
    }
    const Mat3 rotation = rt.leftCols<3>();
    const double orthonormality_error =
        (rotation.transpose() * rotation - Mat3::Identity()).cwiseAbs().maxCoeff();
    if (orthonormality_error > kUnitTolerance || rotation.determinant() <= 0.0) {
      Fail(fmt::format(
          "expected a rotation matrix (|R^T R - I| <= {}, det > 0), found |R^T R - I| = "
          "{:.3g}, det = {:.9g}",
          kUnitTolerance, orthonormality_error, rotation.determinant()));
    }
    record.i_from_j = SE3(Quat(rotation).normalized(), Vec3(rt.col(3)));
    for (int r = 0; r < 6; ++r) {
      for (int c = 0; c < 6; ++c) record.covariance(r, c) = Number(14 + 6 * r + c);
    }
    const double scale = record.covariance.cwiseAbs().maxCoeff();
    const double asymmetry = (record.covariance - record.covariance.transpose()).cwiseAbs().maxCoeff();
    if (asymmetry > kSymmetryTolerance * scale) {
      Fail(fmt::format("expected a symmetric covariance, found max |C - C^T| = {:.3g}",
                       asymmetry));
    }
    record.covariance = 0.5 * (record.covariance + record.covariance.transpose()).eval();
    CheckPositiveDefinite(record.covariance);
    for (size_t k = kNumFieldsGtsfm; k < fields_.size(); ++k) Number(k);  // counts: numeric
    return record;
  }

 private:
  const LineReader& reader_;
  const std::vector<std::string>& fields_;
};

std::string FormatNumber(double value) { return fmt::format("{:.17g}", value); }

}  // namespace

std::vector<LidarConstraintRecord> ReadLidarConstraints(const std::string& path) {
  CheckFileExists(path, "LiDAR constraints file");
  LineReader reader(path);
  std::vector<LidarConstraintRecord> records;
  Format format = Format::kUnknown;
  std::string line;
  while (reader.Next(&line)) {
    const std::string trimmed = Trim(line);
    if (trimmed.empty() || trimmed[0] == '#') continue;
    const std::vector<std::string> fields = SplitString(trimmed, " \t");
    const int n = static_cast<int>(fields.size());
    RecordParser parser(reader, fields);
    if (format == Format::kUnknown) {
      if (n == kNumFieldsLisfm) {
        format = Format::kLisfm;
      } else if (n == kNumFieldsGtsfm || n == kNumFieldsGtsfmWithCounts) {
        format = Format::kGtsfm;
      } else {
        parser.Fail(fmt::format(
            "expected {} fields (t_i_ns t_j_ns tx ty tz qx qy qz qw + 21 covariance entries) "
            "or {}/{} fields (GTSFM: i j, 3x4 [R|t], 6x6 covariance[, 5x5 counts]), found {}",
            kNumFieldsLisfm, kNumFieldsGtsfm, kNumFieldsGtsfmWithCounts, n));
      }
    }
    if (format == Format::kLisfm) {
      if (n != kNumFieldsLisfm) {
        parser.Fail(fmt::format("expected {} fields like the first record, found {}",
                                kNumFieldsLisfm, n));
      }
      records.push_back(parser.ParseLisfm());
    } else {
      if (n != kNumFieldsGtsfm && n != kNumFieldsGtsfmWithCounts) {
        parser.Fail(fmt::format("expected {} or {} fields (GTSFM format of the first record), "
                                "found {}",
                                kNumFieldsGtsfm, kNumFieldsGtsfmWithCounts, n));
      }
      records.push_back(parser.ParseGtsfm());
    }
  }
  return records;
}

void WriteLidarConstraints(const std::vector<LidarConstraintRecord>& records,
                           const std::string& path) {
  const bool with_stamps = records.empty() || records.front().has_stamps;
  std::ostringstream out;
  if (with_stamps) {
    out << "# lisfm LiDAR constraints: t_i_ns t_j_ns tx ty tz qx qy qz qw + 21 upper-triangular\n"
           "# covariance entries (row-major); T_i_j = i_from_j in the IMU frame (m); covariance\n"
           "# on the right perturbation T = T_hat * Exp(xi), xi = [omega; v] (rad, m)\n";
  }
  for (const LidarConstraintRecord& record : records) {
    THROW_CHECK_MSG(record.has_stamps == with_stamps,
                    "WriteLidarConstraints: records with and without stamps mixed");
    std::vector<std::string> fields;
    if (with_stamps) {
      const Quat& q = record.i_from_j.rotation();
      const Vec3& t = record.i_from_j.translation();
      fields = {std::to_string(record.t_i_ns), std::to_string(record.t_j_ns)};
      for (const double v : {t.x(), t.y(), t.z(), q.x(), q.y(), q.z(), q.w()}) {
        fields.push_back(FormatNumber(v));
      }
      for (int r = 0; r < 6; ++r) {
        for (int c = r; c < 6; ++c) fields.push_back(FormatNumber(record.covariance(r, c)));
      }
    } else {
      fields = {std::to_string(record.index_i), std::to_string(record.index_j)};
      const Eigen::Matrix<double, 3, 4> rt = record.i_from_j.Matrix3x4();
      for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 4; ++c) fields.push_back(FormatNumber(rt(r, c)));
      }
      for (int r = 0; r < 6; ++r) {
        for (int c = 0; c < 6; ++c) fields.push_back(FormatNumber(record.covariance(r, c)));
      }
      fields.insert(fields.end(), 25, "0");
    }
    for (size_t k = 0; k < fields.size(); ++k) out << (k ? " " : "") << fields[k];
    out << '\n';
  }
  WriteFileAtomically(path, out.str());
}

}  // namespace lisfm

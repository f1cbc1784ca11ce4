#include "core/io/keyframe_covariances_io.h"

#include <cmath>
#include <sstream>

#include <Eigen/Eigenvalues>
#include <fmt/format.h>

#include "core/errors.h"
#include "core/file_utils.h"

namespace lisfm {
namespace {

constexpr int kNumFields = 1 + 21;
constexpr double kNegativeEigenvalueTolerance = 1e-9;  // relative to the largest

}  // namespace

std::vector<KeyframeCovariance> ReadKeyframeCovariances(const std::string& path) {
  CheckFileExists(path, "keyframe covariances file");
  LineReader reader(path);
  std::vector<KeyframeCovariance> records;
  std::string line;
  while (reader.Next(&line)) {
    const std::string trimmed = Trim(line);
    if (trimmed.empty() || trimmed[0] == '#') continue;
    const std::vector<std::string> fields = SplitString(trimmed, " \t");
    auto fail = [&](const std::string& message) {
      throw InputError(path, reader.Where(), message);
    };
    if (static_cast<int>(fields.size()) != kNumFields) {
      fail(fmt::format("expected {} fields (t_ns + 21 upper-triangular covariance entries), "
                       "found {}",
                       kNumFields, fields.size()));
    }
    KeyframeCovariance record;
    if (!ParseInt64(fields[0], &record.t_ns)) {
      fail(fmt::format("field 1: expected an integer stamp in ns, found '{}'", fields[0]));
    }
    if (!records.empty() && record.t_ns <= records.back().t_ns) {
      fail(fmt::format("expected a stamp after {}, found {}", records.back().t_ns, record.t_ns));
    }
    size_t k = 1;
    for (int r = 0; r < 6; ++r) {
      for (int c = r; c < 6; ++c, ++k) {
        double value = 0.0;
        if (!ParseDouble(fields[k], &value) || !std::isfinite(value)) {
          fail(fmt::format("field {}: expected a finite number, found '{}'", k + 1, fields[k]));
        }
        record.covariance(r, c) = record.covariance(c, r) = value;
      }
    }
    Eigen::SelfAdjointEigenSolver<Mat6> solver(record.covariance, Eigen::EigenvaluesOnly);
    const double largest = solver.eigenvalues().cwiseAbs().maxCoeff();
    const double smallest = solver.eigenvalues().minCoeff();
    if (solver.info() != Eigen::Success ||
        smallest < -kNegativeEigenvalueTolerance * largest) {
      fail(fmt::format("expected a positive semi-definite covariance, found eigenvalue {:.6g}",
                       smallest));
    }
    records.push_back(record);
  }
  return records;
}

void WriteKeyframeCovariances(const std::vector<KeyframeCovariance>& records,
                              const std::string& path) {
  std::ostringstream out;
  out << "# lisfm keyframe covariances: t_ns + 21 upper-triangular entries (row-major) of the\n"
         "# 6x6 covariance of world_from_imu on the right perturbation T = T_hat * Exp(xi),\n"
         "# xi = [omega; v] (rad, m)\n";
  for (size_t n = 0; n < records.size(); ++n) {
    THROW_CHECK_MSG(n == 0 || records[n].t_ns > records[n - 1].t_ns,
                    "WriteKeyframeCovariances: stamps must strictly increase");
    out << records[n].t_ns;
    for (int r = 0; r < 6; ++r) {
      for (int c = r; c < 6; ++c) out << ' ' << fmt::format("{:.17g}", records[n].covariance(r, c));
    }
    out << '\n';
  }
  WriteFileAtomically(path, out.str());
}

}  // namespace lisfm

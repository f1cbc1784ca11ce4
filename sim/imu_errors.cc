#include "sim/imu_errors.h"

#include <fmt/format.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <sstream>

#include "core/errors.h"
#include "core/file_utils.h"
#include "core/option_check.h"
#include "sim/hash_random.h"

namespace lisfm {
namespace sim {
namespace {

constexpr uint64_t kImuStream = 0x496D754572ULL;        // "ImuEr"
constexpr uint64_t kTemperatureStream = 0x54656D70ULL;  // "Temp"
constexpr double kStandardGravity = 9.80665;            // m/s^2 per g (mg -> m/s^2)

std::mt19937_64 StreamRng(uint64_t seed, uint64_t stream) {
  return std::mt19937_64(Mix64(seed * 0x9E3779B97F4A7C15ULL + stream));
}

ImuTriadErrors DrawTriad(std::mt19937_64* rng,
                         double scale_sigma,
                         double cross_axis_sigma,
                         double temperature_coefficient_sigma) {
  std::normal_distribution<double> normal(0.0, 1.0);
  ImuTriadErrors e;
  for (int i = 0; i < 3; ++i) e.scale[i] = scale_sigma * normal(*rng);
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) {
      if (r != c) e.misalignment(r, c) = cross_axis_sigma * normal(*rng);
    }
  }
  for (int i = 0; i < 3; ++i) {
    e.temperature_coefficient[i] = temperature_coefficient_sigma * normal(*rng);
  }
  return e;
}

std::string Num(double value) { return fmt::format("{}", value == 0.0 ? 0.0 : value); }

std::string VectorText(const Vec3& v) {
  return "[" + Num(v.x()) + ", " + Num(v.y()) + ", " + Num(v.z()) + "]";
}

std::string MatrixText(const Mat3& m) {
  std::string s = "[";
  for (int r = 0; r < 3; ++r) {
    s += (r ? ", " : "") + VectorText(m.row(r).transpose());
  }
  return s + "]";
}

// Reading truth/imu_errors.yaml.
class ImuYaml {
 public:
  explicit ImuYaml(std::string path) : path_(std::move(path)) {}

  YAML::Node Require(const YAML::Node& parent,
                     const std::string& key,
                     const std::string& field) const {
    const YAML::Node child = parent.IsMap() ? parent[key] : YAML::Node();
    if (!child.IsDefined() || child.IsNull()) throw InputError(path_, field, "missing");
    return child;
  }

  double Double(const YAML::Node& node, const std::string& field) const {
    double value = 0.0;
    if (!node.IsScalar() || !ParseDouble(Trim(node.Scalar()), &value) || !std::isfinite(value)) {
      throw InputError(path_, field, "expected a finite number");
    }
    return value;
  }

  std::vector<double> List(const YAML::Node& node, const std::string& field) const {
    if (!node.IsSequence()) throw InputError(path_, field, "expected a list of numbers");
    std::vector<double> values;
    for (size_t i = 0; i < node.size(); ++i) {
      values.push_back(Double(node[i], fmt::format("{}[{}]", field, i)));
    }
    return values;
  }

  Vec3 Vector(const YAML::Node& node, const std::string& field) const {
    const std::vector<double> v = List(node, field);
    if (v.size() != 3) {
      throw InputError(path_, field, fmt::format("expected 3 numbers, found {}", v.size()));
    }
    return Vec3(v[0], v[1], v[2]);
  }

  Mat3 Matrix(const YAML::Node& node, const std::string& field) const {
    if (!node.IsSequence() || node.size() != 3) {
      throw InputError(path_, field, "expected a 3x3 matrix as a list of 3 rows");
    }
    Mat3 m;
    for (int r = 0; r < 3; ++r) m.row(r) = Vector(node[r], fmt::format("{}[{}]", field, r));
    return m;
  }

  ImuTriadErrors Triad(const YAML::Node& root, const std::string& name) const {
    const YAML::Node node = Require(root, name, name);
    ImuTriadErrors e;
    e.scale = Vector(Require(node, "scale", name + ".scale"), name + ".scale");
    e.misalignment =
        Matrix(Require(node, "misalignment", name + ".misalignment"), name + ".misalignment");
    e.temperature_coefficient =
        Vector(Require(node, "temperature_coefficient", name + ".temperature_coefficient"),
               name + ".temperature_coefficient");
    if (e.misalignment.diagonal().cwiseAbs().maxCoeff() != 0.0) {
      throw InputError(path_, name + ".misalignment", "expected a zero diagonal");
    }
    return e;
  }

 private:
  std::string path_;
};

}  // namespace

bool ImuErrorOptions::Check() const {
  CHECK_OPTION_MSG(gyro_scale_sigma_percent,
                   gyro_scale_sigma_percent >= 0 && gyro_scale_sigma_percent <= 10,
                   "in [0, 10] %");
  CHECK_OPTION_MSG(accel_scale_sigma_percent,
                   accel_scale_sigma_percent >= 0 && accel_scale_sigma_percent <= 10,
                   "in [0, 10] %");
  CHECK_OPTION_MSG(gyro_cross_axis_sigma_percent,
                   gyro_cross_axis_sigma_percent >= 0 && gyro_cross_axis_sigma_percent <= 10,
                   "in [0, 10] %");
  CHECK_OPTION_MSG(accel_cross_axis_sigma_percent,
                   accel_cross_axis_sigma_percent >= 0 && accel_cross_axis_sigma_percent <= 10,
                   "in [0, 10] %");
  CHECK_OPTION_MSG(
      gyro_temperature_coefficient_dps_per_k,
      gyro_temperature_coefficient_dps_per_k >= 0 && gyro_temperature_coefficient_dps_per_k <= 1,
      "in [0, 1] deg/s/K");
  CHECK_OPTION_MSG(
      accel_temperature_coefficient_mg_per_k,
      accel_temperature_coefficient_mg_per_k >= 0 && accel_temperature_coefficient_mg_per_k <= 10,
      "in [0, 10] mg/K");
  CHECK_OPTION_MSG(
      temperature_sigma_k, temperature_sigma_k >= 0 && temperature_sigma_k <= 50, "in [0, 50] K");
  CHECK_OPTION_MSG(temperature_time_constant_s,
                   temperature_time_constant_s >= 1 && temperature_time_constant_s <= 1e5,
                   "in [1, 1e5] s");
  return true;
}

TemperatureDrift::TemperatureDrift(
    double sigma_k, double time_constant_s, TimestampNs start_ns, TimestampNs end_ns, uint64_t seed)
    : sigma_k_(sigma_k), time_constant_s_(time_constant_s), start_ns_(start_ns) {
  THROW_CHECK_GE(sigma_k, 0.0);
  THROW_CHECK_GT(time_constant_s, 0.0);
  THROW_CHECK_GE(end_ns, start_ns);
  const int64_t count = (end_ns - start_ns + kPeriodNs - 1) / kPeriodNs + 1;
  // State s = (x1, x2), dT = x2: dx1 = -x1/tau dt + sqrt(q) dW, dx2 = (x1 - x2)/tau dt,
  // q = 4 sigma^2 / tau. Stationary covariance P = sigma^2 [[2, 1], [1, 1]].
  // Over one step h: s' = F s + w, F = exp(-a) [[1, 0], [a, 1]], a = h / tau,
  // w ~ N(0, Q), Q = P - F P F^T (exact for a stationary linear system).
  const long double a = static_cast<long double>(NsToSeconds(kPeriodNs)) / time_constant_s;
  const long double e2 = std::exp(-2 * a);
  const long double q11 = 2 - 2 * e2;
  const long double q12 = 1 - e2 * (1 + 2 * a);
  const long double q22 = 1 - e2 * (1 + 2 * a + 2 * a * a);
  const double l11 = static_cast<double>(std::sqrt(q11));
  const double l21 = static_cast<double>(q12 / std::sqrt(q11));
  const double l22 =
      static_cast<double>(std::sqrt(std::max<long double>(0, q22 - q12 * q12 / q11)));
  const double f = static_cast<double>(std::exp(-a)), fa = static_cast<double>(std::exp(-a) * a);
  std::mt19937_64 rng(Mix64(seed * 0x9E3779B97F4A7C15ULL + kTemperatureStream));
  std::normal_distribution<double> normal(0.0, 1.0);
  // First state from P: chol(P) = sigma [[sqrt 2, 0], [1/sqrt 2, 1/sqrt 2]].
  const double z1 = normal(rng), z2 = normal(rng);
  double x1 = sigma_k * std::sqrt(2.0) * z1;
  double x2 = sigma_k * (z1 + z2) / std::sqrt(2.0);
  samples_k_.reserve(static_cast<size_t>(count));
  samples_k_.push_back(x2);
  for (int64_t i = 1; i < count; ++i) {
    const double w1 = normal(rng), w2 = normal(rng);
    const double n1 = sigma_k * l11 * w1;
    const double n2 = sigma_k * (l21 * w1 + l22 * w2);
    const double y1 = f * x1 + n1;
    const double y2 = fa * x1 + f * x2 + n2;
    x1 = y1;
    x2 = y2;
    samples_k_.push_back(x2);
  }
}

TemperatureDrift::TemperatureDrift(double sigma_k,
                                   double time_constant_s,
                                   TimestampNs start_ns,
                                   std::vector<double> samples_k)
    : sigma_k_(sigma_k),
      time_constant_s_(time_constant_s),
      start_ns_(start_ns),
      samples_k_(std::move(samples_k)) {}

double TemperatureDrift::At(TimestampNs t_ns) const {
  if (samples_k_.empty()) return 0.0;
  if (t_ns <= start_ns_) return samples_k_.front();
  const int64_t i = (t_ns - start_ns_) / kPeriodNs;
  if (i + 1 >= static_cast<int64_t>(samples_k_.size())) return samples_k_.back();
  const double u =
      static_cast<double>((t_ns - start_ns_) - i * kPeriodNs) / static_cast<double>(kPeriodNs);
  return (1.0 - u) * samples_k_[i] + u * samples_k_[i + 1];
}

Mat3 ImuTriadErrors::Matrix() const {
  return (Vec3::Ones() + scale).asDiagonal() * (Mat3::Identity() + misalignment);
}

ImuErrors DrawImuErrors(const ImuErrorOptions& options,
                        double noise_scale,
                        uint64_t seed,
                        TimestampNs start_ns,
                        TimestampNs end_ns) {
  THROW_CHECK_OPTIONS(options);
  THROW_CHECK_GE(noise_scale, 0.0);
  const double k = noise_scale;
  std::mt19937_64 rng = StreamRng(seed, kImuStream);
  ImuErrors errors;
  errors.gyro = DrawTriad(&rng,
                          k * options.gyro_scale_sigma_percent / 100,
                          k * options.gyro_cross_axis_sigma_percent / 100,
                          k * options.gyro_temperature_coefficient_dps_per_k * M_PI / 180);
  errors.accel =
      DrawTriad(&rng,
                k * options.accel_scale_sigma_percent / 100,
                k * options.accel_cross_axis_sigma_percent / 100,
                k * options.accel_temperature_coefficient_mg_per_k * 1e-3 * kStandardGravity);
  errors.temperature = TemperatureDrift(
      options.temperature_sigma_k, options.temperature_time_constant_s, start_ns, end_ns, seed);
  return errors;
}

void WriteImuErrorsYaml(const std::string& path, const ImuErrors& errors) {
  std::ostringstream out;
  out << "# lisfm simulate: the true IMU errors of this recording (error source `imu`).\n"
         "# Per triad, IMU frame, at time t (sim/imu_errors.h):\n"
         "#   measured = matrix * true + b_rw(t) + temperature_coefficient * dT(t) + noise,\n"
         "#   matrix = diag(1 + scale) * (I + misalignment).\n"
         "# imu0/bias_groundtruth.csv holds b_rw(t) + temperature_coefficient * dT(t) per "
         "sample.\n"
         "# temperature_coefficient: gyro rad/s/K, accel m/s^2/K. dT(t) in K: samples_k at\n"
         "# start_ns + i * period_s, linear in between (the end samples outside); a stationary\n"
         "# process with autocorrelation sigma_k^2 (1 + |l|/tau) exp(-|l|/tau), tau = "
         "time_constant_s.\n";
  for (const auto& [name, triad] :
       {std::pair<const char*, const ImuTriadErrors*>{"gyro", &errors.gyro},
        std::pair<const char*, const ImuTriadErrors*>{"accel", &errors.accel}}) {
    out << name << ":\n"
        << "  scale: " << VectorText(triad->scale) << "\n"
        << "  misalignment: " << MatrixText(triad->misalignment) << "\n"
        << "  matrix: " << MatrixText(triad->Matrix()) << "\n"
        << "  temperature_coefficient: " << VectorText(triad->temperature_coefficient) << "\n";
  }
  const TemperatureDrift& t = errors.temperature;
  out << "temperature:\n"
      << "  sigma_k: " << Num(t.sigma_k()) << "\n"
      << "  time_constant_s: " << Num(t.time_constant_s()) << "\n"
      << "  start_ns: " << t.start_ns() << "\n"
      << "  period_s: " << Num(NsToSeconds(TemperatureDrift::kPeriodNs)) << "\n"
      << "  samples_k: [";
  for (size_t i = 0; i < t.samples_k().size(); ++i) {
    out << (i ? ", " : "") << Num(t.samples_k()[i]);
  }
  out << "]\n";
  WriteFileAtomically(path, out.str());
}

ImuErrors ReadImuErrorsYaml(const std::string& path) {
  CheckFileExists(path, "IMU errors YAML");
  YAML::Node root;
  try {
    root = YAML::Load(ReadFile(path));
  } catch (const YAML::ParserException& e) {
    throw InputError(path, fmt::format("line {}", e.mark.line + 1), "malformed YAML: " + e.msg);
  }
  const ImuYaml src(path);
  if (!root.IsMap()) throw InputError(path, "gyro", "expected a map with gyro, accel, temperature");
  ImuErrors errors;
  errors.gyro = src.Triad(root, "gyro");
  errors.accel = src.Triad(root, "accel");
  const YAML::Node t = src.Require(root, "temperature", "temperature");
  const double period =
      src.Double(src.Require(t, "period_s", "temperature.period_s"), "temperature.period_s");
  if (period != NsToSeconds(TemperatureDrift::kPeriodNs)) {
    throw InputError(path, "temperature.period_s", "expected 1");
  }
  const YAML::Node start = src.Require(t, "start_ns", "temperature.start_ns");
  int64_t start_ns = 0;
  if (!start.IsScalar() || !ParseInt64(Trim(start.Scalar()), &start_ns)) {
    throw InputError(path, "temperature.start_ns", "expected an integer (ns)");
  }
  errors.temperature = TemperatureDrift(
      src.Double(src.Require(t, "sigma_k", "temperature.sigma_k"), "temperature.sigma_k"),
      src.Double(src.Require(t, "time_constant_s", "temperature.time_constant_s"),
                 "temperature.time_constant_s"),
      start_ns,
      src.List(src.Require(t, "samples_k", "temperature.samples_k"), "temperature.samples_k"));
  return errors;
}

}  // namespace sim
}  // namespace lisfm

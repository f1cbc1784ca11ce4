#include "core/io/trajectory_io.h"

#include <fmt/format.h>

#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>

#include "core/errors.h"
#include "core/file_utils.h"

namespace lisfm {

namespace {

constexpr double kQuaternionNormTolerance = 1e-3;

// Shortest "%.Ng" text (N >= 9) that reads back to exactly `v`.
std::string FormatValue(double v) {
  char buf[64];
  for (int precision = 9; precision <= 17; ++precision) {
    std::snprintf(buf, sizeof(buf), "%.*g", precision, v);
    if (std::strtod(buf, nullptr) == v) break;
  }
  return buf;
}

bool IsSkippable(const std::string& line) {
  const std::string t = Trim(line);
  return t.empty() || t[0] == '#';
}

// Tracks the previous stamp and its line to report non-increasing times.
class StampOrder {
 public:
  void Check(const LineReader& reader, TimestampNs t_ns) {
    if (has_previous_ && t_ns <= previous_ns_) {
      throw InputError(
          reader.path(),
          reader.Where(),
          fmt::format("timestamps must be strictly increasing: expected a time "
                      "after {} s (line {}), found {} s",
                      FormatNsAsSeconds(previous_ns_),
                      previous_line_,
                      FormatNsAsSeconds(t_ns)));
    }
    has_previous_ = true;
    previous_ns_ = t_ns;
    previous_line_ = reader.line_number();
  }

 private:
  bool has_previous_ = false;
  TimestampNs previous_ns_ = 0;
  int previous_line_ = 0;
};

TimestampNs ParseSecondsField(const LineReader& reader,
                              const std::string& token,
                              const std::string& layout) {
  TimestampNs t_ns = 0;
  if (!ParseSecondsToNs(token, &t_ns)) {
    double seconds = 0;  // a number ParseSecondsToNs rejects is out of range
    const bool out_of_range = ParseDouble(token, &seconds);
    throw InputError(
        reader.path(),
        reader.Where(),
        out_of_range
            ? fmt::format("expected a time in seconds within +-{:.0f} s (int64 "
                          "nanoseconds) in column 1 of '{}', found '{}'",
                          kMaxAbsSecondsAsNs,
                          layout,
                          token)
            : "expected a time in seconds in column 1 of '" + layout +
                  "', found '" + token + "'");
  }
  return t_ns;
}

double ParseNumberField(const LineReader& reader,
                        const std::vector<std::string>& tokens,
                        size_t column,
                        const std::string& layout) {
  const std::string token = Trim(tokens[column]);
  double v = 0;
  if (!ParseDouble(token, &v)) {
    throw InputError(
        reader.path(),
        reader.Where(),
        fmt::format("expected a number in column {} of '{}', found '{}'",
                    column + 1,
                    layout,
                    token));
  }
  return v;
}

// Checks the quaternion is within kQuaternionNormTolerance of unit norm.
Quat MakeUnitQuaternion(
    const LineReader& reader, double w, double x, double y, double z) {
  Quat q(w, x, y, z);
  const double norm = q.norm();
  if (!(std::abs(norm - 1.0) <= kQuaternionNormTolerance)) {
    throw InputError(
        reader.path(),
        reader.Where(),
        fmt::format(
            "expected a unit quaternion (norm within {} of 1), found norm {}",
            kQuaternionNormTolerance,
            norm));
  }
  q.normalize();
  return q;
}

void CheckNotEmpty(const std::string& path,
                   size_t count,
                   const std::string& what) {
  if (count == 0)
    throw InputError(path, "", "no " + what + " found (empty file)");
}

std::string Lowercase(std::string s) {
  for (char& c : s)
    c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

}  // namespace

Trajectory ReadTum(const std::string& path) {
  static const std::string kLayout = "t x y z qx qy qz qw";
  LineReader reader(path);
  std::vector<StampedPose> poses;
  StampOrder order;
  std::string line;
  while (reader.Next(&line)) {
    if (IsSkippable(line)) continue;
    const std::vector<std::string> tokens = SplitString(line, " \t");
    if (tokens.size() != 8) {
      throw InputError(
          path,
          reader.Where(),
          fmt::format(
              "expected 8 columns '{}', found {}", kLayout, tokens.size()));
    }
    StampedPose pose;
    pose.t_ns = ParseSecondsField(reader, tokens[0], kLayout);
    double v[7];
    for (size_t c = 1; c < 8; ++c)
      v[c - 1] = ParseNumberField(reader, tokens, c, kLayout);
    order.Check(reader, pose.t_ns);
    pose.pose = SE3(MakeUnitQuaternion(reader, v[6], v[3], v[4], v[5]),
                    Vec3(v[0], v[1], v[2]));
    poses.push_back(pose);
  }
  CheckNotEmpty(path, poses.size(), "poses");
  return Trajectory(std::move(poses));
}

void WriteTum(const std::string& path, const Trajectory& trajectory) {
  AtomicOutputFile out(path);
  out.stream() << "# t x y z qx qy qz qw  (t in s, world_from_body)\n";
  for (const auto& p : trajectory.poses()) {
    const Vec3& t = p.pose.translation();
    const Quat& q = p.pose.rotation();
    out.stream() << FormatNsAsSeconds(p.t_ns) << ' ' << FormatValue(t.x())
                 << ' ' << FormatValue(t.y()) << ' ' << FormatValue(t.z())
                 << ' ' << FormatValue(q.x()) << ' ' << FormatValue(q.y())
                 << ' ' << FormatValue(q.z()) << ' ' << FormatValue(q.w())
                 << '\n';
  }
  out.Commit();
}

Trajectory ReadEurocCsv(const std::string& path) {
  static const std::string kLayout = "t_ns,x,y,z,qw,qx,qy,qz[,...]";
  LineReader reader(path);
  std::vector<StampedPose> poses;
  StampOrder order;
  std::string line;
  while (reader.Next(&line)) {
    if (IsSkippable(line)) continue;
    const std::vector<std::string> tokens =
        SplitString(line, ",", /*skip_empty=*/false);
    if (tokens.size() < 8) {
      throw InputError(
          path,
          reader.Where(),
          fmt::format(
              "expected at least 8 comma-separated columns '{}', found {}",
              kLayout,
              tokens.size()));
    }
    StampedPose pose;
    const std::string stamp = Trim(tokens[0]);
    if (!ParseInt64(stamp, &pose.t_ns)) {
      throw InputError(path,
                       reader.Where(),
                       "expected an integer time in ns in column 1 of '" +
                           kLayout + "', found '" + stamp + "'");
    }
    double v[7];
    for (size_t c = 1; c < 8; ++c)
      v[c - 1] = ParseNumberField(reader, tokens, c, kLayout);
    order.Check(reader, pose.t_ns);
    pose.pose = SE3(MakeUnitQuaternion(reader, v[3], v[4], v[5], v[6]),
                    Vec3(v[0], v[1], v[2]));
    poses.push_back(pose);
  }
  CheckNotEmpty(path, poses.size(), "poses");
  return Trajectory(std::move(poses));
}

void WriteEurocCsv(const std::string& path, const Trajectory& trajectory) {
  AtomicOutputFile out(path);
  out.stream() << "#timestamp [ns],p_RS_R_x [m],p_RS_R_y [m],p_RS_R_z [m],"
                  "q_RS_w [],q_RS_x [],q_RS_y [],q_RS_z []\n";
  for (const auto& p : trajectory.poses()) {
    const Vec3& t = p.pose.translation();
    const Quat& q = p.pose.rotation();
    out.stream() << p.t_ns << ',' << FormatValue(t.x()) << ','
                 << FormatValue(t.y()) << ',' << FormatValue(t.z()) << ','
                 << FormatValue(q.w()) << ',' << FormatValue(q.x()) << ','
                 << FormatValue(q.y()) << ',' << FormatValue(q.z()) << '\n';
  }
  out.Commit();
}

Trajectory ReadTrajectory(const std::string& path) {
  CheckFileExists(path, "trajectory file");
  const std::string ext =
      Lowercase(std::filesystem::path(path).extension().string());
  if (ext == ".csv") return ReadEurocCsv(path);
  if (ext == ".txt" || ext == ".tum") return ReadTum(path);
  LineReader reader(path);
  std::string line;
  while (reader.Next(&line)) {
    if (IsSkippable(line)) continue;
    return line.find(',') != std::string::npos ? ReadEurocCsv(path)
                                               : ReadTum(path);
  }
  CheckNotEmpty(path, 0, "poses");
  return Trajectory();
}

std::vector<ControlPoint> ReadControlPoints(const std::string& path) {
  static const std::string kLayout8 = "t x y z qx qy qz qw";
  static const std::string kLayout5 = "t id x y z";
  static const std::string kLayout4 = "t x y z";
  LineReader reader(path);
  std::vector<ControlPoint> points;
  StampOrder order;
  std::string line;
  while (reader.Next(&line)) {
    if (IsSkippable(line)) continue;
    const std::vector<std::string> tokens = SplitString(line, " \t");
    ControlPoint p;
    size_t first_xyz = 1;
    const std::string* layout = &kLayout4;
    if (tokens.size() == 8) {
      layout = &kLayout8;
    } else if (tokens.size() == 5) {
      layout = &kLayout5;
      first_xyz = 2;
      p.id = tokens[1];
    } else if (tokens.size() != 4) {
      throw InputError(
          path,
          reader.Where(),
          fmt::format(
              "expected a control point '{}' or '{}' (8 or 4 columns) or "
              "'{}' (5 columns), found {} columns",
              kLayout8,
              kLayout4,
              kLayout5,
              tokens.size()));
    }
    p.t_ns = ParseSecondsField(reader, tokens[0], *layout);
    for (size_t c = 0; c < 3; ++c) {
      p.position[static_cast<Eigen::Index>(c)] =
          ParseNumberField(reader, tokens, first_xyz + c, *layout);
    }
    // The orientation columns carry no information but must still be numbers.
    for (size_t c = 4; c < tokens.size() && layout == &kLayout8; ++c) {
      ParseNumberField(reader, tokens, c, *layout);
    }
    order.Check(reader, p.t_ns);
    points.push_back(p);
  }
  CheckNotEmpty(path, points.size(), "control points");
  return points;
}

}  // namespace lisfm

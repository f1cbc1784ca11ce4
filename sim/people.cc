#include "sim/people.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>

#include "core/errors.h"
#include "core/option_check.h"
#include "sim/scene.h"

namespace lisfm {
namespace sim {
namespace {

constexpr float kInfinity = std::numeric_limits<float>::infinity();

// Body geometry in the person frame (x forward, y left, z up), metres.
constexpr float kHeadZ = 1.62f, kHeadRadius = 0.11f;
constexpr float kTorsoY = 0.08f, kTorsoZ0 = 1.0f, kTorsoZ1 = 1.38f, kTorsoRadius = 0.13f;
constexpr float kShoulderY = 0.24f, kShoulderZ = 1.42f, kArmLength = 0.6f, kArmRadius = 0.05f;
constexpr float kHipY = 0.1f, kHipZ = 0.9f, kLegLength = 0.88f, kLegRadius = 0.075f;
constexpr float kLegSwing = 0.35f, kArmSwing = 0.3f;  // rad
constexpr double kStrideM = 1.45;
constexpr float kBoundZ = 0.88f;

// Path sampling and the people's lateral placement (GeneratePeople).
constexpr double kPathSpacing = 0.1;     // m
constexpr double kKeepRightM = 0.8;      // nominal offset from the route's centre line
constexpr double kBodyClearance = 0.35;  // m from walls and obstacles
constexpr int kWindow = 5;               // +-0.5 m of path (samples)

// Entry distance (> 0) of the unit ray into the sphere (centre c, radius r),
// or +inf (a miss, or the origin inside).
inline float RaySphere(const Eigen::Vector3f& o,
                       const Eigen::Vector3f& d,
                       const Eigen::Vector3f& c,
                       float r) {
  const Eigen::Vector3f oc = c - o;
  const float b = oc.dot(d);
  const float q = oc.squaredNorm() - r * r;
  if (q <= 0.f) return kInfinity;
  const float disc = b * b - q;
  if (b <= 0.f || disc < 0.f) return kInfinity;
  return b - std::sqrt(disc);
}

}  // namespace

bool DynamicsOptions::Check() const {
  CHECK_OPTION_MSG(people_per_100m, people_per_100m >= 0 && people_per_100m <= 100, "in [0, 100]");
  CHECK_OPTION_MSG(speed, speed > 0 && speed <= 3, "in (0, 3] m/s");
  return true;
}

float IntersectBodyPart(const BodyPart& part,
                        const Eigen::Vector3f& origin,
                        const Eigen::Vector3f& direction,
                        Eigen::Vector3f* normal) {
  // A capsule is the union of a finite cylinder and two end spheres; the ray
  // enters it where it first enters one of them (origin outside all three).
  const Eigen::Vector3f ba = part.b - part.a;
  const float r = part.radius;
  const float ta = RaySphere(origin, direction, part.a, r);
  const float tb = RaySphere(origin, direction, part.b, r);
  float best = std::min(ta, tb);
  Eigen::Vector3f centre = ta <= tb ? part.a : part.b;  // closest axis point of the hit
  const float baba = ba.squaredNorm();
  if (baba > 1e-12f) {
    // Points p = o + t d with |(p - a) x ba|^2 = r^2 |ba|^2 and 0 < (p - a).ba < |ba|^2.
    const Eigen::Vector3f oa = origin - part.a;
    const float bard = ba.dot(direction), baoa = ba.dot(oa);
    const float a = baba - bard * bard;
    if (a > 1e-9f * baba) {
      const float b = baba * direction.dot(oa) - baoa * bard;
      const float c = baba * oa.squaredNorm() - baoa * baoa - r * r * baba;
      const float disc = b * b - a * c;
      if (c > 0.f && disc >= 0.f) {
        const float t = (-b - std::sqrt(disc)) / a;
        const float y = baoa + t * bard;
        if (t > 0.f && y > 0.f && y < baba && t < best) {
          best = t;
          centre = part.a + ba * (y / baba);
        }
      }
    }
  }
  if (best < kInfinity && normal != nullptr) {
    *normal = (origin + best * direction - centre).normalized();
  }
  return best;
}

WalkingPerson::WalkingPerson(
    std::vector<Vec3> path, double spacing_m, double start_m, double speed, TimestampNs start_ns)
    : path_(std::move(path)),
      spacing_(spacing_m),
      start_m_(start_m),
      speed_(speed),
      start_ns_(start_ns) {
  THROW_CHECK_GE(path_.size(), 3u);
  THROW_CHECK_GT(spacing_, 0.0);
}

double WalkingPerson::ArcAt(TimestampNs t_ns) const {
  const double length = path_length_m();
  const double s = start_m_ + speed_ * NsToSeconds(t_ns - start_ns_);
  double arc = std::fmod(s, length);
  if (arc < 0) arc += length;
  return arc >= length ? 0.0 : arc;
}

void WalkingPerson::Locate(TimestampNs t_ns, Vec3* feet, double* yaw) const {
  const int n = static_cast<int>(path_.size());
  const double f = ArcAt(t_ns) / spacing_;
  const int i0 = std::min(static_cast<int>(f), n - 1);
  const double w = f - i0;
  auto at = [&](int i) -> const Vec3& { return path_[((i % n) + n) % n]; };
  *feet = at(i0) + (at(i0 + 1) - at(i0)) * w;
  if (yaw == nullptr) return;
  // Heading: central differences over +-0.3 m, blended between the samples.
  constexpr int k = 3;
  const Vec3 t0 = at(i0 + k) - at(i0 - k), t1 = at(i0 + 1 + k) - at(i0 + 1 - k);
  const Vec3 tangent = t0 * (1 - w) + t1 * w;
  *yaw = std::atan2(tangent.y(), tangent.x()) + (speed_ < 0 ? M_PI : 0.0);
}

Eigen::Vector3f WalkingPerson::BoundCentre(TimestampNs t_ns) const {
  Vec3 feet;
  Locate(t_ns, &feet, nullptr);
  return feet.cast<float>() + Eigen::Vector3f(0, 0, kBoundZ);
}

PersonPose WalkingPerson::Pose(TimestampNs t_ns) const {
  Vec3 feet_d;
  double yaw_d;
  Locate(t_ns, &feet_d, &yaw_d);
  const Eigen::Vector3f feet = feet_d.cast<float>();
  const float c = static_cast<float>(std::cos(yaw_d)), s = static_cast<float>(std::sin(yaw_d));
  // Person frame -> scene frame: rotation about z by the heading.
  auto world = [&](float x, float y, float z) {
    return Eigen::Vector3f(feet.x() + c * x - s * y, feet.y() + s * x + c * y, feet.z() + z);
  };
  const double walked = std::fabs(speed_) * NsToSeconds(t_ns - start_ns_);
  const float phase = static_cast<float>(2 * M_PI * std::fmod(walked / kStrideM, 1.0));
  const float leg = kLegSwing * std::sin(phase), arm = -kArmSwing * std::sin(phase);
  PersonPose pose;
  pose.centre = world(0, 0, kBoundZ);
  pose.radius = 1.0f;
  pose.parts[0] = {world(0, 0, kHeadZ), world(0, 0, kHeadZ), kHeadRadius, 0};
  pose.parts[1] = {world(0, kTorsoY, kTorsoZ0), world(0, kTorsoY, kTorsoZ1), kTorsoRadius, 1};
  pose.parts[2] = {world(0, -kTorsoY, kTorsoZ0), world(0, -kTorsoY, kTorsoZ1), kTorsoRadius, 1};
  for (int side = 0; side < 2; ++side) {
    const float sign = side == 0 ? 1.f : -1.f;  // left, right
    // Left leg forward with the right arm, and vice versa.
    const float leg_angle = sign * leg, arm_angle = sign * arm;
    pose.parts[3 + side] = {world(0, sign * kShoulderY, kShoulderZ),
                            world(kArmLength * std::sin(arm_angle),
                                  sign * kShoulderY,
                                  kShoulderZ - kArmLength * std::cos(arm_angle)),
                            kArmRadius,
                            2};
    pose.parts[5 + side] = {world(0, sign * kHipY, kHipZ),
                            world(kLegLength * std::sin(leg_angle),
                                  sign * kHipY,
                                  kHipZ - kLegLength * std::cos(leg_angle)),
                            kLegRadius,
                            3};
  }
  return pose;
}

namespace {

// One cycle of the route (closed: the loop; open: out and back) sampled every
// kPathSpacing of arc; the last sample is not repeated.
std::vector<Vec3> RouteCycle(const WalkingRoute& route) {
  std::vector<Vec3> corners = route.waypoints;
  if (!route.closed) {
    for (int i = static_cast<int>(route.waypoints.size()) - 2; i > 0; --i) {
      corners.push_back(route.waypoints[i]);
    }
  }
  const size_t n = corners.size();
  std::vector<double> arc = {0.0};
  for (size_t i = 0; i < n; ++i)
    arc.push_back(arc.back() + (corners[(i + 1) % n] - corners[i]).norm());
  std::vector<Vec3> out;
  size_t seg = 0;
  for (double s = 0; s < arc.back() - 1e-9; s += kPathSpacing) {
    while (seg + 1 < n && arc[seg + 1] <= s) ++seg;
    const double len = std::max(1e-12, arc[seg + 1] - arc[seg]);
    out.push_back(corners[seg] + (corners[(seg + 1) % n] - corners[seg]) * ((s - arc[seg]) / len));
  }
  return out;
}

}  // namespace

std::vector<WalkingPerson> GeneratePeople(const Scene& scene,
                                          const WalkingRoute& route,
                                          const DynamicsOptions& options,
                                          TimestampNs start_ns,
                                          uint32_t seed) {
  THROW_CHECK_OPTIONS(options);
  std::vector<WalkingPerson> people;
  if (route.waypoints.size() < 2 || options.people_per_100m <= 0) return people;
  std::vector<Vec3> centre = RouteCycle(route);
  const int n = static_cast<int>(centre.size());
  if (n < 4 * kWindow) return people;
  for (Vec3& p : centre) p.z() -= kRouteDeviceHeight;  // feet
  const double cycle = kPathSpacing * n;
  const int count =
      std::max(1, static_cast<int>(std::lround(options.people_per_100m * cycle / 100.0)));
  auto at = [&](const std::vector<Vec3>& v, int i) -> const Vec3& { return v[((i % n) + n) % n]; };
  // Horizontal left normal of the centre line.
  std::vector<Vec3> left(n);
  for (int i = 0; i < n; ++i) {
    Vec3 t = at(centre, i + 2) - at(centre, i - 2);
    t.z() = 0;
    left[i] = t.norm() > 1e-9 ? Vec3(-t.y(), t.x(), 0).normalized() : Vec3::UnitY();
  }
  // Offset from the centre line, keeping right, for each direction of travel
  // (+1: along the route, -1: against it): the free space beside the centre
  // line less the body clearance, at most kKeepRightM; the narrowest within
  // +-0.5 m (door jambs, posts between samples), then smoothed (never wider).
  auto offsets = [&](double direction) {
    std::vector<double> offset(n), narrow(n), smooth(n);
    for (int i = 0; i < n; ++i) {
      const Vec3 side = -direction * left[i];
      double free = kKeepRightM + kBodyClearance;
      for (double z = 0.1; z < 1.85; z += 0.1) {  // every 0.1 m from ankle to head height
        const RayHit hit = scene.Intersect(centre[i] + Vec3(0, 0, z), side, 0.0, free);
        if (hit.hit) free = std::min(free, static_cast<double>(hit.distance));
      }
      offset[i] = std::clamp(free - kBodyClearance, 0.0, kKeepRightM);
    }
    for (int i = 0; i < n; ++i) {
      double m = offset[i];
      for (int k = -kWindow; k <= kWindow; ++k) m = std::min(m, offset[((i + k) % n + n) % n]);
      narrow[i] = m;
    }
    for (int i = 0; i < n; ++i) {
      double sum = 0;
      for (int k = -kWindow; k <= kWindow; ++k) sum += narrow[((i + k) % n + n) % n];
      smooth[i] = std::min(narrow[i], sum / (2 * kWindow + 1));
    }
    return smooth;
  };
  const std::vector<double> along = offsets(1.0), against = offsets(-1.0);
  std::mt19937 rng(seed * 2246822519u + 0x5bd1e995u);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  for (int p = 0; p < count; ++p) {
    const double direction = p % 2 == 0 ? 1.0 : -1.0;
    const double speed = direction * options.speed * (0.85 + 0.3 * uniform(rng));
    const double start_m =
        std::min(cycle, 5.0) + std::max(0.0, cycle - 10.0) * (p + 0.5 * uniform(rng)) / count;
    const std::vector<double>& offset = direction > 0 ? along : against;
    std::vector<Vec3> path(n);
    for (int i = 0; i < n; ++i) path[i] = centre[i] - direction * offset[i] * left[i];
    // Rounded corners: moving average over +-0.5 m.
    std::vector<Vec3> rounded(n);
    for (int i = 0; i < n; ++i) {
      Vec3 sum = Vec3::Zero();
      for (int k = -kWindow; k <= kWindow; ++k) sum += at(path, i + k);
      rounded[i] = sum / (2 * kWindow + 1);
    }
    people.emplace_back(std::move(rounded), kPathSpacing, start_m, speed, start_ns);
  }
  return people;
}

}  // namespace sim
}  // namespace lisfm

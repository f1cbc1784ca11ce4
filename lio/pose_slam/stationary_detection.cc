#include "lio/pose_slam/stationary_detection.h"

#include <algorithm>
#include <cmath>

#include "core/errors.h"
#include "core/geometry.h"
#include "core/option_check.h"

namespace lisfm {

namespace {

// Fewest samples a test window needs (a shorter one says nothing about noise).
constexpr int kMinWindowSamples = 10;

// Prefix sums of x and |x|^2 (x shifted by a reference to keep the sums of
// squares small), for the mean and scatter of any run of samples.
class PrefixMoments {
 public:
  PrefixMoments(const std::vector<ImuSample>& samples, bool gyro) {
    const size_t n = samples.size();
    reference_ = gyro ? samples[n / 2].gyro : samples[n / 2].accel;
    sum_.assign(n + 1, Vec3::Zero());
    sum_squares_.assign(n + 1, 0.0);
    for (size_t k = 0; k < n; ++k) {
      const Vec3 x = (gyro ? samples[k].gyro : samples[k].accel) - reference_;
      sum_[k + 1] = sum_[k] + x;
      sum_squares_[k + 1] = sum_squares_[k] + x.squaredNorm();
    }
  }

  // Mean of samples [begin, end).
  Vec3 Mean(size_t begin, size_t end) const {
    return (sum_[end] - sum_[begin]) / static_cast<double>(end - begin) + reference_;
  }

  // sqrt(trace of the covariance) of samples [begin, end).
  double Scatter(size_t begin, size_t end) const {
    const double n = static_cast<double>(end - begin);
    const Vec3 mean = (sum_[end] - sum_[begin]) / n;
    const double variance = (sum_squares_[end] - sum_squares_[begin]) / n - mean.squaredNorm();
    return std::sqrt(std::max(0.0, variance));
  }

 private:
  Vec3 reference_;
  std::vector<Vec3> sum_;
  std::vector<double> sum_squares_;
};

// Merges sorted closed intervals that overlap into disjoint ones.
std::vector<StationaryPeriod> Merge(const std::vector<StationaryPeriod>& sorted) {
  std::vector<StationaryPeriod> merged;
  for (const StationaryPeriod& p : sorted) {
    if (!merged.empty() && p.start_ns <= merged.back().end_ns) {
      merged.back().end_ns = std::max(merged.back().end_ns, p.end_ns);
    } else {
      merged.push_back(p);
    }
  }
  return merged;
}

// The periods of at least min_duration_ns.
std::vector<StationaryPeriod> KeepLong(const std::vector<StationaryPeriod>& periods,
                                       TimestampNs min_duration_ns) {
  std::vector<StationaryPeriod> out;
  for (const StationaryPeriod& p : periods) {
    if (p.end_ns - p.start_ns >= min_duration_ns) out.push_back(p);
  }
  return out;
}

}  // namespace

bool StationaryDetectionOptions::Check() const {
  CHECK_OPTION_GT(window_s, 0.0);
  CHECK_OPTION_GT(max_gyro_std, 0.0);
  CHECK_OPTION_GT(max_accel_std, 0.0);
  CHECK_OPTION_GT(max_gyro_mean, 0.0);
  CHECK_OPTION_GE(min_duration_s, 0.0);
  return true;
}

std::vector<StationaryPeriod> DetectStationaryPeriods(const std::vector<ImuSample>& samples,
                                                      const StationaryDetectionOptions& options) {
  THROW_CHECK_OPTIONS(options);
  if (samples.size() < static_cast<size_t>(kMinWindowSamples)) return {};
  const PrefixMoments gyro(samples, true), accel(samples, false);
  const TimestampNs window_ns = SecondsToNs(options.window_s);
  // Every window [t_begin, t_begin + window] that starts at a sample and
  // passes the test; their union is the stationary time.
  std::vector<StationaryPeriod> passing;
  size_t end = 0;  // one past the last sample of the window
  for (size_t begin = 0; begin < samples.size(); ++begin) {
    end = std::max(end, begin + 1);
    while (end < samples.size() && samples[end].t_ns - samples[begin].t_ns <= window_ns) ++end;
    if (samples[end - 1].t_ns - samples[begin].t_ns < window_ns / 2) continue;  // data ends
    if (end - begin < static_cast<size_t>(kMinWindowSamples)) continue;
    if (gyro.Scatter(begin, end) > options.max_gyro_std) continue;
    if (accel.Scatter(begin, end) > options.max_accel_std) continue;
    if (gyro.Mean(begin, end).norm() > options.max_gyro_mean) continue;
    passing.push_back({samples[begin].t_ns, samples[end - 1].t_ns});
  }
  // A window that passes may still hold the first or last instants of a gentle
  // motion (a walk ramps up from rest): only the centre halves of the passing
  // windows count, except at the ends of the data.
  std::vector<StationaryPeriod> periods = Merge(passing);
  for (StationaryPeriod& p : periods) {
    if (p.start_ns > samples.front().t_ns) p.start_ns += window_ns / 2;
    if (p.end_ns < samples.back().t_ns) p.end_ns -= window_ns / 2;
  }
  return KeepLong(periods, SecondsToNs(options.min_duration_s));
}

std::vector<StationaryPeriod> DetectStationaryPeriodsFromPoses(const Trajectory& trajectory,
                                                               double max_speed,
                                                               double max_angular_rate,
                                                               double min_duration_s) {
  THROW_CHECK_GT(max_speed, 0.0);
  THROW_CHECK_GT(max_angular_rate, 0.0);
  std::vector<StationaryPeriod> still_steps;
  for (size_t k = 0; k + 1 < trajectory.size(); ++k) {
    const StampedPose& a = trajectory[k];
    const StampedPose& b = trajectory[k + 1];
    const double dt = NsToSeconds(b.t_ns - a.t_ns);
    const double speed = (b.pose.translation() - a.pose.translation()).norm() / dt;
    const double rate = so3::AngularDistance(a.pose.rotation(), b.pose.rotation()) / dt;
    if (speed < max_speed && rate < max_angular_rate) still_steps.push_back({a.t_ns, b.t_ns});
  }
  return KeepLong(Merge(still_steps), SecondsToNs(min_duration_s));
}

std::vector<StationaryPeriod> IntersectStationaryPeriods(const std::vector<StationaryPeriod>& a,
                                                         const std::vector<StationaryPeriod>& b,
                                                         double min_duration_s) {
  const TimestampNs min_duration_ns = SecondsToNs(min_duration_s);
  std::vector<StationaryPeriod> out;
  size_t i = 0, j = 0;
  while (i < a.size() && j < b.size()) {
    const TimestampNs start = std::max(a[i].start_ns, b[j].start_ns);
    const TimestampNs end = std::min(a[i].end_ns, b[j].end_ns);
    if (end - start >= min_duration_ns && end >= start) out.push_back({start, end});
    if (a[i].end_ns < b[j].end_ns) {
      ++i;
    } else {
      ++j;
    }
  }
  return out;
}

int StationaryPeriodIndex(const std::vector<StationaryPeriod>& periods, TimestampNs t_ns) {
  // The last period that starts at or before t_ns.
  const auto it = std::upper_bound(
      periods.begin(), periods.end(), t_ns, [](TimestampNs t, const StationaryPeriod& p) {
        return t < p.start_ns;
      });
  if (it == periods.begin()) return -1;
  const int index = static_cast<int>(it - periods.begin()) - 1;
  return periods[index].Contains(t_ns) ? index : -1;
}

bool PairInsideStationaryPeriod(const std::vector<StationaryPeriod>& periods,
                                TimestampNs t_i_ns,
                                TimestampNs t_j_ns) {
  const int period = StationaryPeriodIndex(periods, t_i_ns);
  return period >= 0 && periods[period].Contains(t_j_ns);
}

PiecewiseBias AssignPiecewiseBias(const std::vector<TimestampNs>& keyframe_times_ns,
                                  const std::vector<StationaryPeriod>& periods) {
  for (size_t k = 1; k < keyframe_times_ns.size(); ++k) {
    THROW_CHECK_LT(keyframe_times_ns[k - 1], keyframe_times_ns[k]);
  }
  PiecewiseBias bias;
  const int num_keyframes = static_cast<int>(keyframe_times_ns.size());
  if (num_keyframes == 0) return bias;
  bias.first_keyframe.push_back(0);
  for (const StationaryPeriod& period : periods) {
    const int k = static_cast<int>(
        std::lower_bound(keyframe_times_ns.begin(), keyframe_times_ns.end(), period.start_ns) -
        keyframe_times_ns.begin());
    // A bias variable needs an interval to act on: keyframe k must not be the last.
    if (k >= 1 && k < num_keyframes - 1 && k > bias.first_keyframe.back()) {
      bias.first_keyframe.push_back(k);
    }
  }
  bias.interval_bias.resize(std::max(0, num_keyframes - 1));
  int b = 0;
  for (int k = 0; k + 1 < num_keyframes; ++k) {
    if (b + 1 < bias.num_biases() && bias.first_keyframe[b + 1] == k) ++b;
    bias.interval_bias[k] = b;
  }
  return bias;
}

double BiasRandomWalkSeconds(const PiecewiseBias& bias,
                             const std::vector<TimestampNs>& keyframe_times_ns,
                             int b) {
  THROW_CHECK(b >= 0 && b + 1 < bias.num_biases());
  const int last_keyframe = static_cast<int>(keyframe_times_ns.size()) - 1;
  const auto midpoint_ns = [&](int index) {
    const int first = bias.first_keyframe[index];
    const int end = index + 1 < bias.num_biases() ? bias.first_keyframe[index + 1] : last_keyframe;
    return keyframe_times_ns[first] + (keyframe_times_ns[end] - keyframe_times_ns[first]) / 2;
  };
  return NsToSeconds(midpoint_ns(b + 1) - midpoint_ns(b));
}

}  // namespace lisfm

#include "importers/database_importer.h"

#include <fmt/format.h>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <numeric>
#include <set>
#include <sstream>

#include "colmap_ext/io/camera_models.h"
#include "colmap_ext/io/database.h"
#include "colmap_ext/io/rig_config.h"
#include "core/errors.h"
#include "core/file_utils.h"
#include "core/io/cloud_io.h"
#include "core/io/keyframe_covariances_io.h"
#include "core/io/lidar_constraints_io.h"
#include "core/io/rig_io.h"
#include "core/io/trajectory_io.h"
#include "core/logging.h"
#include "core/option_check.h"
#include "core/work_list.h"
#include "icp/nearest_neighbors.h"
#include "importers/sequence.h"

namespace lisfm {

bool CovisibilityOptions::Check() const {
  CHECK_OPTION_MSG(source, source == "map" || source == "constraints", "map or constraints");
  CHECK_OPTION_MSG(
      score, score == "count" || score == "fraction" || score == "area", "count, fraction or area");
  CHECK_OPTION_GT(max_view_angle_deg, 0.0);
  CHECK_OPTION_LE(max_view_angle_deg, 180.0);
  CHECK_OPTION_GE(max_point_range_m, 0.0);
  CHECK_OPTION_GT(max_point_distance_m, 0.0);
  CHECK_OPTION_GE(scan_voxel_size_m, 0.0);
  CHECK_OPTION_GT(max_image_time_offset_s, 0.0);
  CHECK_OPTION_GE(zbuffer_cell_px, 1);
  CHECK_OPTION_GE(point_footprint_m, 0.0);
  CHECK_OPTION_GE(occlusion_tolerance_m, 0.0);
  CHECK_OPTION_GE(occlusion_tolerance_ratio, 0.0);
  CHECK_OPTION_GE(min_count, 1);
  CHECK_OPTION_GE(max_pairs_per_image, 1);
  CHECK_OPTION_GE(num_temporal_neighbors, 0);
  CHECK_OPTION_GE(min_view_overlap, 0.0);
  CHECK_OPTION_LE(min_view_overlap, 1.0);
  CHECK_OPTION_GT(view_overlap_depth_m, 0.0);
  CHECK_OPTION_GE(fallback_num_neighbors, 1);
  CHECK_OPTION_MSG(num_threads, num_threads == -1 || num_threads >= 1, "-1 or >= 1");
  return true;
}

bool ImporterPriorOptions::Check() const {
  CHECK_OPTION_GT(min_position_sigma_m, 0.0);
  CHECK_OPTION_GE(drift_m_per_s, 0.0);
  CHECK_OPTION_GE(drift_rad_per_s, 0.0);
  CHECK_OPTION_GE(max_extrapolation_s, 0.0);
  CHECK_OPTION_GT(max_frame_time_offset_s, 0.0);
  return true;
}

bool DatabaseImporterOptions::Check() const {
  CHECK_OPTION_NESTED(covisibility);
  CHECK_OPTION_NESTED(priors);
  return true;
}

std::optional<SE3> InterpolatePoseSe3(const Trajectory& trajectory, TimestampNs t_ns) {
  const auto& poses = trajectory.poses();
  if (poses.empty() || t_ns < poses.front().t_ns || t_ns > poses.back().t_ns) {
    return std::nullopt;
  }
  auto it =
      std::lower_bound(poses.begin(), poses.end(), t_ns, [](const StampedPose& p, TimestampNs t) {
        return p.t_ns < t;
      });
  if (it->t_ns == t_ns) return it->pose;
  const StampedPose& b = *it;
  const StampedPose& a = *std::prev(it);
  const double s = static_cast<double>(t_ns - a.t_ns) / static_cast<double>(b.t_ns - a.t_ns);
  const SE3 a_from_b = a.pose.Inverse() * b.pose;
  return a.pose * SE3::Exp(s * a_from_b.Log());
}

std::string PairSourceName(PairSource source) {
  switch (source) {
    case PairSource::kCovisibility:
      return "covisibility";
    case PairSource::kRig:
      return "rig";
    case PairSource::kTemporal:
      return "temporal";
    case PairSource::kPriors:
      return "priors";
  }
  return "unknown";
}

namespace {

double SecondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// Smallest range per cell of one image, from one scan's points (world frame).
struct ZBuffer {
  int cell = 8;
  int cols = 0, rows = 0;
  std::vector<float> min_range;  // +inf when empty

  float At(const Vec2& pixel) const {
    const int c = static_cast<int>(std::floor((pixel.x() + 0.5) / cell));
    const int r = static_cast<int>(std::floor((pixel.y() + 0.5) / cell));
    if (c < 0 || r < 0 || c >= cols || r >= rows) return -1.f;
    return min_range[static_cast<size_t>(r) * cols + c];
  }
};

// An empty z-buffer of `model`'s image.
ZBuffer EmptyZBuffer(const CameraModel& model, int cell) {
  ZBuffer z;
  z.cell = cell;
  z.cols = (model.width + cell - 1) / cell;
  z.rows = (model.height + cell - 1) / cell;
  z.min_range.assign(static_cast<size_t>(z.cols) * z.rows, std::numeric_limits<float>::infinity());
  return z;
}

// Enters a point at `pixel` and `range` (m) covering a disc of footprint_m:
// radius focal * footprint / (2 range) px.
void Splat(const Vec2& pixel, double range, double focal, double footprint_m, ZBuffer* z) {
  const int cell = z->cell;
  const double radius = std::min(focal * footprint_m / (2.0 * range), 4.0 * cell + 64.0);
  const int c0 = std::max(0, static_cast<int>(std::floor((pixel.x() + 0.5 - radius) / cell)));
  const int c1 =
      std::min(z->cols - 1, static_cast<int>(std::floor((pixel.x() + 0.5 + radius) / cell)));
  const int r0 = std::max(0, static_cast<int>(std::floor((pixel.y() + 0.5 - radius) / cell)));
  const int r1 =
      std::min(z->rows - 1, static_cast<int>(std::floor((pixel.y() + 0.5 + radius) / cell)));
  for (int r = r0; r <= r1; ++r) {
    for (int c = c0; c <= c1; ++c) {
      float& m = z->min_range[static_cast<size_t>(r) * z->cols + c];
      m = std::min(m, static_cast<float>(range));
    }
  }
}

// Cosine of the widest angle between the optical axis and a ray through the
// image border (sampled every 8 px), widened by 1 degree: no point at a larger
// angle projects into the image.
double MinViewCosine(const CameraModel& model) {
  double widest = 0;
  Vec3 ray;
  auto sample = [&](double u, double v) {
    if (model.Unproject(Vec2(u, v), &ray)) {
      widest = std::max(widest, std::acos(std::clamp(ray.normalized().z(), -1.0, 1.0)));
    } else {
      widest = M_PI;
    }
  };
  for (int u = 0; u <= model.width; u += 8) {
    sample(u - 0.5, -0.5);
    sample(u - 0.5, model.height - 0.5);
  }
  for (int v = 0; v <= model.height; v += 8) {
    sample(-0.5, v - 0.5);
    sample(model.width - 0.5, v - 0.5);
  }
  return std::cos(std::min(M_PI, widest + M_PI / 180.0));
}

ZBuffer BuildZBuffer(const CameraModel& model,
                     const SE3& cam_from_world,
                     const std::vector<Eigen::Vector3f>& points_in_world,
                     int cell,
                     double footprint_m) {
  ZBuffer z = EmptyZBuffer(model, cell);
  const double focal = 0.5 * (model.fx + model.fy);
  Vec2 pixel;
  for (const Eigen::Vector3f& p : points_in_world) {
    const Vec3 x = cam_from_world * p.cast<double>();
    if (!model.Project(x, &pixel, /*check_bounds=*/true)) continue;
    Splat(pixel, x.norm(), focal, footprint_m, &z);
  }
  return z;
}

}  // namespace

std::map<std::pair<int, int>, PairVotes> ComputeCovisibility(
    const Rig& rig,
    const std::vector<ImporterImage>& images,
    const std::vector<KeyframeScan>& scans,
    const std::vector<std::pair<int, int>>& scan_pairs,
    const CovisibilityOptions& options) {
  return *ComputeCovisibility(rig, images, scans, scan_pairs, options, WorkListRunner());
}

std::map<std::pair<int, int>, PairVotes> ComputeMapCovisibility(
    const Rig& rig,
    const std::vector<ImporterImage>& images,
    const std::vector<KeyframeScan>& scans,
    const CovisibilityOptions& options) {
  return *ComputeMapCovisibility(rig, images, scans, options, WorkListRunner());
}

std::optional<std::map<std::pair<int, int>, PairVotes>> ComputeCovisibility(
    const Rig& rig,
    const std::vector<ImporterImage>& images,
    const std::vector<KeyframeScan>& scans,
    const std::vector<std::pair<int, int>>& scan_pairs,
    const CovisibilityOptions& options,
    const WorkListRunner& runner) {
  THROW_CHECK(options.Check());
  for (const ImporterImage& image : images) {
    THROW_CHECK_LT(static_cast<size_t>(image.camera_index), rig.cameras.size());
  }
  const int64_t max_dt_ns = SecondsToNs(options.max_image_time_offset_s);

  std::optional<tbb::global_control> threads;
  if (options.num_threads > 0) {
    threads.emplace(tbb::global_control::max_allowed_parallelism, options.num_threads);
  }

  // Per scan: downsampled world points, a tree of the full scan (world), the
  // images near it and their z-buffers (from the downsampled points).
  struct ScanData {
    std::vector<Eigen::Vector3f> sparse_world;
    std::unique_ptr<KdTree> tree;
    std::vector<int> images;
    std::vector<ZBuffer> zbuffers;
    std::vector<SE3> cam_from_world;
  };
  std::vector<char> used(scans.size(), 0);
  for (const auto& [i, j] : scan_pairs) {
    THROW_CHECK(i >= 0 && j >= 0 && static_cast<size_t>(i) < scans.size() &&
                static_cast<size_t>(j) < scans.size());
    used[i] = used[j] = 1;
  }
  // Each image belongs to the used scan nearest to it in time (within max_dt_ns),
  // over all scan pairs (whatever share of them this process votes for).
  std::vector<std::vector<int>> images_of_scan(scans.size());
  {
    std::vector<std::pair<TimestampNs, int>> by_time;
    for (size_t u = 0; u < scans.size(); ++u) {
      if (used[u]) by_time.emplace_back(scans[u].t_ns, static_cast<int>(u));
    }
    std::sort(by_time.begin(), by_time.end());
    for (size_t k = 0; k < images.size() && !by_time.empty(); ++k) {
      const TimestampNs t = images[k].t_imu_ns;
      auto it = std::lower_bound(
          by_time.begin(), by_time.end(), std::make_pair(t, std::numeric_limits<int>::min()));
      int best = -1;
      int64_t best_dt = max_dt_ns;
      for (auto c : {it, it == by_time.begin() ? by_time.end() : std::prev(it)}) {
        if (c == by_time.end()) continue;
        const int64_t dt = std::llabs(c->first - t);
        if (dt < best_dt || (dt == best_dt && (best < 0 || c->second < best))) {
          best = c->second;
          best_dt = dt;
        }
      }
      if (best >= 0) images_of_scan[best].push_back(static_cast<int>(k));
    }
  }
  // The scans of the pairs `subset` (indices into scan_pairs), then their votes.
  using Votes = std::map<std::pair<int, int>, int64_t>;
  const float max_sq =
      static_cast<float>(options.max_point_distance_m * options.max_point_distance_m);
  auto vote = [&](const std::vector<size_t>& subset) {
    std::vector<char> needed(scans.size(), 0);
    for (size_t q : subset) needed[scan_pairs[q].first] = needed[scan_pairs[q].second] = 1;
    std::vector<ScanData> data(scans.size());
    for (size_t u = 0; u < scans.size(); ++u) {
      if (needed[u]) data[u].images = images_of_scan[u];
    }
    tbb::parallel_for(size_t(0), scans.size(), [&](size_t s) {
      if (!needed[s]) return;
      const KeyframeScan& scan = scans[s];
      std::vector<Eigen::Vector3f> world;
      world.reserve(scan.points_in_imu.size());
      const Eigen::Matrix3f R = scan.world_from_imu.RotationMatrix().cast<float>();
      const Eigen::Vector3f t = scan.world_from_imu.translation().cast<float>();
      for (const auto& p : scan.points_in_imu) world.push_back(R * p + t);
      ScanData& d = data[s];
      d.sparse_world = VoxelDownsamplePoints(world, options.scan_voxel_size_m);
      d.tree = std::make_unique<KdTree>(std::move(world), "keyframe scan");
      for (int image : d.images) {
        const SE3 cam_from_world = images[image].world_from_cam.Inverse();
        d.cam_from_world.push_back(cam_from_world);
        d.zbuffers.push_back(BuildZBuffer(rig.cameras[images[image].camera_index].model,
                                          cam_from_world,
                                          d.sparse_world,
                                          options.zbuffer_cell_px,
                                          options.point_footprint_m));
      }
    });

    auto visible = [&](const ScanData& d, size_t u, const Eigen::Vector3f& p) {
      const CameraModel& model = rig.cameras[images[d.images[u]].camera_index].model;
      const Vec3 x = d.cam_from_world[u] * p.cast<double>();
      Vec2 pixel;
      if (!model.Project(x, &pixel, /*check_bounds=*/true)) return false;
      const float front = d.zbuffers[u].At(pixel);
      if (front < 0.f) return false;
      const double range = x.norm();
      return range <=
             front * (1.0 + options.occlusion_tolerance_ratio) + options.occlusion_tolerance_m;
    };

    // Votes per scan pair of the subset.
    std::vector<Votes> subset_votes(subset.size());
    tbb::parallel_for(size_t(0), subset.size(), [&](size_t e) {
      const size_t q = subset[e];
      const ScanData& di = data[scan_pairs[q].first];
      const ScanData& dj = data[scan_pairs[q].second];
      if (di.images.empty() || dj.images.empty()) return;
      Votes& votes = subset_votes[e];
      std::vector<int> seen_i, seen_j;
      uint32_t index;
      float sq;
      for (const Eigen::Vector3f& p : di.sparse_world) {
        if (!dj.tree->NearestWithin(p, max_sq, &index, &sq)) continue;
        seen_i.clear();
        seen_j.clear();
        for (size_t u = 0; u < di.images.size(); ++u) {
          if (visible(di, u, p)) seen_i.push_back(di.images[u]);
        }
        if (seen_i.empty()) continue;
        for (size_t u = 0; u < dj.images.size(); ++u) {
          if (visible(dj, u, p)) seen_j.push_back(dj.images[u]);
        }
        for (int a : seen_i) {
          for (int b : seen_j) {
            if (a == b) continue;
            ++votes[{std::min(a, b), std::max(a, b)}];
          }
        }
      }
    });
    return subset_votes;
  };
  std::vector<Votes> pair_votes;
  if (!runner) {
    std::vector<size_t> all(scan_pairs.size());
    std::iota(all.begin(), all.end(), size_t(0));
    pair_votes = vote(all);
  } else {
    // Cost of a pair: the points of its two scans.
    std::vector<double> costs;
    for (const auto& [i, j] : scan_pairs) {
      costs.push_back(
          static_cast<double>(scans[i].points_in_imu.size() + scans[j].points_in_imu.size()));
    }
    const auto encoded = runner(costs, [&](const std::vector<size_t>& subset) {
      std::vector<std::string> out;
      for (const Votes& votes : vote(subset)) {
        ByteWriter writer;
        writer.Put<uint64_t>(votes.size());
        for (const auto& [pair, n] : votes) {
          writer.Put<int32_t>(pair.first);
          writer.Put<int32_t>(pair.second);
          writer.Put<int64_t>(n);
        }
        out.push_back(writer.Take());
      }
      return out;
    });
    if (!encoded) return std::nullopt;
    for (const std::string& bytes : *encoded) {
      ByteReader reader(bytes);
      Votes votes;
      const uint64_t n = reader.Get<uint64_t>();
      for (uint64_t k = 0; k < n; ++k) {
        const int a = reader.Get<int32_t>();
        const int b = reader.Get<int32_t>();
        votes[{a, b}] = reader.Get<int64_t>();
      }
      pair_votes.push_back(std::move(votes));
    }
  }
  // Merged in pair order.
  std::map<std::pair<int, int>, PairVotes> result;
  for (size_t q = 0; q < scan_pairs.size(); ++q) {
    for (const auto& [pair, n] : pair_votes[q]) {
      PairVotes& v = result[pair];
      v.count += n;
      v.score = static_cast<double>(v.count);
      v.voters.push_back({scan_pairs[q], n});
    }
  }
  return result;
}

std::optional<std::map<std::pair<int, int>, PairVotes>> ComputeMapCovisibility(
    const Rig& rig,
    const std::vector<ImporterImage>& images,
    const std::vector<KeyframeScan>& scans,
    const CovisibilityOptions& options,
    const WorkListRunner& runner,
    const SharedWorkListRunner& shared_runner,
    MapCovisibilityTimings* timings) {
  THROW_CHECK(options.Check());
  for (const ImporterImage& image : images) {
    THROW_CHECK_LT(static_cast<size_t>(image.camera_index), rig.cameras.size());
  }
  MapCovisibilityTimings local_timings;
  if (timings == nullptr) timings = &local_timings;
  *timings = MapCovisibilityTimings();
  auto step_start = std::chrono::steady_clock::now();
  std::optional<tbb::global_control> threads;
  if (options.num_threads > 0) {
    threads.emplace(tbb::global_control::max_allowed_parallelism, options.num_threads);
  }
  // The map: every scan in the world frame, one point per voxel.
  std::vector<Eigen::Vector3f> world;
  for (const KeyframeScan& scan : scans) {
    const Eigen::Matrix3f R = scan.world_from_imu.RotationMatrix().cast<float>();
    const Eigen::Vector3f t = scan.world_from_imu.translation().cast<float>();
    for (const auto& p : scan.points_in_imu) world.push_back(R * p + t);
  }
  const std::vector<Eigen::Vector3f> map = VoxelDownsamplePoints(world, options.scan_voxel_size_m);
  world = {};
  timings->map = SecondsSince(step_start);
  step_start = std::chrono::steady_clock::now();
  const int n = static_cast<int>(images.size());
  const double max_range = options.max_point_range_m > 0 ? options.max_point_range_m
                                                         : std::numeric_limits<double>::infinity();
  std::vector<double> min_view_cos;
  for (const RigCamera& camera : rig.cameras) min_view_cos.push_back(MinViewCosine(camera.model));
  // Per image: the visible map points, ascending.
  auto visible_points = [&](int a) {
    std::vector<uint32_t> visible_a;
    const CameraModel& model = rig.cameras[images[a].camera_index].model;
    const SE3 cam_from_world = images[a].world_from_cam.Inverse();
    // Map points in the image (within max_range): index, pixel, range.
    struct Projected {
      uint32_t index;
      float range;
      Vec2 pixel;
    };
    std::vector<Projected> in_view;
    const double max_range_sq = max_range * max_range;
    const Eigen::Matrix3f R = cam_from_world.RotationMatrix().cast<float>();
    const Eigen::Vector3f t = cam_from_world.translation().cast<float>();
    Vec2 pixel;
    const float min_cos = static_cast<float>(min_view_cos[images[a].camera_index]);
    for (size_t k = 0; k < map.size(); ++k) {
      const Eigen::Vector3f xf = R * map[k] + t;
      const float range_sq = xf.squaredNorm();
      if (range_sq > max_range_sq) continue;
      if (xf.z() < min_cos * std::sqrt(range_sq)) continue;
      const Vec3 x = xf.cast<double>();
      if (!model.Project(x, &pixel, /*check_bounds=*/true)) continue;
      in_view.push_back({static_cast<uint32_t>(k), static_cast<float>(x.norm()), pixel});
    }
    ZBuffer z = EmptyZBuffer(model, options.zbuffer_cell_px);
    const double focal = 0.5 * (model.fx + model.fy);
    for (const Projected& p : in_view) {
      Splat(p.pixel, p.range, focal, options.point_footprint_m, &z);
    }
    for (const Projected& p : in_view) {
      const float front = z.At(p.pixel);
      if (front < 0.f) continue;
      if (p.range <=
          front * (1.0 + options.occlusion_tolerance_ratio) + options.occlusion_tolerance_m) {
        visible_a.push_back(p.index);
      }
    }
    return visible_a;
  };
  std::vector<std::vector<uint32_t>> visible(n);
  // An image's visible points as varint deltas of the ascending indices (a gap
  // below 128 takes one byte, below 16384 two, instead of four).
  auto project_share = [&](const std::vector<size_t>& subset) {
    const auto project_start = std::chrono::steady_clock::now();
    std::vector<std::string> out(subset.size());
    tbb::parallel_for(size_t(0), subset.size(), [&](size_t e) {
      const std::vector<uint32_t> v = visible_points(static_cast<int>(subset[e]));
      ByteWriter writer;
      writer.PutVarint(v.size());
      uint32_t previous = 0;
      for (uint32_t k : v) {
        writer.PutVarint(k - previous);
        previous = k;
      }
      out[e] = writer.Take();
    });
    timings->project = SecondsSince(project_start);
    return out;
  };
  auto decode_visible = [&](const std::vector<std::string>& encoded) {
    tbb::parallel_for(0, n, [&](int a) {
      ByteReader reader(encoded[a]);
      visible[a].resize(reader.GetVarint());
      uint32_t previous = 0;
      for (uint32_t& k : visible[a]) {
        k = previous + static_cast<uint32_t>(reader.GetVarint());
        previous = k;
      }
      THROW_CHECK(reader.AtEnd());
    });
  };
  // Every image projects the whole map: equal costs.
  const std::vector<double> project_costs(n, 1.0);
  // With both runners every process gets every visible list (the votes are
  // then split too); with `runner` alone the lists go to the process that
  // continues, which counts all votes.
  const bool split_votes = runner && shared_runner;
  if (!runner) {
    tbb::parallel_for(0, n, [&](int a) { visible[a] = visible_points(a); });
    timings->project = SecondsSince(step_start);
  } else if (split_votes) {
    const std::vector<std::string> encoded = shared_runner(project_costs, project_share);
    timings->exchange = SecondsSince(step_start) - timings->project;
    decode_visible(encoded);
  } else {
    const auto encoded = runner(project_costs, project_share);
    timings->exchange = SecondsSince(step_start) - timings->project;
    if (!encoded) return std::nullopt;
    decode_visible(*encoded);
  }
  step_start = std::chrono::steady_clock::now();
  // The images seeing each map point (compressed rows, images ascending).
  std::vector<uint32_t> row_start(map.size() + 1, 0);
  for (int a = 0; a < n; ++a) {
    for (uint32_t k : visible[a]) ++row_start[k + 1];
  }
  for (size_t k = 0; k < map.size(); ++k) row_start[k + 1] += row_start[k];
  std::vector<int> seen_by(row_start.back());
  {
    std::vector<uint32_t> fill(row_start.begin(), row_start.end() - 1);
    for (int a = 0; a < n; ++a) {
      for (uint32_t k : visible[a]) seen_by[fill[k]++] = a;
    }
  }
  // Index in seen_by of the first image b > a seeing map point k.
  auto first_after = [&](uint32_t k, int a) {
    return static_cast<uint32_t>(
        std::upper_bound(seen_by.begin() + row_start[k], seen_by.begin() + row_start[k + 1], a) -
        seen_by.begin());
  };
  // Votes of each image a with the images b > a.
  const double min_cos = std::cos(options.max_view_angle_deg * M_PI / 180.0);
  // Per image a: (b, votes, solid-angle weight) for the images b > a.
  struct Tally {
    int32_t b;
    int64_t count;
    double area;
  };
  const double voxel_sq =
      options.scan_voxel_size_m > 0 ? options.scan_voxel_size_m * options.scan_voxel_size_m : 1.0;
  // The sums run over a's visible points in ascending order wherever a is
  // counted, so a's tallies are the same bits in any process.
  auto tally = [&](int a) {
    std::vector<int64_t> count(n, 0);
    std::vector<double> area(n, 0.0);
    const Vec3 ca = images[a].world_from_cam.translation();
    for (uint32_t k : visible[a]) {
      const Vec3 p = map[k].cast<double>();
      const Vec3 da = p - ca;
      const double range_a = da.norm();
      const Vec3 ra = da / range_a;
      for (uint32_t e = first_after(k, a); e < row_start[k + 1]; ++e) {
        const int b = seen_by[e];
        const Vec3 db = p - images[b].world_from_cam.translation();
        const double range_b = db.norm();
        if (ra.dot(db) < min_cos * range_b) continue;
        ++count[b];
        area[b] += voxel_sq / (range_a * range_b);
      }
    }
    std::vector<Tally> out;
    for (int b = a + 1; b < n; ++b) {
      if (count[b] > 0) out.push_back({b, count[b], area[b]});
    }
    return out;
  };
  std::vector<std::vector<Tally>> tallies(n);
  if (!split_votes) {
    tbb::parallel_for(0, n, [&](int a) { tallies[a] = tally(a); });
    timings->tally = SecondsSince(step_start);
  } else {
    // Cost of image a: its (point, image b > a) visits, plus its pass over
    // the n images.
    std::vector<double> costs(n);
    tbb::parallel_for(0, n, [&](int a) {
      double c = 0.25 * n;
      for (uint32_t k : visible[a]) c += row_start[k + 1] - first_after(k, a);
      costs[a] = c;
    });
    const auto tally_start = std::chrono::steady_clock::now();
    const auto encoded = runner(costs, [&](const std::vector<size_t>& subset) {
      const auto share_start = std::chrono::steady_clock::now();
      std::vector<std::string> out(subset.size());
      tbb::parallel_for(size_t(0), subset.size(), [&](size_t e) {
        ByteWriter writer;
        const std::vector<Tally> t = tally(static_cast<int>(subset[e]));
        writer.Put<uint64_t>(t.size());
        for (const Tally& x : t) {
          writer.Put<int32_t>(x.b);
          writer.Put<int64_t>(x.count);
          writer.Put<double>(x.area);
        }
        out[e] = writer.Take();
      });
      timings->tally = SecondsSince(share_start);
      return out;
    });
    timings->exchange += SecondsSince(tally_start) - timings->tally;
    if (!encoded) return std::nullopt;
    for (int a = 0; a < n; ++a) {
      ByteReader reader((*encoded)[a]);
      tallies[a].resize(reader.Get<uint64_t>());
      for (Tally& x : tallies[a]) {
        x.b = reader.Get<int32_t>();
        x.count = reader.Get<int64_t>();
        x.area = reader.Get<double>();
      }
      THROW_CHECK(reader.AtEnd());
    }
  }
  std::map<std::pair<int, int>, PairVotes> result;
  for (int a = 0; a < n; ++a) {
    for (const Tally& t : tallies[a]) {
      PairVotes& v = result[{a, t.b}];
      v.count = t.count;
      if (options.score == "fraction") {
        const size_t seen = std::min(visible[a].size(), visible[t.b].size());
        v.score = static_cast<double>(t.count) / static_cast<double>(seen);
      } else if (options.score == "area") {
        v.score = t.area;
      } else {
        v.score = static_cast<double>(t.count);
      }
    }
  }
  return result;
}

std::vector<std::pair<int, int>> OverlappingRigCameras(const Rig& rig,
                                                       const CovisibilityOptions& options) {
  std::vector<std::pair<int, int>> result;
  const int n = static_cast<int>(rig.cameras.size());
  // Fraction of a grid of camera a's pixels whose rays, at the test depth,
  // project into camera b.
  auto overlap = [&](int a, int b) {
    const RigCamera& ca = rig.cameras[a];
    const RigCamera& cb = rig.cameras[b];
    const SE3 b_from_a = cb.cam_from_imu * ca.cam_from_imu.Inverse();
    int total = 0, seen = 0;
    const int steps = 16;
    for (int r = 0; r < steps; ++r) {
      for (int c = 0; c < steps; ++c) {
        const Vec2 pixel((c + 0.5) * ca.model.width / steps - 0.5,
                         (r + 0.5) * ca.model.height / steps - 0.5);
        Vec3 ray;
        if (!ca.model.Unproject(pixel, &ray)) continue;
        ++total;
        Vec2 pb;
        if (cb.model.Project(
                b_from_a * (ray.normalized() * options.view_overlap_depth_m), &pb, true)) {
          ++seen;
        }
      }
    }
    return total == 0 ? 0.0 : static_cast<double>(seen) / total;
  };
  for (int a = 0; a < n; ++a) {
    for (int b = a + 1; b < n; ++b) {
      if (options.min_view_overlap == 0 ||
          std::max(overlap(a, b), overlap(b, a)) >= options.min_view_overlap) {
        result.emplace_back(a, b);
      }
    }
  }
  return result;
}

std::vector<SelectedPair> SelectPairs(const Rig& rig,
                                      const std::vector<ImporterImage>& images,
                                      const std::map<std::pair<int, int>, PairVotes>& votes,
                                      bool use_priors_fallback,
                                      const CovisibilityOptions& options) {
  std::map<std::pair<int, int>, SelectedPair> selected;
  auto add = [&](int a, int b, PairSource source, int64_t count) {
    if (a == b) return;
    const std::pair<int, int> key(std::min(a, b), std::max(a, b));
    if (selected.count(key)) return;
    selected[key] = SelectedPair{key.first, key.second, source, count};
  };
  const int n = static_cast<int>(images.size());
  // Co-visibility (or the fallback): each image's best pairs.
  std::vector<std::vector<std::pair<double, int>>> ranked(n);  // (score, other)
  if (!use_priors_fallback) {
    for (const auto& [pair, v] : votes) {
      if (v.count < options.min_count) continue;
      ranked[pair.first].push_back({v.score, pair.second});
      ranked[pair.second].push_back({v.score, pair.first});
    }
  }
  std::set<std::pair<int, int>> kept;
  for (int a = 0; a < n; ++a) {
    auto& list = ranked[a];
    std::sort(list.begin(), list.end(), [](const auto& x, const auto& y) {
      return x.first > y.first || (x.first == y.first && x.second < y.second);
    });
    for (size_t r = 0; r < list.size() && r < static_cast<size_t>(options.max_pairs_per_image);
         ++r) {
      kept.insert({std::min(a, list[r].second), std::max(a, list[r].second)});
    }
  }
  for (const auto& key : kept) {
    add(key.first, key.second, PairSource::kCovisibility, votes.at(key).count);
  }
  if (use_priors_fallback) {
    for (int a = 0; a < n; ++a) {
      const Vec3 ca = images[a].world_from_cam.translation();
      const Vec3 za = images[a].world_from_cam.rotation() * Vec3::UnitZ();
      std::vector<std::pair<double, int>> near;
      for (int b = 0; b < n; ++b) {
        if (b == a || images[b].frame == images[a].frame) continue;
        const Vec3 zb = images[b].world_from_cam.rotation() * Vec3::UnitZ();
        if (za.dot(zb) <= 0) continue;
        near.push_back({(images[b].world_from_cam.translation() - ca).squaredNorm(), b});
      }
      std::sort(near.begin(), near.end());
      for (size_t r = 0; r < near.size() && r < static_cast<size_t>(options.fallback_num_neighbors);
           ++r) {
        add(a, near[r].second, PairSource::kPriors, 0);
      }
    }
  }
  if (options.intra_rig_pairs) {
    std::set<std::pair<int, int>> overlapping;
    for (const auto& p : OverlappingRigCameras(rig, options)) overlapping.insert(p);
    std::map<int, std::vector<int>> by_frame;
    for (int a = 0; a < n; ++a) by_frame[images[a].frame].push_back(a);
    for (const auto& [frame, list] : by_frame) {
      for (int a : list) {
        for (int b : list) {
          const int ka = images[a].camera_index, kb = images[b].camera_index;
          if (ka < kb && overlapping.count({ka, kb})) add(a, b, PairSource::kRig, 0);
        }
      }
    }
  }
  if (options.num_temporal_neighbors > 0) {
    std::vector<std::vector<int>> by_camera(rig.cameras.size());
    for (int a = 0; a < n; ++a) by_camera[images[a].camera_index].push_back(a);
    for (auto& list : by_camera) {
      std::sort(list.begin(), list.end(), [&](int x, int y) {
        return images[x].t_imu_ns < images[y].t_imu_ns;
      });
      for (size_t u = 0; u < list.size(); ++u) {
        for (size_t v = u + 1;
             v < list.size() && v <= u + static_cast<size_t>(options.num_temporal_neighbors);
             ++v) {
          add(list[u], list[v], PairSource::kTemporal, 0);
        }
      }
    }
  }
  std::vector<SelectedPair> result;
  result.reserve(selected.size());
  for (const auto& [key, pair] : selected) result.push_back(pair);
  return result;
}

std::vector<LidarConstraintRecord> ReexpressConstraints(
    const std::vector<LidarConstraintRecord>& records,
    const Trajectory& world_from_imu,
    const std::vector<TimestampNs>& keyframe_stamps,
    const std::vector<ImporterFrame>& frames,
    const ImporterPriorOptions& options,
    size_t* num_dropped) {
  std::vector<int> order(frames.size());
  for (size_t f = 0; f < frames.size(); ++f) order[f] = static_cast<int>(f);
  std::sort(order.begin(), order.end(), [&](int x, int y) {
    return frames[x].t_imu_ns < frames[y].t_imu_ns;
  });
  const int64_t max_dt = SecondsToNs(options.max_frame_time_offset_s);
  auto nearest = [&](TimestampNs t) {
    auto it = std::lower_bound(order.begin(), order.end(), t, [&](int f, TimestampNs s) {
      return frames[f].t_imu_ns < s;
    });
    int best = -1;
    int64_t best_dt = max_dt;
    for (auto c : {it, it == order.begin() ? order.end() : std::prev(it)}) {
      if (c == order.end()) continue;
      const int64_t dt = std::llabs(frames[*c].t_imu_ns - t);
      if (dt <= best_dt) {
        best = *c;
        best_dt = dt;
      }
    }
    return best;
  };
  std::vector<LidarConstraintRecord> result;
  size_t dropped = 0;
  for (const LidarConstraintRecord& record : records) {
    TimestampNs t_i = record.t_i_ns, t_j = record.t_j_ns;
    if (!record.has_stamps) {
      if (record.index_i >= static_cast<int64_t>(keyframe_stamps.size()) ||
          record.index_j >= static_cast<int64_t>(keyframe_stamps.size())) {
        ++dropped;
        continue;
      }
      t_i = keyframe_stamps[record.index_i];
      t_j = keyframe_stamps[record.index_j];
    }
    const int a = nearest(t_i), b = nearest(t_j);
    const auto pose_i = InterpolatePoseSe3(world_from_imu, t_i);
    const auto pose_j = InterpolatePoseSe3(world_from_imu, t_j);
    if (a < 0 || b < 0 || a == b || !pose_i || !pose_j) {
      ++dropped;
      continue;
    }
    const SE3 a_from_i = frames[a].world_from_imu.Inverse() * *pose_i;
    const SE3 j_from_b = pose_j->Inverse() * frames[b].world_from_imu;
    LidarConstraintRecord out;
    out.has_stamps = true;
    out.t_i_ns = frames[a].stamp_ns;
    out.t_j_ns = frames[b].stamp_ns;
    out.i_from_j = a_from_i * record.i_from_j * j_from_b;
    // A T Exp(xi) B = (A T B) Exp(Ad(B^-1) xi).
    const Mat6 ad = j_from_b.Inverse().Adjoint();
    out.covariance = ad * record.covariance * ad.transpose();
    const double dt =
        NsToSeconds(std::llabs(frames[a].t_imu_ns - t_i) + std::llabs(frames[b].t_imu_ns - t_j));
    const double sr = options.drift_rad_per_s * dt, st = options.drift_m_per_s * dt;
    out.covariance.diagonal().head<3>().array() += sr * sr;
    out.covariance.diagonal().tail<3>().array() += st * st;
    out.covariance = 0.5 * (out.covariance + out.covariance.transpose()).eval();
    result.push_back(out);
  }
  if (num_dropped != nullptr) *num_dropped = dropped;
  return result;
}

std::pair<int, int> ReadImageSize(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path, "", "cannot open the image");
  unsigned char head[24] = {0};
  in.read(reinterpret_cast<char*>(head), sizeof(head));
  const std::streamsize got = in.gcount();
  auto be32 = [](const unsigned char* p) {
    return (static_cast<uint32_t>(p[0]) << 24) | (static_cast<uint32_t>(p[1]) << 16) |
           (static_cast<uint32_t>(p[2]) << 8) | p[3];
  };
  static const unsigned char kPng[8] = {0x89, 'P', 'N', 'G', 0x0d, 0x0a, 0x1a, 0x0a};
  if (got >= 24 && std::equal(kPng, kPng + 8, head)) {
    return {static_cast<int>(be32(head + 16)), static_cast<int>(be32(head + 20))};
  }
  if (got >= 2 && head[0] == 0xff && head[1] == 0xd8) {
    // JPEG: walk the markers to the first start-of-frame (SOF0..SOF15 except
    // DHT 0xc4, JPG 0xc8, DAC 0xcc), which holds height then width.
    in.clear();
    in.seekg(2);
    for (;;) {
      int c = in.get();
      while (c == 0xff) c = in.get();
      if (c == EOF) break;
      const int marker = c;
      unsigned char len_bytes[2];
      if (!in.read(reinterpret_cast<char*>(len_bytes), 2)) break;
      const int length = (len_bytes[0] << 8) | len_bytes[1];
      if (marker >= 0xc0 && marker <= 0xcf && marker != 0xc4 && marker != 0xc8 && marker != 0xcc) {
        unsigned char sof[5];
        if (!in.read(reinterpret_cast<char*>(sof), 5)) break;
        return {(sof[3] << 8) | sof[4], (sof[1] << 8) | sof[2]};
      }
      if (length < 2) break;
      in.seekg(length - 2, std::ios::cur);
    }
    throw InputError(path, "", "JPEG without a frame header (truncated?)");
  }
  throw InputError(path, "", "not a PNG or JPEG image");
}

namespace {

// The camera centre's position covariance from a right-perturbation 6x6
// covariance of world_from_imu (header comment).
Mat3 CentreCovariance(const SE3& world_from_imu, const SE3& imu_from_cam, const Mat6& cov) {
  const Mat3 R = world_from_imu.RotationMatrix();
  const Vec3 t = imu_from_cam.translation();
  Mat3 skew;
  skew << 0, -t.z(), t.y(), t.z(), 0, -t.x(), -t.y(), t.x(), 0;
  Eigen::Matrix<double, 3, 6> J;
  J.leftCols<3>() = -R * skew;
  J.rightCols<3>() = R;
  return J * cov * J.transpose();
}

const KeyframeCovariance& NearestCovariance(const std::vector<KeyframeCovariance>& covs,
                                            TimestampNs t) {
  auto it =
      std::lower_bound(covs.begin(), covs.end(), t, [](const KeyframeCovariance& c, TimestampNs s) {
        return c.t_ns < s;
      });
  if (it == covs.end()) return covs.back();
  if (it == covs.begin()) return *it;
  return (t - std::prev(it)->t_ns <= it->t_ns - t) ? *std::prev(it) : *it;
}

// One image row from a sequence index row.
struct ImageSource {
  int camera_index = 0;
  TimestampNs stamp_ns = 0;
  std::string name;  // relative to the image path
  std::string path;
  std::string index_file;  // for errors
  int index_line = 0;
  bool stamp_on_imu_clock = false;  // HILTI GTSFM keyframes: the stamp is the pose time
};

std::string JsonNumber(double v) { return fmt::format("{:.6g}", v); }

}  // namespace

DatabaseImporterSummary RunDatabaseImporter(const DatabaseImporterInput& input,
                                            const DatabaseImporterOptions& options,
                                            const std::string& output_dir,
                                            const WorkListRunner& runner,
                                            const SharedWorkListRunner& shared_runner) {
  THROW_CHECK(options.Check());
  const auto start = std::chrono::steady_clock::now();
  DatabaseImporterSummary summary;
  const bool hilti = input.input_type == "hilti_gtsfm";
  if (!hilti && input.input_type != "sequence") {
    throw UsageError("--input_type: expected sequence or hilti_gtsfm, found " + input.input_type);
  }

  // ---- rig and image sources ----
  Rig rig;
  std::vector<ImageSource> sources;
  std::string image_root = input.image_path.empty() ? input.input_path : input.image_path;
  Trajectory trajectory;               // world_from_imu
  std::vector<StampedPose> keyframes;  // world_from_imu at the keyframe stamps
  std::vector<KeyframeCovariance> keyframe_covariances;
  std::vector<LidarConstraintRecord> constraints;
  std::string constraints_path;
  if (!hilti) {
    CheckDirExists(input.input_path, "--input_path sequence folder");
    rig = ReadRigYaml(JoinPaths(input.input_path, "rig.yaml"));
    for (size_t k = 0; k < rig.cameras.size(); ++k) {
      const std::string dir = JoinPaths(input.input_path, rig.cameras[k].name);
      if (!DirExists(dir)) continue;
      const std::string index = JoinPaths(dir, "data.csv");
      const std::vector<SensorFile> files = ReadSensorIndex(index, JoinPaths(dir, "data"));
      int line = 0;
      for (const SensorFile& f : files) {
        ++line;
        ImageSource s;
        s.camera_index = static_cast<int>(k);
        s.stamp_ns = f.t_ns;
        const std::string file = f.path.substr(f.path.find_last_of('/') + 1);
        s.name = rig.cameras[k].name + "/data/" + file;
        s.path = JoinPaths(image_root, s.name);
        s.index_file = index;
        s.index_line = line;
        if (!FileExists(s.path)) {
          throw InputError(
              index,
              fmt::format("record {}", line),
              fmt::format("image {} not found under --image_path {}", s.name, image_root));
        }
        sources.push_back(s);
      }
    }
    CheckDirExists(input.pose_slam_path, "--pose_slam_path folder");
    trajectory = ReadTum(JoinPaths(input.pose_slam_path, "trajectory.txt"));
    keyframes = ReadTum(JoinPaths(input.pose_slam_path, "keyframes.txt")).poses();
    keyframe_covariances =
        ReadKeyframeCovariances(JoinPaths(input.pose_slam_path, "keyframe_covariances.txt"));
    constraints_path = JoinPaths(input.pose_slam_path, "constraints.txt");
    constraints = ReadLidarConstraints(constraints_path);
  } else {
    // HILTI 2022 extract as GTSFM ships it: images/k.jpg with k = 5 * keyframe
    // + camera, keyframe k at FAST-LIO2 pose k (lidar/fastlio2_odom.txt line k,
    // the g2o vertex k that GTSFM's hilti_loader reads), constraints between
    // keyframe indices.
    CheckDirExists(input.input_path, "--input_path HILTI folder");
    rig = LoadHiltiCalibration(JoinPaths(input.input_path, "calibration"));
    const Trajectory odom = ReadTum(JoinPaths(input.input_path, "lidar/fastlio2_odom.txt"));
    const std::string images_dir = JoinPaths(input.input_path, "images");
    CheckDirExists(images_dir, "HILTI images folder");
    const int num_cams = static_cast<int>(rig.cameras.size());
    int num_images = 0;
    while (FileExists(JoinPaths(images_dir, std::to_string(num_images) + ".jpg"))) ++num_images;
    const int num_frames = num_images / num_cams;
    if (num_frames == 0) throw InputError(images_dir, "", "no images 0.jpg, 1.jpg, ...");
    if (num_frames > static_cast<int>(odom.size())) {
      throw InputError(JoinPaths(input.input_path, "lidar/fastlio2_odom.txt"),
                       "",
                       fmt::format("{} poses for {} keyframes", odom.size(), num_frames));
    }
    image_root = JoinPaths(output_dir, "images");
    for (int f = 0; f < num_frames; ++f) {
      keyframes.push_back(odom[f]);
      trajectory.PushBack(odom[f]);
      KeyframeCovariance c;
      c.t_ns = odom[f].t_ns;
      // GTSFM's soft absolute pose prior sigma (3e-2 per tangent component).
      c.covariance = Mat6::Identity() * 3e-2 * 3e-2;
      keyframe_covariances.push_back(c);
      for (int k = 0; k < num_cams; ++k) {
        ImageSource s;
        s.camera_index = k;
        s.stamp_ns = odom[f].t_ns;
        s.name = fmt::format("{}/data/{}.jpg", rig.cameras[k].name, odom[f].t_ns);
        const std::string jpg = JoinPaths(images_dir, std::to_string(num_cams * f + k) + ".jpg");
        s.path = JoinPaths(image_root, s.name);
        s.index_file = jpg;
        s.stamp_on_imu_clock = true;
        CreateDirs(JoinPaths(image_root, rig.cameras[k].name + "/data"));
        std::error_code ec;
        std::filesystem::create_symlink(std::filesystem::absolute(jpg), s.path, ec);
        if (ec) throw InputError(s.path, "", "cannot create the image link: " + ec.message());
        sources.push_back(s);
      }
    }
    constraints_path = JoinPaths(input.input_path, "lidar/constraints.txt");
    constraints = ReadLidarConstraints(constraints_path);
  }
  if (trajectory.empty()) throw InputError(input.pose_slam_path, "", "empty trajectory");
  if (keyframe_covariances.empty()) {
    throw InputError(
        JoinPaths(input.pose_slam_path, "keyframe_covariances.txt"), "", "no keyframe covariances");
  }
  if (sources.empty()) throw InputError(input.input_path, "", "no camera images");
  summary.num_constraints_read = constraints.size();

  // ---- images with priors ----
  std::vector<ImporterImage> images;
  const int64_t max_extra = SecondsToNs(options.priors.max_extrapolation_s);
  std::map<std::string, size_t> skipped_per_index;
  for (const ImageSource& s : sources) {
    const RigCamera& camera = rig.cameras[s.camera_index];
    const auto [w, h] = ReadImageSize(s.path);
    if (w != camera.model.width || h != camera.model.height) {
      throw InputError(s.path,
                       "",
                       fmt::format("image size {}x{}, but rig.yaml {}.resolution is [{}, {}]",
                                   w,
                                   h,
                                   camera.name,
                                   camera.model.width,
                                   camera.model.height));
    }
    ImporterImage image;
    image.name = s.name;
    image.path = s.path;
    image.camera_index = s.camera_index;
    image.stamp_ns = s.stamp_ns;
    image.t_imu_ns =
        s.stamp_on_imu_clock ? s.stamp_ns : s.stamp_ns + SecondsToNs(camera.timeshift_cam_imu_s);
    const TimestampNs t_clamped =
        std::clamp(image.t_imu_ns, trajectory.start_ns(), trajectory.end_ns());
    if (std::llabs(t_clamped - image.t_imu_ns) > max_extra) {
      ++skipped_per_index[s.index_file];
      continue;
    }
    const SE3 world_from_imu = *InterpolatePoseSe3(trajectory, t_clamped);
    const SE3 imu_from_cam = camera.cam_from_imu.Inverse();
    image.world_from_cam = world_from_imu * imu_from_cam;
    const KeyframeCovariance& kc = NearestCovariance(keyframe_covariances, image.t_imu_ns);
    const double dt = NsToSeconds(std::llabs(kc.t_ns - image.t_imu_ns));
    const double drift = options.priors.drift_m_per_s * dt;
    const double floor = options.priors.min_position_sigma_m;
    image.position_covariance = CentreCovariance(world_from_imu, imu_from_cam, kc.covariance) +
                                Mat3::Identity() * (drift * drift + floor * floor);
    images.push_back(image);
  }
  for (const auto& [file, n] : skipped_per_index) {
    LogWarning(
        "database_importer: {}: {} images outside the pose_slam trajectory [{}, {}] left "
        "out (--DatabaseImporter.max_extrapolation_s {})",
        file,
        n,
        trajectory.start_ns(),
        trajectory.end_ns(),
        options.priors.max_extrapolation_s);
    summary.num_images_skipped += n;
  }
  if (images.empty()) {
    throw InputError(JoinPaths(input.pose_slam_path, "trajectory.txt"),
                     "",
                     fmt::format("no camera time lies within the trajectory [{}, {}] ns",
                                 trajectory.start_ns(),
                                 trajectory.end_ns()));
  }
  // Rig frames by name stamp; the frame time is that of its lowest-index camera.
  std::vector<ImporterFrame> frames;
  {
    std::map<TimestampNs, int> frame_of_stamp;
    std::vector<size_t> order(images.size());
    for (size_t u = 0; u < images.size(); ++u) order[u] = u;
    std::stable_sort(order.begin(), order.end(), [&](size_t x, size_t y) {
      return images[x].stamp_ns < images[y].stamp_ns ||
             (images[x].stamp_ns == images[y].stamp_ns &&
              images[x].camera_index < images[y].camera_index);
    });
    for (size_t u : order) {
      auto [it, inserted] =
          frame_of_stamp.emplace(images[u].stamp_ns, static_cast<int>(frames.size()));
      if (inserted) {
        ImporterFrame f;
        f.stamp_ns = images[u].stamp_ns;
        f.t_imu_ns = images[u].t_imu_ns;
        f.world_from_imu =
            images[u].world_from_cam * rig.cameras[images[u].camera_index].cam_from_imu;
        frames.push_back(f);
      }
      images[u].frame = it->second;
    }
  }
  summary.num_images = images.size();
  summary.num_frames = frames.size();
  summary.num_cameras = rig.cameras.size();
  summary.seconds_read = SecondsSince(start);

  // ---- co-visibility ----
  const auto covis_start = std::chrono::steady_clock::now();
  std::vector<TimestampNs> keyframe_stamps;
  for (const auto& k : keyframes) keyframe_stamps.push_back(k.t_ns);
  summary.num_keyframes = keyframes.size();
  std::map<std::pair<int, int>, PairVotes> votes;
  std::vector<KeyframeScan> scans;
  bool fallback = constraints.empty() || hilti;
  bool ran_runner = false;
  if (constraints.empty()) {
    LogWarning(
        "database_importer: {} holds no constraints: pairs from the pose priors instead "
        "of LiDAR co-visibility",
        constraints_path);
  }
  if (!fallback) {
    std::map<TimestampNs, int> scan_of_stamp;
    std::vector<std::pair<int, int>> scan_pairs;
    const Trajectory keyframe_trajectory(keyframes);
    auto scan_index = [&](TimestampNs t) {
      auto it = scan_of_stamp.find(t);
      if (it != scan_of_stamp.end()) return it->second;
      const std::string path =
          JoinPaths(JoinPaths(input.lio_path, "keyframes"), std::to_string(t) + ".pcd");
      if (!FileExists(path)) {
        throw InputError(options.covisibility.source == "map"
                             ? JoinPaths(input.pose_slam_path, "keyframes.txt")
                             : constraints_path,
                         "",
                         fmt::format("keyframe {} has no scan {} (--lio_path)", t, path));
      }
      KeyframeScan scan;
      scan.t_ns = t;
      const auto pose = InterpolatePoseSe3(keyframe_trajectory, t);
      if (!pose) {
        throw InputError(
            constraints_path, "", fmt::format("keyframe {} is outside keyframes.txt", t));
      }
      scan.world_from_imu = *pose;
      scan.points_in_imu = FinitePointsOf(ReadPointCloud(path));
      scans.push_back(std::move(scan));
      scan_of_stamp[t] = static_cast<int>(scans.size() - 1);
      return static_cast<int>(scans.size() - 1);
    };
    CheckDirExists(JoinPaths(input.lio_path, "keyframes"), "--lio_path keyframes folder");
    if (options.covisibility.source == "map") {
      for (TimestampNs t : keyframe_stamps) scan_index(t);
      summary.seconds_scans = SecondsSince(covis_start);
      auto map_votes = ComputeMapCovisibility(
          rig, images, scans, options.covisibility, runner, shared_runner, &summary.map_timings);
      ran_runner = true;
      if (!map_votes) {
        summary.share_only = true;
        return summary;
      }
      votes = std::move(*map_votes);
    }
    std::set<std::pair<TimestampNs, TimestampNs>> seen;
    for (const LidarConstraintRecord& r : constraints) {
      if (options.covisibility.source == "map") break;
      TimestampNs ti = r.t_i_ns, tj = r.t_j_ns;
      if (!r.has_stamps) {
        if (r.index_i >= static_cast<int64_t>(keyframe_stamps.size()) ||
            r.index_j >= static_cast<int64_t>(keyframe_stamps.size())) {
          continue;
        }
        ti = keyframe_stamps[r.index_i];
        tj = keyframe_stamps[r.index_j];
      }
      if (!seen.insert({std::min(ti, tj), std::max(ti, tj)}).second) continue;
      scan_pairs.push_back({scan_index(ti), scan_index(tj)});
    }
    // Each scan with itself: the images of one scan that see the same points.
    if (options.covisibility.source == "constraints") {
      for (size_t u = 0; u < scans.size(); ++u) {
        scan_pairs.push_back({static_cast<int>(u), static_cast<int>(u)});
      }
      auto pair_votes =
          ComputeCovisibility(rig, images, scans, scan_pairs, options.covisibility, runner);
      ran_runner = true;
      if (!pair_votes) {
        summary.share_only = true;
        return summary;
      }
      votes = std::move(*pair_votes);
    }
  }
  if (runner && !ran_runner &&
      !runner({}, [](const std::vector<size_t>&) { return std::vector<std::string>(); })) {
    summary.share_only = true;  // nothing to share: rank 0 writes
    return summary;
  }
  summary.num_covisibility_votes_pairs = votes.size();
  const auto select_start = std::chrono::steady_clock::now();
  const std::vector<SelectedPair> pairs =
      SelectPairs(rig, images, votes, fallback, options.covisibility);
  summary.priors_fallback = fallback;
  summary.num_pairs = pairs.size();
  for (const SelectedPair& p : pairs) {
    switch (p.source) {
      case PairSource::kCovisibility:
        ++summary.num_pairs_covisibility;
        break;
      case PairSource::kRig:
        ++summary.num_pairs_rig;
        break;
      case PairSource::kTemporal:
        ++summary.num_pairs_temporal;
        break;
      case PairSource::kPriors:
        ++summary.num_pairs_priors;
        break;
    }
  }
  size_t dropped = 0;
  const std::vector<LidarConstraintRecord> frame_constraints = ReexpressConstraints(
      constraints, trajectory, keyframe_stamps, frames, options.priors, &dropped);
  summary.num_constraints_written = frame_constraints.size();
  summary.num_constraints_dropped = dropped;
  if (dropped > 0) {
    LogWarning(
        "database_importer: {} of {} constraints have no pair of distinct rig frames "
        "within {} s of their keyframes; left out",
        dropped,
        constraints.size(),
        options.priors.max_frame_time_offset_s);
  }
  summary.seconds_select = SecondsSince(select_start);
  summary.seconds_covisibility = SecondsSince(covis_start);

  // ---- outputs ----
  const auto write_start = std::chrono::steady_clock::now();
  std::vector<colmap::camera_t> camera_ids(rig.cameras.size());
  std::vector<colmap::image_t> image_ids(images.size());
  {
    colmap::Database db(JoinPaths(output_dir, "database.db"), colmap::Database::OpenMode::kCreate);
    colmap::DatabaseTransaction transaction(&db);
    for (size_t k = 0; k < rig.cameras.size(); ++k) {
      colmap::Camera camera =
          colmap::CameraFromCameraModel(rig.cameras[k].model, static_cast<colmap::camera_t>(k + 1));
      camera_ids[k] = db.WriteCamera(camera, /*use_camera_id=*/true);
    }
    // Image ids in (frame stamp, camera) order.
    std::vector<size_t> order(images.size());
    for (size_t u = 0; u < images.size(); ++u) order[u] = u;
    std::sort(order.begin(), order.end(), [&](size_t x, size_t y) {
      return std::make_pair(images[x].stamp_ns, images[x].camera_index) <
             std::make_pair(images[y].stamp_ns, images[y].camera_index);
    });
    colmap::image_t next_id = 1;
    for (size_t u : order) {
      const ImporterImage& image = images[u];
      colmap::DbImage row;
      row.image_id = next_id++;
      row.name = image.name;
      row.camera_id = camera_ids[image.camera_index];
      const Quat q = image.world_from_cam.rotation().conjugate();
      row.has_prior_rotation = true;
      row.prior_qvec = Vec4(q.w(), q.x(), q.y(), q.z());
      row.has_prior_position = true;
      row.prior_position = image.world_from_cam.translation();
      row.prior_position_covariance = image.position_covariance;
      row.prior_coordinate_system = colmap::PriorCoordinateSystem::kCartesian;
      image_ids[u] = db.WriteImage(row, /*use_image_id=*/true);
    }
    transaction.Commit();
  }
  {
    std::vector<size_t> order(images.size());
    for (size_t u = 0; u < images.size(); ++u) order[u] = u;
    std::sort(order.begin(), order.end(), [&](size_t x, size_t y) {
      return image_ids[x] < image_ids[y];
    });
    std::string list;
    for (size_t u : order) list += images[u].name + "\n";
    WriteFileAtomically(JoinPaths(output_dir, "image_list.txt"), list);
  }
  {
    std::string text, csv = "# image_name1,image_name2,source,count,scan_pairs (t_i-t_j:votes)\n";
    for (const SelectedPair& p : pairs) {
      text += images[p.a].name + " " + images[p.b].name + "\n";
      std::string voters;
      if (p.source == PairSource::kCovisibility) {
        const PairVotes& v = votes.at({p.a, p.b});
        std::string s;
        for (const auto& [sp, n] : v.voters) {
          if (!s.empty()) s += ";";
          s += fmt::format("{}-{}:{}", scans[sp.first].t_ns, scans[sp.second].t_ns, n);
        }
        voters = s;
      }
      csv += fmt::format("{},{},{},{},{}\n",
                         images[p.a].name,
                         images[p.b].name,
                         PairSourceName(p.source),
                         p.count,
                         voters);
    }
    WriteFileAtomically(JoinPaths(output_dir, "pairs.txt"), text);
    WriteFileAtomically(JoinPaths(output_dir, "covisibility.csv"), csv);
  }
  WriteRigYaml(JoinPaths(output_dir, "rig.yaml"),
               rig,
               "rig of the database (lisfm database_importer); cameras are COLMAP cameras 1..N");
  colmap::WriteRigConfigs({colmap::RigConfigFromRig(rig, camera_ids)},
                          JoinPaths(output_dir, "rig_config.json"));
  WriteLidarConstraints(frame_constraints, JoinPaths(output_dir, "constraints.txt"));
  summary.seconds_write = SecondsSince(write_start);
  summary.seconds_total = SecondsSince(start);
  {
    std::ostringstream json;
    json << "{\n";
    json << fmt::format("  \"input_type\": \"{}\",\n", input.input_type);
    json << fmt::format("  \"cameras\": {},\n  \"images\": {},\n  \"images_skipped\": {},\n",
                        summary.num_cameras,
                        summary.num_images,
                        summary.num_images_skipped);
    json << fmt::format(
        "  \"rig_frames\": {},\n  \"keyframes\": {},\n", summary.num_frames, summary.num_keyframes);
    json << fmt::format("  \"constraints\": {{\"read\": {}, \"written\": {}, \"dropped\": {}}},\n",
                        summary.num_constraints_read,
                        summary.num_constraints_written,
                        summary.num_constraints_dropped);
    json << fmt::format(
        "  \"pairs\": {{\"total\": {}, \"covisibility\": {}, \"rig\": {}, \"temporal\": {}, "
        "\"priors\": {}, \"image_pairs_with_votes\": {}, \"priors_fallback\": {}}},\n",
        summary.num_pairs,
        summary.num_pairs_covisibility,
        summary.num_pairs_rig,
        summary.num_pairs_temporal,
        summary.num_pairs_priors,
        summary.num_covisibility_votes_pairs,
        summary.priors_fallback ? "true" : "false");
    json << fmt::format(
        "  \"covisibility_seconds\": {{\"scans\": {}, \"map\": {}, \"project\": {}, "
        "\"exchange\": {}, \"tally\": {}, \"select\": {}}},\n",
        JsonNumber(summary.seconds_scans),
        JsonNumber(summary.map_timings.map),
        JsonNumber(summary.map_timings.project),
        JsonNumber(summary.map_timings.exchange),
        JsonNumber(summary.map_timings.tally),
        JsonNumber(summary.seconds_select));
    json << fmt::format(
        "  \"seconds\": {{\"read\": {}, \"covisibility\": {}, \"write\": {}, \"total\": {}}}\n",
        JsonNumber(summary.seconds_read),
        JsonNumber(summary.seconds_covisibility),
        JsonNumber(summary.seconds_write),
        JsonNumber(summary.seconds_total));
    json << "}\n";
    WriteFileAtomically(JoinPaths(output_dir, "importer_summary.json"), json.str());
  }
  return summary;
}

}  // namespace lisfm

#include "lio/voxel_map.h"

#include <algorithm>
#include <cmath>

#include "core/errors.h"
#include "core/option_check.h"

namespace lisfm {

bool VoxelMapOptions::Check() const {
  CHECK_OPTION_GT(voxel_size, 0.0);
  CHECK_OPTION_GE(resolution, 0.0);
  CHECK_OPTION_LT(resolution, voxel_size);
  CHECK_OPTION_GE(max_points_per_voxel, 1);
  CHECK_OPTION_GE(max_voxels, 1u);
  return true;
}

VoxelMap::VoxelMap(const VoxelMapOptions& options)
    : options_(options),
      inv_voxel_size_(static_cast<float>(1.0 / options.voxel_size)),
      min_sq_spacing_(static_cast<float>(options.resolution * options.resolution)) {
  THROW_CHECK_OPTIONS(options);
  // Centre, 6 faces, 12 edges.
  for (int dx = -1; dx <= 1; ++dx)
    for (int dy = -1; dy <= 1; ++dy)
      for (int dz = -1; dz <= 1; ++dz) {
        const int n = std::abs(dx) + std::abs(dy) + std::abs(dz);
        if (n <= 2) nearby_offsets_.push_back({dx, dy, dz});
      }
  std::sort(nearby_offsets_.begin(), nearby_offsets_.end(), [](const Key& a, const Key& b) {
    return std::abs(a.x) + std::abs(a.y) + std::abs(a.z) < std::abs(b.x) + std::abs(b.y) + std::abs(b.z);
  });
}

VoxelMap::Key VoxelMap::KeyOf(const Point& p) const {
  return {static_cast<int32_t>(std::floor(p.x() * inv_voxel_size_)),
          static_cast<int32_t>(std::floor(p.y() * inv_voxel_size_)),
          static_cast<int32_t>(std::floor(p.z() * inv_voxel_size_))};
}

size_t VoxelMap::Insert(const std::vector<Point>& points,
                        const std::vector<MapPointAttributes>* attributes) {
  THROW_CHECK(attributes == nullptr || attributes->size() == points.size());
  size_t stored = 0;
  for (size_t i = 0; i < points.size(); ++i) {
    const Point& p = points[i];
    if (!p.allFinite()) continue;
    const MapPointAttributes a = attributes != nullptr ? (*attributes)[i] : MapPointAttributes();
    const Key key = KeyOf(p);
    auto it = grid_.find(key);
    if (it == grid_.end()) {
      lru_.push_front(key);
      Voxel v;
      v.lru_it = lru_.begin();
      v.points.reserve(8);
      v.points.push_back(p);
      v.attributes.reserve(8);
      v.attributes.push_back(a);
      grid_.emplace(key, std::move(v));
      ++num_points_;
      ++stored;
      if (grid_.size() > options_.max_voxels) {
        const Key old = lru_.back();
        lru_.pop_back();
        auto old_it = grid_.find(old);
        num_points_ -= old_it->second.points.size();
        grid_.erase(old_it);
      }
      continue;
    }
    Voxel& v = it->second;
    lru_.splice(lru_.begin(), lru_, v.lru_it);  // mark used
    if (static_cast<int>(v.points.size()) >= options_.max_points_per_voxel) continue;
    bool too_close = false;
    for (const Point& q : v.points) {
      if ((q - p).squaredNorm() < min_sq_spacing_) {
        too_close = true;
        break;
      }
    }
    if (too_close) continue;
    v.points.push_back(p);
    v.attributes.push_back(a);
    ++num_points_;
    ++stored;
  }
  return stored;
}

int VoxelMap::KnnSearch(const Point& query,
                        int k,
                        double max_distance,
                        std::vector<Point>* neighbours,
                        std::vector<float>* squared_distances) const {
  // Small fixed-size insertion-sorted buffer: k is ~5.
  constexpr int kMaxK = 32;
  k = std::min(k, kMaxK);
  float best_d[kMaxK];
  const Point* best_p[kMaxK];
  int found = 0;
  const float max_sq = static_cast<float>(max_distance * max_distance);
  const Key c = KeyOf(query);
  // Query position inside its voxel, for the distance to neighbouring voxels.
  const float vs = static_cast<float>(options_.voxel_size);
  const Eigen::Vector3f local = query - Eigen::Vector3f(c.x * vs, c.y * vs, c.z * vs);
  for (const Key& o : nearby_offsets_) {
    // Squared distance from the query to the neighbour voxel's box: skip the
    // voxel when it cannot hold anything closer than what was found.
    float box_d2 = 0;
    const int off[3] = {o.x, o.y, o.z};
    for (int a = 0; a < 3; ++a) {
      const float d = off[a] < 0 ? local[a] : (off[a] > 0 ? vs - local[a] : 0.0f);
      box_d2 += d * d;
    }
    if (box_d2 > max_sq || (found == k && box_d2 >= best_d[k - 1])) continue;
    const auto it = grid_.find({c.x + o.x, c.y + o.y, c.z + o.z});
    if (it == grid_.end()) continue;
    for (const Point& p : it->second.points) {
      const float d = (p - query).squaredNorm();
      if (d > max_sq) continue;
      if (found == k && d >= best_d[k - 1]) continue;
      int i = (found < k) ? found++ : k - 1;
      while (i > 0 && best_d[i - 1] > d) {
        best_d[i] = best_d[i - 1];
        best_p[i] = best_p[i - 1];
        --i;
      }
      best_d[i] = d;
      best_p[i] = &p;
    }
  }
  neighbours->resize(found);
  squared_distances->resize(found);
  for (int i = 0; i < found; ++i) {
    (*neighbours)[i] = *best_p[i];
    (*squared_distances)[i] = best_d[i];
  }
  return found;
}

std::vector<VoxelMap::Point> VoxelMap::AllPoints() const {
  std::vector<Point> all;
  all.reserve(num_points_);
  for (const auto& kv : grid_) all.insert(all.end(), kv.second.points.begin(), kv.second.points.end());
  return all;
}

PointCloud VoxelMap::ToCloud() const {
  PointCloud cloud;
  cloud.points.reserve(num_points_);
  for (const auto& kv : grid_) {
    const Voxel& v = kv.second;
    for (size_t i = 0; i < v.points.size(); ++i) {
      LidarPoint lp;
      lp.x = v.points[i].x();
      lp.y = v.points[i].y();
      lp.z = v.points[i].z();
      lp.intensity = v.attributes[i].intensity;
      lp.sensor_id = v.attributes[i].sensor_id;
      cloud.points.push_back(lp);
    }
  }
  return cloud;
}

}  // namespace lisfm

// An iVox-style incremental map (Bai et al., "Faster-LIO", RA-L 2022): a hash
// map from integer voxel coordinates to a small array of points. Insertion
// keeps at most one point per `resolution` cell inside each voxel, so the map
// stays uniformly dense; k-nearest-neighbour search scans the voxel of the
// query and its 18 face/edge neighbours ("NEARBY18"); voxels are evicted in
// least-recently-used order once more than `max_voxels` exist, which removes
// far-away regions as the sensor moves.
//
// Points are world-frame positions (float), each with the attributes of the
// LiDAR return that created it (MapPointAttributes). Not thread-safe for
// concurrent insertion; concurrent const searches are safe.
#pragma once

#include <cstdint>
#include <list>
#include <unordered_map>
#include <vector>

#include "core/point_cloud.h"
#include "core/types.h"

namespace lisfm {

struct VoxelMapOptions {
  double voxel_size = 0.5;      // m, edge of a hash voxel
  double resolution = 0.1;      // m, minimum spacing of stored points inside a voxel
  int max_points_per_voxel = 64;
  size_t max_voxels = 200000;   // LRU capacity (~ 200k * 0.125 m^3 = 25,000 m^3 of occupied space)
  bool Check() const;
};

// What a map point keeps of the LiDAR return that created it.
struct MapPointAttributes {
  float intensity = 0;    // return intensity, as the sensor reported it
  uint8_t sensor_id = 0;  // the LiDAR that measured it (lidar0, lidar1, ...)
};

class VoxelMap {
 public:
  using Point = Eigen::Vector3f;

  explicit VoxelMap(const VoxelMapOptions& options);

  // Adds world points; returns how many were stored (others were too close to
  // an existing point of their voxel or the voxel was full). `attributes`, when
  // given, has one entry per point and is stored with the kept points
  // (otherwise they get default attributes).
  size_t Insert(const std::vector<Point>& points,
                const std::vector<MapPointAttributes>* attributes = nullptr);

  // Up to k nearest neighbours of `query` within `max_distance` (m), sorted
  // by distance. Returns the count found; fills `neighbours` and squared distances.
  int KnnSearch(const Point& query,
                int k,
                double max_distance,
                std::vector<Point>* neighbours,
                std::vector<float>* squared_distances) const;

  size_t NumPoints() const { return num_points_; }
  size_t NumVoxels() const { return grid_.size(); }
  std::vector<Point> AllPoints() const;
  // The map as a world-frame cloud, in the order of AllPoints(): x y z,
  // intensity and sensor_id of each point; t and ring are 0 (a map point has
  // no time within a scan). stamp_ns is 0.
  PointCloud ToCloud() const;

 private:
  struct Key {
    int32_t x, y, z;
    bool operator==(const Key& o) const { return x == o.x && y == o.y && z == o.z; }
  };
  struct KeyHash {
    size_t operator()(const Key& k) const {
      // Teschner et al. spatial hash primes.
      return (static_cast<size_t>(k.x) * 73856093u) ^ (static_cast<size_t>(k.y) * 19349669u) ^
             (static_cast<size_t>(k.z) * 83492791u);
    }
  };
  struct Voxel {
    std::vector<Point> points;
    std::vector<MapPointAttributes> attributes;  // parallel to points
    std::list<Key>::iterator lru_it;
  };

  Key KeyOf(const Point& p) const;

  VoxelMapOptions options_;
  float inv_voxel_size_;
  float min_sq_spacing_;
  std::unordered_map<Key, Voxel, KeyHash> grid_;
  std::list<Key> lru_;  // front = most recently used
  size_t num_points_ = 0;
  std::vector<Key> nearby_offsets_;
};

}  // namespace lisfm

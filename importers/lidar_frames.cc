#include "importers/lidar_frames.h"

#include <algorithm>

#include <fmt/format.h>

#include "core/errors.h"
#include "core/io/cloud_io.h"

namespace lisfm {

LidarFrameReader::LidarFrameReader(const Sequence& sequence, std::vector<int> lidars)
    : sequence_(sequence), lidars_(std::move(lidars)), next_scan_(sequence.lidar_scans.size(), 0) {
  if (lidars_.empty()) throw InputError("no LiDAR selected");
  for (int k : lidars_) {
    if (k < 0 || k >= static_cast<int>(sequence_.lidar_scans.size())) {
      throw InputError(fmt::format("{}: the rig has no LiDAR {} (it has {})", sequence_.root, k,
                                   sequence_.lidar_scans.size()));
    }
  }
}

size_t LidarFrameReader::num_frames() const { return sequence_.lidar_scans[lidars_[0]].size(); }

bool LidarFrameReader::Next(LidarFrame* frame) {
  const auto& primary = sequence_.lidar_scans[lidars_[0]];
  if (next_frame_ >= primary.size()) return false;
  const SensorFile& file = primary[next_frame_++];
  frame->clouds.clear();
  frame->sensor_ids.clear();
  auto load = [&](const SensorFile& f, int sensor) {
    frame->clouds.push_back(ReadPointCloud(f.path));
    // Point times become int64 ns offsets (SecondsToNs) downstream.
    const std::vector<LidarPoint>& points = frame->clouds.back().points;
    for (size_t i = 0; i < points.size(); ++i) {
      if (!IsRepresentableAsNs(points[i].t)) {
        throw InputError(f.path, "record " + std::to_string(i),
                         fmt::format("t = {}, expected finite seconds since the scan stamp",
                                     points[i].t));
      }
    }
    frame->clouds.back().stamp_ns = f.t_ns;
    frame->sensor_ids.push_back(sensor);
  };
  load(file, lidars_[0]);
  for (size_t u = 1; u < lidars_.size(); ++u) {
    const int k = lidars_[u];
    const auto& scans = sequence_.lidar_scans[k];
    size_t& i = next_scan_[k];
    for (; i < scans.size() && scans[i].t_ns <= file.t_ns; ++i) {
      if (scans[i].t_ns > previous_primary_ns_) load(scans[i], k);
    }
  }
  previous_primary_ns_ = file.t_ns;
  frame->end_ns = INT64_MIN;
  for (size_t c = 0; c < frame->clouds.size(); ++c) {
    float t_max = 0;
    for (const auto& p : frame->clouds[c].points) t_max = std::max(t_max, p.t);
    const double offset = sequence_.rig.lidars[frame->sensor_ids[c]].time_offset_s;
    frame->end_ns = std::max(frame->end_ns, frame->clouds[c].stamp_ns + SecondsToNs(offset) +
                                                SecondsToNs(t_max));
  }
  return true;
}

}  // namespace lisfm

// Evaluation plots drawn with OpenCV (no python): a PNG with a top view (x-y,
// equal aspect) of a reference and an aligned estimate trajectory, and an
// error-over-time panel below it.
#pragma once

#include <string>
#include <vector>

#include "core/types.h"

namespace lisfm {

struct TrajectoryPlotData {
  std::string title;            // one line at the top ("" for none)
  std::vector<Vec3> reference;  // reference positions (m), reference world
  bool reference_as_markers =
      false;                   // circles instead of a line (control points)
  std::vector<Vec3> estimate;  // aligned estimate positions (m), same world
  std::vector<double> error_time_s;  // abscissa of the error panel (s)
  std::vector<double> error_m;  // error at each error_time_s (m), same size
  std::string reference_label = "reference";
  std::string estimate_label = "estimate (aligned)";
};

// Writes a PNG (1200 x 1000 px) atomically to `path`. The top view uses x and
// y only (z is ignored) with equal scale on both axes. Throws InternalError
// when both trajectories are empty or the error vectors differ in size, and
// InputError when the file cannot be written.
void WriteTrajectoryPlot(const std::string& path,
                         const TrajectoryPlotData& data);

}  // namespace lisfm

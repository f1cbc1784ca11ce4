// Walking options shared by tests whose data were generated with three rests.
#pragma once

#include "sim/motion.h"

namespace lisfm {

// A walk with three rests: at the start, in the middle and at the end.
inline sim::WalkingOptions ThreeStopWalk() {
  sim::WalkingOptions options;
  options.num_stops = 3;
  return options;
}

}  // namespace lisfm

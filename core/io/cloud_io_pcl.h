// PCD and PLY files through PCL's readers (pcl::PCDReader, pcl::PLYReader),
// converted to PointCloud with the field rules of cloud_io.h: the reference
// that tests and benchmarks compare cloud_io's own parsers with. For valid
// files only (PCL 1.13 crashes on some malformed ones; cloud_io.h validates,
// these do not). Library lisfm_core_io_pcl, which links PCL's io (and VTK):
// the lisfm executable does not use it.
//
// Failures: PCL's exceptions and non-zero status, a missing x/y/z field or an
// out-of-range attribute throw InputError naming the path.
#pragma once

#include <string>

#include "core/point_cloud.h"

namespace lisfm {

PointCloud ReadPcdWithPclReader(const std::string& path);
PointCloud ReadPlyWithPclReader(const std::string& path);

}  // namespace lisfm

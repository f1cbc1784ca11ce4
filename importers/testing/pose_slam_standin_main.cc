// lisfm_pose_slam_standin LIO_PATH OUTPUT_PATH [--point_to_plane]: writes the
// stand-in pose_slam folder of importers/testing/pose_slam_standin.h (for
// scripts/bench_covisibility.sh; the real `lisfm pose_slam` output replaces it).
#include <exception>
#include <iostream>
#include <string>

#include "importers/testing/pose_slam_standin.h"

int main(int argc, char** argv) {
  if (argc < 3) {
    std::cerr << "usage: lisfm_pose_slam_standin LIO_PATH OUTPUT_PATH [--point_to_plane]\n";
    return 2;
  }
  lisfm::test::PoseSlamStandInOptions options;
  if (argc > 3 && std::string(argv[3]) == "--point_to_plane") options.point_to_plane_only = true;
  try {
    const size_t n = lisfm::test::WritePoseSlamStandIn(argv[1], argv[2], options);
    std::cout << "pose_slam stand-in: " << n << " constraints in " << argv[2] << "\n";
  } catch (const std::exception& e) {
    std::cerr << "error: " << e.what() << "\n";
    return 1;
  }
  return 0;
}

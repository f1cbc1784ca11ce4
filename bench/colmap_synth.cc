// lisfm_colmap_synth: writes a synthetic COLMAP model for benchmarks.
//   lisfm_colmap_synth <output_folder> [num_images] [num_points] [track_length] [bin|txt]
#include <cstdlib>
#include <exception>
#include <iostream>
#include <string>

#include "colmap_ext/io/model_io.h"
#include "colmap_ext/testing/synthetic.h"

int main(int argc, char** argv) {
  if (argc < 2 || argv[1][0] == '-') {
    std::cerr << "usage: lisfm_colmap_synth <output_folder> [num_images=1000] "
                 "[num_points=500000] [track_length=4] [bin|txt]\n";
    return 2;
  }
  try {
    // Five 1280 x 960 cameras in turn (PINHOLE, OPENCV_FISHEYE, OPENCV, ...) on
    // a ring around a cube of points; 0.5 px noise, 500 keypoints per image
    // without a point.
    lisfm::colmap::SyntheticDatasetOptions options;
    options.num_frames = argc > 2 ? std::atoi(argv[2]) : 1000;
    options.num_cameras = 5;
    options.camera_models = {"PINHOLE", "OPENCV_FISHEYE", "OPENCV"};
    options.image_width = 1280;
    options.image_height = 960;
    options.focal_length = 800.0;
    options.num_points = argc > 3 ? std::atoi(argv[3]) : 500000;
    options.track_length = argc > 4 ? std::atoi(argv[4]) : 4;
    options.pixel_noise = 0.5;
    options.num_random_keypoints = 500;
    const bool text = argc > 5 && std::string(argv[5]) == "txt";
    if (!options.Check()) {
      std::cerr << "error: invalid sizes\n";
      return 2;
    }
    const auto model =
        lisfm::colmap::SyntheticReconstruction(lisfm::colmap::SynthesizeDataset(options));
    lisfm::colmap::WriteModel(model, argv[1],
                              text ? lisfm::colmap::ModelFormat::kText
                                   : lisfm::colmap::ModelFormat::kBinary);
    std::cout << "wrote " << model.NumImages() << " images, " << model.NumPoints3D()
              << " points, " << model.ComputeNumObservations() << " observations to "
              << argv[1] << "\n";
  } catch (const std::exception& e) {
    std::cerr << "error: " << e.what() << "\n";
    return 1;
  }
  return 0;
}

// Dense RGB-D SLAM with point-based fusion: per frame, preprocess (downsample,
// optional bilateral filter, depth range, vertex and normal maps), track frame to
// model (RegisterProjective against the model rendered at the previous pose) or
// take a given pose, then fuse into a SurfelMap.
//
// Frames: a depth image is z along the optical axis (m) on the pixel grid of
// `intrinsics` (full resolution); poses are world_from_camera. With tracking, the
// first frame's pose is the one passed to the first AddFrame (identity if none) and
// later poses chain the ICP estimates.
//
// Tracking: the model is rendered (index map, splat radius model_splat_px) at the
// previous pose; the initial guess is the previous pose or, with constant_velocity,
// the previous relative motion applied once more. With colour and
// ProjectiveIcpOptions::photometric_weight > 0 the ICP adds the photometric term,
// I = (0.299 R + 0.587 G + 0.114 B) / 255, of this frame against the model's colour
// rendered at the previous pose (the same index map as the geometric target;
// where no surfel is seen, the previous frame's intensity). The model's colour is
// anchored in the world: a frame-to-frame target would add each frame's error
// along the directions only texture constrains (a corridor's axis). The ICP
// estimate is used when it has at least min_inliers matches; otherwise the frame
// keeps the initial guess and FrameResult::tracked is false.
//
// Threads: TBB inside each stage; not thread-safe itself. Results do not depend
// on the thread count.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <vector>

#include "core/geometry.h"
#include "icp/projective_icp.h"
#include "icp/surfel_map.h"

namespace lisfm {

struct RgbdFusionOptions {
  int downsample_factor = 2;     // keep every k-th pixel in both directions (1..8)
  double min_depth_m = 0.1;      // depths below are invalid (m)
  double max_depth_m = 5.0;      // depths above are invalid (m)
  double max_depth_jump = 0.05;  // no normal across a neighbour depth step above this fraction of z
  // Normals from slopes over this many pixels each side (ComputeVertexNormalMap;
  // 1 = central differences). At 320x240 central differences of Kinect-like depth
  // scatter normals by tens of degrees (speckled normal maps); 2 cuts that noise
  // 2.2x and drops normals within 2 pixels of a depth discontinuity.
  int normal_window_px = 2;
  // Pixels whose normal window spans a crease lose their normal when their
  // off-plane score exceeds this many clipped RMS of the frame's scores
  // (ComputeVertexNormalMap; 0 = keep them). Mixed normals at a room's edges bias
  // tracking along the motion: without it a noise-free box room tracks with ~1 mm
  // error after 20 frames, with it ~1 um (surfel_map_test).
  double crease_rejection_sigma = 3;
  double max_incidence_deg = 80.0;        // drop pixels seen more obliquely (normal vs ray, deg)
  bool bilateral_filter = false;          // bilateral filter of the (downsampled) depth
  double bilateral_sigma_px = 1.5;        // spatial sigma (pixels of the downsampled image)
  double bilateral_sigma_depth_m = 0.02;  // range sigma (m)
  int model_splat_px = 1;  // tracking target: surfels cover up to this many pixels (0..3)
  // Initial guess of tracking: the previous frame's motion (1) or the previous pose
  // (0). The ICP keeps the initial guess along unconstrained directions (a corridor's
  // axis), where a constant-velocity guess integrates every velocity error into
  // position without bound; the previous pose leaves at most the true motion there.
  bool constant_velocity = false;
  bool Check() const;
};

struct RgbdFrameResult {
  SE3 world_from_camera;
  bool tracked = false;     // pose from ICP (false: given pose, first frame, or ICP failed)
  ProjectiveIcpResult icp;  // when tracking ran
  FuseStats fuse;
  double preprocess_ms = 0, track_ms = 0, fuse_ms = 0;  // wall-clock per stage (ms)
};

class RgbdFusion {
 public:
  // full_intrinsics: the input images' pinhole model. Throws InternalError for
  // bad options, InputError for intrinsics that do not describe an image.
  RgbdFusion(const PinholeIntrinsics& full_intrinsics,
             const RgbdFusionOptions& options,
             const ProjectiveIcpOptions& icp_options,
             const SurfelFusionOptions& fusion_options);

  // Fuses one frame. depth_m: full-resolution depth (m, 0 = invalid); rgb: RGB bytes
  // (3 per pixel, row-major) or empty. world_from_camera: the frame's pose, or
  // nullopt to track (then it is also the first frame's pose when given there).
  // Throws InputError when the image sizes do not match the intrinsics.
  RgbdFrameResult AddFrame(const std::vector<float>& depth_m,
                           const std::vector<uint8_t>& rgb,
                           const std::optional<SE3>& world_from_camera);

  const SurfelMap& map() const { return map_; }
  // Intrinsics of the downsampled frames the map is built from.
  const PinholeIntrinsics& intrinsics() const { return intrinsics_; }
  int num_frames() const { return num_frames_; }
  // Valid pixels (vertex + normal) over all frames so far.
  size_t num_input_points() const { return num_input_points_; }

 private:
  void Preprocess(const std::vector<float>& depth_m, const std::vector<uint8_t>& rgb);

  PinholeIntrinsics full_;
  PinholeIntrinsics intrinsics_;
  RgbdFusionOptions options_;
  ProjectiveIcpOptions icp_options_;
  SurfelMap map_;
  FusionFrame frame_;
  std::vector<float> depth_;
  std::vector<float> filtered_;
  VertexNormalMap model_;              // the model rendered at the previous pose
  std::vector<uint32_t> model_index_;  // its index map (SurfelMap::RenderIndexMap)
  std::vector<float> intensity_;
  IntensityPyramid intensity_pyramid_, previous_intensity_pyramid_;
  SE3 previous_, previous_motion_;
  int num_frames_ = 0;
  size_t num_input_points_ = 0;
};

}  // namespace lisfm

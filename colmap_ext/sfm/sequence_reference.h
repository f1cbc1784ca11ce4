// Reference cameras of a simulated sequence folder (`lisfm simulate`;
// docs/FORMATS.md "Sequence folder", "Error sources") for `lisfm
// model_evaluator --reference_format sequence`, and the comparison of a
// model's refined rig with the true one.
//
// A sequence folder with ground truth holds `rig.yaml` (the believed
// calibration), `groundtruth.txt` (TUM, world_from_imu, exact), `truth/` and,
// with the simulator's `calibration` error source, `truth/rig.yaml` (the true
// extrinsics and time shifts; without it the calibration is exact and
// `rig.yaml` is the truth).
//
// Time: a camera stamp is the IMU-clock time read with rig.yaml's time shift;
// the true capture time is t_true = stamp + (truth shift − rig.yaml shift) of
// that camera, clamped to the ground truth's ends (a generated walk starts
// and ends at rest). Reference pose of an image of camera k:
//   world_from_cam = world_from_imu(t_true) · cam_from_imu_true⁻¹
// (world_from_imu on the SE(3) geodesic between the bracketing ground-truth
// poses). Names are those of `lisfm database_importer`: `camK/data/<file>`
// with <file> the `camK/data.csv` file name (DESIGN.md "Formats").
//
// Rig: a model written with a rig holds COLMAP 3.12 rigs.bin, whose rig frame
// is the reference camera's (the rig camera with the smallest camera id), so
// what the model refines is cam_k_from_cam_ref; it is compared with
// cam_k_from_imu_true · cam_ref_from_imu_true⁻¹ (and so is rig.yaml's
// believed one, to show what bundle adjustment changed).
#pragma once

#include <string>
#include <vector>

#include "colmap_ext/io/reconstruction.h"
#include "colmap_ext/sfm/sfm_evaluation.h"
#include "core/rig.h"
#include "core/time.h"
#include "core/trajectory.h"

namespace lisfm {
namespace colmap {

// One camera frame of a sequence: rig camera index, stamp (ns, as in the
// folder) and image name.
struct SequenceImage {
  int camera_index = 0;
  TimestampNs stamp_ns = 0;
  std::string name;
};

// True when `path` is a folder holding `rig.yaml` and `groundtruth.txt` (a
// sequence folder with ground truth; `truth/` is checked on reading).
bool IsSequenceFolderWithGroundTruth(const std::string& path);

// The reference poses (see the file comment) of `images`; `believed` and
// `truth` have the same cameras. Throws InputError (naming `source`) for a
// camera index the rigs lack or a rig camera count mismatch.
std::vector<NamedPose> SequenceReferencePoses(const Rig& believed,
                                              const Rig& truth,
                                              const Trajectory& groundtruth,
                                              const std::vector<SequenceImage>& images,
                                              const std::string& source);

struct SequenceReference {
  std::vector<NamedPose> poses;  // every row of every camK/data.csv, camera then time order
  Rig believed_rig;              // rig.yaml
  Rig truth_rig;                 // truth/rig.yaml, or rig.yaml when it is absent
  bool has_truth_rig_file = false;
};

// Reads a sequence folder's reference. Throws InputError naming the folder
// when `truth/` is missing (not a simulated sequence with ground truth), and
// the file and line for a malformed rig.yaml, groundtruth.txt or camK/data.csv
// (docs/FORMATS.md); a camera of rig.yaml without its folder is skipped.
SequenceReference ReadSequenceReference(const std::string& folder);

// One rig camera of a model's COLMAP 3.12 rig against the truth.
struct RigCameraEvaluation {
  camera_t camera_id = 0;
  int camera_index = -1;      // rig camera index K (from the image names camK/...)
  bool is_reference = false;  // the rig's reference sensor (errors 0 by definition)
  // Refined cam_from_ref (model) vs the true one: rotation angle (deg) and
  // translation distance (m; model translation times `scale`).
  double rotation_error_deg = 0;
  double translation_error_m = 0;
  // rig.yaml's (believed) cam_from_ref vs the true one.
  double believed_rotation_error_deg = 0;
  double believed_translation_error_m = 0;
};

// Per camera of the model's first rig (empty when the model has no rig).
// The camera index of a camera id comes from the names of its images
// (`camK/data/<ns>.<ext>`); `scale` converts model units to metres (the
// Sim(3) alignment scale, 1 for metric models). Throws InputError naming
// `source` when a rig camera has no image with such a name or an index the
// rigs lack.
std::vector<RigCameraEvaluation> EvaluateModelRig(const Reconstruction& model,
                                                  const Rig& believed,
                                                  const Rig& truth,
                                                  double scale,
                                                  const std::string& source);

}  // namespace colmap
}  // namespace lisfm

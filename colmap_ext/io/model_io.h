// COLMAP sparse model files, byte-exact with COLMAP 3.8 (REFERENCES.md
// section 1 "Model files"):
//   cameras.bin   u64 count; per camera: id u32, model i32, width u64,
//                 height u64, params f64 x model count
//   images.bin    u64 count; per image: id u32, qvec 4 f64 (w,x,y,z), tvec 3 f64,
//                 camera id u32, NUL-terminated name, u64 n, n x (x f64, y f64,
//                 point3D id u64, max = none)
//   points3D.bin  u64 count; per point: id u64, xyz 3 f64, rgb 3 u8, error f64,
//                 u64 track length, (image id u32, point2D idx u32) pairs
//   *.txt         COLMAP's text form: `%.17g` numbers, -1 = no 3D point, three
//                 comment header lines with counts and means.
//   rigs.bin, frames.bin  optional, COLMAP 3.12 layout (3.8 ignores them);
//                 written only when the reconstruction has rigs / frames.
// All little-endian. Writers store QvecForWriting(qvec) (reconstruction.h:
// unit quaternions unchanged, others normalised as COLMAP does) and keep the
// reconstruction's order; readers keep the file's order and values (no
// re-normalisation), so read + write reproduces COLMAP's files byte for byte.
//
// Failures: a missing file, a truncated or over-long .bin (InputError naming
// the file and "record N"), a malformed text line ("line N"), unknown camera
// models, wrong parameter counts and tracks that do not match the images
// (Reconstruction::Validate) all throw InputError. Outputs are written
// atomically (temporary name + rename).
#pragma once

#include <string>

#include "colmap_ext/io/reconstruction.h"

namespace lisfm {
namespace colmap {

enum class ModelFormat { kBinary, kText };

// Reads cameras/images/points3D .bin (preferred) or .txt from `folder`, plus
// rigs.bin / frames.bin when present, and validates the result.
Reconstruction ReadModel(const std::string& folder, ModelFormat* format = nullptr);
Reconstruction ReadModelBinary(const std::string& folder);
Reconstruction ReadModelText(const std::string& folder);
// True when `folder` holds a binary (or text) model.
bool HasModel(const std::string& folder, ModelFormat format);

// Create `folder` if needed and write the three files (and rigs.bin /
// frames.bin for a binary model with rigs or frames).
void WriteModelBinary(const Reconstruction& reconstruction, const std::string& folder);
void WriteModelText(const Reconstruction& reconstruction, const std::string& folder);
void WriteModel(const Reconstruction& reconstruction,
                const std::string& folder,
                ModelFormat format);

// Single files (the readers add to `reconstruction`; read cameras before images).
void ReadCamerasBinary(const std::string& path, Reconstruction* reconstruction);
void ReadImagesBinary(const std::string& path, Reconstruction* reconstruction);
void ReadPoints3DBinary(const std::string& path, Reconstruction* reconstruction);
void ReadRigsBinary(const std::string& path, Reconstruction* reconstruction);
void ReadFramesBinary(const std::string& path, Reconstruction* reconstruction);
void ReadCamerasText(const std::string& path, Reconstruction* reconstruction);
void ReadImagesText(const std::string& path, Reconstruction* reconstruction);
void ReadPoints3DText(const std::string& path, Reconstruction* reconstruction);

// File contents as COLMAP writes them (used by the writers and tests).
std::string CamerasBinary(const Reconstruction& reconstruction);
std::string ImagesBinary(const Reconstruction& reconstruction);
std::string Points3DBinary(const Reconstruction& reconstruction);
std::string RigsBinary(const Reconstruction& reconstruction);
std::string FramesBinary(const Reconstruction& reconstruction);
std::string CamerasText(const Reconstruction& reconstruction);
std::string ImagesText(const Reconstruction& reconstruction);
std::string Points3DText(const Reconstruction& reconstruction);

// COLMAP 3.8 `model_converter --output_type PLY`: binary little-endian PLY,
// float x y z + uchar red green blue per 3D point.
void WritePly(const Reconstruction& reconstruction, const std::string& path);

}  // namespace colmap
}  // namespace lisfm

// Point cloud files: PCD (ascii, binary, binary_compressed) and PLY (ascii,
// binary little/big endian) in, PCD (binary or ascii) and binary little-endian
// PLY out, parsed here from the file's bytes (one read; binary bodies decoded
// in place, LZF for binary_compressed; 3-10x faster than PCL's readers on
// LiDAR scans, and no PCL io in the executable: its VTK dependencies cost
// ~0.03 s of dynamic loading at every process start). cloud_io_pcl.h reads
// the same files through PCL's readers, the reference the tests compare with.
//
// Fields (by name; any other field in a file is ignored):
//   x y z       required, any numeric type, converted to float32 metres;
//   intensity   optional (missing -> 0), any numeric type -> float32;
//   t           optional (missing -> 0), float32/float64 seconds since the scan
//               stamp (DESIGN.md "Time"). Only the name `t` is read, and only
//               as a floating-point type: `time`, `timestamp`, `offset_time`
//               and integer `t` (Ouster: uint32 ns) have sensor-specific units
//               and epochs, so they are never reinterpreted; an integer `t` is
//               an InputError (convert such files in an importer instead);
//   ring        optional (missing -> 0), integer value in [0, 65535];
//   sensor_id   optional (missing -> 0), integer value in [0, 255].
// A file with only x y z (and e.g. rgb or normals) loads with zero attributes.
// Every field read must have COUNT 1.
//
// Written fields: `x y z intensity t ring` (float32 x5, uint16) -- the
// sequence-folder format of DESIGN.md -- plus `sensor_id` (uint8) only when
// some point has a non-zero sensor_id (merged multi-LiDAR clouds). Since a
// missing sensor_id reads as 0, every attribute survives a write/read round
// trip bit-exactly (ascii PCD writes 9 significant digits, enough for float32).
// Written clouds are unorganised (WIDTH = N, HEIGHT = 1, identity VIEWPOINT).
//
// Organised clouds (HEIGHT > 1) are read row-major with all WIDTH*HEIGHT
// points, NaN points included, so the layout survives; use RemoveNonFinite()
// (core/point_cloud.h) before geometry. The PCD VIEWPOINT is ignored.
//
// Time stamps: PointCloud::stamp_ns is NOT stored in the file (a binary PCD has
// no place for it). Readers return stamp_ns = 0; the stamp lives in the file
// name (`lidarK/data/<ns>.pcd`, DESIGN.md "Formats") and the caller sets it.
//
// Failures: a missing, empty, truncated or malformed file, an unknown
// extension, a missing x/y/z field or an out-of-range attribute throws one
// InputError naming the path (and the header line or point record). The PCD
// header and body are validated before anything is decoded (the checks were
// written against PCL 1.13, which crashes on some malformed PCDs, e.g. an empty
// file, and silently accepts non-numeric ascii tokens). Writers throw
// InputError when the output cannot be written; output appears atomically
// (temporary name + rename).
//
// Threads: the functions are reentrant.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

#include "core/point_cloud.h"

namespace lisfm {

PointCloud ReadPcd(const std::string& path);
// `binary` = false writes DATA ascii (human-readable, ~3x larger, slower).
void WritePcd(const std::string& path, const PointCloud& cloud, bool binary = true);

PointCloud ReadPly(const std::string& path);
// Always binary_little_endian 1.0, a single `vertex` element.
void WritePly(const std::string& path, const PointCloud& cloud);

// Dispatch on the extension, case-insensitive: .pcd or .ply; anything else is
// an InputError naming the path.
PointCloud ReadPointCloud(const std::string& path);
void WritePointCloud(const std::string& path, const PointCloud& cloud);

// The positions of the finite points of a .pcd or .ply file, in file order (what
// registration needs), and how many non-finite points were dropped (may be
// null). Binary and binary_compressed PCDs are decoded straight into the
// positions after the same header validation and errors as ReadPcd; their other
// fields are neither read nor checked. Every other file goes through
// ReadPointCloud (all of its checks). Same positions as ReadPointCloud followed
// by dropping non-finite points.
std::vector<Eigen::Vector3f> ReadPointPositions(const std::string& path,
                                                size_t* num_non_finite = nullptr);

}  // namespace lisfm

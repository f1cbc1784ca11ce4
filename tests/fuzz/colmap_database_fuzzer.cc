// Fuzz target colmap_database: the bytes of a COLMAP database (SQLite) file,
// opened read-only with colmap::Database and read the way database_info and
// global_mapper read it (cameras, images with their priors, keypoints,
// matches, two-view geometries, rigs and frames).
#include <cstddef>
#include <cstdint>
#include <string>

#include "colmap_ext/io/database.h"
#include "core/errors.h"
#include "tests/fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  lisfm::fuzz::RemoveScratch("database.db-wal");
  lisfm::fuzz::RemoveScratch("database.db-shm");
  lisfm::fuzz::RemoveScratch("database.db-journal");
  const std::string path = lisfm::fuzz::WriteScratchFile("database.db", data, size);
  try {
    lisfm::colmap::Database database(path, lisfm::colmap::Database::OpenMode::kReadOnly);
    for (const char* table : {"cameras", "images", "keypoints", "matches", "two_view_geometries"}) {
      database.CountRows(table);
    }
    database.ReadAllCameras();
    for (const lisfm::colmap::DbImage& image : database.ReadAllImages()) {
      database.ReadKeypoints(image.image_id);
      database.ReadDescriptors(image.image_id);
    }
    database.ReadAllNumMatches();
    database.ReadAllMatches();
    database.ReadAllTwoViewGeometries();
    database.ReadRigs();
    database.ReadFrames();
  } catch (const lisfm::InputError&) {
    // A clean rejection of bad input.
  }
  return 0;
}

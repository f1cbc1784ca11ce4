# The dependency arrows of DESIGN.md, one entry per product library:
#   "<folder>|<target>|<folders it may use>"
# Read by the top-level CMakeLists.txt (lisfm_check_layering: every lisfm_*
# library links only what its entry allows) and by cmake/CheckIncludes.cmake
# (the ctest "layering/includes": every #include of a source file names a
# folder its module may use). Test support (<module>/testing, tests/), tests
# and bench/ may use every library; nothing but apps/ includes apps/.
set(LISFM_LAYERS
  "core|lisfm_core|"
  "core/io|lisfm_core_io|core"
  "core/mpi|lisfm_mpi|core"
  "icp|lisfm_icp|core core/io"
  "lio|lisfm_lio|core core/io icp"
  "lio/pose_slam|lisfm_pose_slam|core core/io icp lio"
  "colmap_ext/io|lisfm_colmap_io|core core/io"
  "colmap_ext/sfm|lisfm_colmap_sfm|core core/io colmap_ext/io"
  "importers|lisfm_importers|core core/io icp colmap_ext/io"
  "sim|lisfm_sim|core core/io"
)

# Folders of test support, tests and benchmarks (they may include any product
# folder and each other, never apps/).
set(LISFM_TEST_FOLDERS icp/testing colmap_ext/testing importers/testing tests/common tests/e2e tests/fuzz tests/integration
    bench)

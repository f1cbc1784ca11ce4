# Shared compile flags, per-module include roots, the layering check and the
# lisfm_add_test() helper.

function(lisfm_target_flags target)
  target_compile_options(${target} PRIVATE -Wall -Wextra)
  if(LISFM_WERROR)
    target_compile_options(${target} PRIVATE -Werror)
  endif()
  if(LISFM_ASAN)
    target_compile_options(${target} PRIVATE -fsanitize=address -fno-omit-frame-pointer)
    target_link_options(${target} PRIVATE -fsanitize=address)
  endif()
endfunction()

# lisfm_module_headers(<target>)
# Gives <target> an include root of its own, <build>/include_roots/<target>,
# holding symbolic links <folder>/<x>.h to the headers of the current source
# folder (not of its subfolders). A library exposes the root PUBLIC (an
# INTERFACE library INTERFACE, an executable PRIVATE), so `#include "<folder>/x.h"`
# compiles only in targets that link <target>: an include of a module that the
# target does not link fails to compile. No target sees the source tree itself.
function(lisfm_module_headers target)
  file(RELATIVE_PATH rel ${LISFM_SOURCE_DIR} ${CMAKE_CURRENT_SOURCE_DIR})
  set(root ${CMAKE_BINARY_DIR}/include_roots/${target})
  file(REMOVE_RECURSE ${root})
  file(MAKE_DIRECTORY ${root}/${rel})
  file(GLOB headers CONFIGURE_DEPENDS RELATIVE ${CMAKE_CURRENT_SOURCE_DIR}
       ${CMAKE_CURRENT_SOURCE_DIR}/*.h)
  foreach(header ${headers})
    file(CREATE_LINK ${CMAKE_CURRENT_SOURCE_DIR}/${header} ${root}/${rel}/${header} SYMBOLIC)
  endforeach()
  get_target_property(type ${target} TYPE)
  if(type STREQUAL "INTERFACE_LIBRARY")
    target_include_directories(${target} INTERFACE ${root})
  elseif(type STREQUAL "EXECUTABLE")
    target_include_directories(${target} PRIVATE ${root})
  else()
    target_include_directories(${target} PUBLIC ${root})
  endif()
endfunction()

# lisfm_check_layering(): fails the configure step when a product library
# links a lisfm_* library that its LISFM_LAYERS entry (cmake/Layering.cmake)
# does not allow, or links a test-support library.
function(lisfm_check_layering)
  set(folder_targets "")
  foreach(entry ${LISFM_LAYERS})
    string(REPLACE "|" ";" fields "${entry}")
    list(GET fields 0 folder)
    list(GET fields 1 target)
    set(target_of_${folder} ${target})
  endforeach()
  foreach(entry ${LISFM_LAYERS})
    string(REPLACE "|" ";" fields "${entry}")
    list(LENGTH fields n)
    list(GET fields 0 folder)
    list(GET fields 1 target)
    set(allowed "")
    if(n GREATER 2)
      list(GET fields 2 deps)
      string(REPLACE " " ";" deps "${deps}")
      foreach(dep ${deps})
        list(APPEND allowed ${target_of_${dep}})
      endforeach()
    endif()
    if(NOT TARGET ${target})
      message(FATAL_ERROR "layering: ${target} (${folder}/) is listed in cmake/Layering.cmake "
                          "but not defined")
    endif()
    get_target_property(links ${target} LINK_LIBRARIES)
    get_target_property(interface_links ${target} INTERFACE_LINK_LIBRARIES)
    foreach(link ${links} ${interface_links})
      string(REGEX REPLACE "^\\$<LINK_ONLY:(.*)>$" "\\1" link "${link}")
      if(link MATCHES "^lisfm" AND NOT link IN_LIST allowed)
        message(FATAL_ERROR "layering: ${target} (${folder}/) links ${link}, which DESIGN.md's "
                            "dependency arrows do not allow (allowed: ${allowed}; "
                            "cmake/Layering.cmake)")
      endif()
    endforeach()
  endforeach()
endfunction()

# lisfm_add_test(NAME x_test SRCS a.cc b.cc LINK_LIBS lib... [LABELS slow] [RUNS_LISFM])
# Registers the ctest "<folder>/x_test" where <folder> is the current folder
# relative to the source root. RUNS_LISFM: the test runs the `lisfm`
# executable, so building the test builds lisfm first (never a stale binary).
function(lisfm_add_test)
  cmake_parse_arguments(T "RUNS_LISFM" "NAME" "SRCS;LINK_LIBS;LABELS" ${ARGN})
  if(NOT LISFM_TESTS_ENABLED)
    return()
  endif()
  file(RELATIVE_PATH rel ${LISFM_SOURCE_DIR} ${CMAKE_CURRENT_SOURCE_DIR})
  string(REPLACE "/" "_" module_id "${rel}")
  set(exe "${module_id}_${T_NAME}")
  add_executable(${exe} ${T_SRCS})
  target_link_libraries(${exe} PRIVATE ${T_LINK_LIBS} lisfm_test_main)
  lisfm_target_flags(${exe})
  if(T_RUNS_LISFM)
    add_dependencies(${exe} lisfm)
  endif()
  add_test(NAME "${rel}/${T_NAME}" COMMAND ${exe})
  set_tests_properties("${rel}/${T_NAME}" PROPERTIES
    ENVIRONMENT "LISFM_TEST_DATA_DIR=${LISFM_SHARED_DATA_DIR};LISFM_SOURCE_DIR=${LISFM_SOURCE_DIR};LISFM_BINARY=$<TARGET_FILE:lisfm>")
  if(T_LABELS)
    set_tests_properties("${rel}/${T_NAME}" PROPERTIES LABELS "${T_LABELS}")
  endif()
endfunction()

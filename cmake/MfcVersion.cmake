# The version header, <build>/generated/mfcd/version.hpp (from cmake/version.hpp.in): the project's
# version and the git commit's short hash ("unknown" outside a git checkout), computed when the
# build is configured: a later commit shows after the next configure. Not tracked per commit on
# purpose: a new hash relinks every program, and a new mfc-teach re-teaches the development parts'
# templates (tools/teach/CMakeLists.txt), on every commit. Programs read it through mfc_version, tools/common/build_version.hpp: a library
# of every area, so defined here; only its one file recompiles when the commit changes.
include_guard(GLOBAL)

# Runs git in the source tree; `out` is its output, empty when git fails.
function(mfc_git out)
  execute_process(COMMAND ${GIT_EXECUTABLE} ${ARGN} WORKING_DIRECTORY ${PROJECT_SOURCE_DIR}
                  OUTPUT_VARIABLE text OUTPUT_STRIP_TRAILING_WHITESPACE RESULT_VARIABLE status ERROR_QUIET)
  if(NOT status EQUAL 0)
    set(text "")
  endif()
  set(${out} "${text}" PARENT_SCOPE)
endfunction()

set(MFC_GIT_COMMIT unknown)
find_package(Git QUIET)
if(GIT_FOUND)
  mfc_git(commit rev-parse --short HEAD)
  if(commit MATCHES "^[0-9a-f]+$")
    set(MFC_GIT_COMMIT ${commit})
  endif()
endif()

configure_file(${CMAKE_CURRENT_LIST_DIR}/version.hpp.in ${PROJECT_BINARY_DIR}/generated/mfcd/version.hpp @ONLY)
add_library(mfc_version STATIC ${PROJECT_SOURCE_DIR}/tools/common/build_version.cpp)
target_include_directories(mfc_version PUBLIC ${PROJECT_SOURCE_DIR} PRIVATE ${PROJECT_BINARY_DIR}/generated)
target_link_libraries(mfc_version PRIVATE mfc_warnings)

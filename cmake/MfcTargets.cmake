# Small helpers so every folder declares its libraries, tests and benchmarks the same way.
include_guard(GLOBAL)
include(GoogleTest)

# mfc_test(NAME SOURCES a.cpp b.cpp LIBS lib1 lib2 [LABELS label] [RESOURCE_LOCK name])
# One GoogleTest executable; each TEST() becomes its own ctest entry. RESOURCE_LOCK: tests that
# share something exclusive (a UDP port) never run at the same time under ctest -j.
function(mfc_test name)
  cmake_parse_arguments(T "" "RESOURCE_LOCK" "SOURCES;LIBS;LABELS" ${ARGN})
  add_executable(${name} ${T_SOURCES})
  target_link_libraries(${name} PRIVATE ${T_LIBS} GTest::gtest GTest::gtest_main mfc_warnings)
  target_compile_definitions(${name} PRIVATE MFC_SOURCE_DIR="${PROJECT_SOURCE_DIR}"
                             MFC_BINARY_DIR="${PROJECT_BINARY_DIR}")
  # A test that uses up the process's file descriptors skips under UBSan (MFC_UBSAN): its vptr
  # check probes memory through pipe(), which then fails, and it reports a false "invalid vptr".
  if(MFC_SANITIZE MATCHES "undefined")
    target_compile_definitions(${name} PRIVATE MFC_UBSAN=1)
  endif()
  # Under ThreadSanitizer, OpenMP regions run on one thread: libgomp is not instrumented, so TSan
  # cannot see its barriers and would report its own synchronisation as races.
  if(MFC_SANITIZE MATCHES "thread")
    set(props ENVIRONMENT "OMP_NUM_THREADS=1")
  else()
    set(props ENVIRONMENT "OMP_NUM_THREADS=2")
  endif()
  if(T_LABELS)
    # gtest_discover_tests writes PROPERTIES into its generated script unquoted, so a second
    # label would be read as a property name: one label per test executable.
    list(LENGTH T_LABELS n)
    if(n GREATER 1)
      message(FATAL_ERROR "mfc_test(${name}): one label only (got ${T_LABELS})")
    endif()
    list(APPEND props LABELS "${T_LABELS}")
  endif()
  if(T_RESOURCE_LOCK)
    list(APPEND props RESOURCE_LOCK "${T_RESOURCE_LOCK}")
  endif()
  gtest_discover_tests(${name} DISCOVERY_TIMEOUT 60 PROPERTIES ${props})
endfunction()

# mfc_benchmark(NAME SOURCES a.cpp LIBS lib1)
function(mfc_benchmark name)
  if(NOT MFC_BUILD_BENCHMARKS)
    return()
  endif()
  cmake_parse_arguments(B "" "" "SOURCES;LIBS" ${ARGN})
  add_executable(${name} ${B_SOURCES})
  target_link_libraries(${name} PRIVATE ${B_LIBS} benchmark::benchmark mfc_warnings)
  set_target_properties(${name} PROPERTIES RUNTIME_OUTPUT_DIRECTORY ${PROJECT_BINARY_DIR}/bench)
endfunction()

# Every program's command line: CLI11 (Debian's libcli11-dev, header-only, tools/deps/core.txt)
# and the project's conventions on it, tools/common/cli.hpp (--help, --version, exit status 2 on a
# usage error). Programs link mfc_cli.
include_guard(GLOBAL)
include(MfcVersion)

find_package(CLI11 2.1 CONFIG REQUIRED)
add_library(mfc_cli INTERFACE)
target_include_directories(mfc_cli INTERFACE ${PROJECT_SOURCE_DIR})
target_link_libraries(mfc_cli INTERFACE CLI11::CLI11 mfc_version)

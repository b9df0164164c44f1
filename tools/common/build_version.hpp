#pragma once
// Which build this is: the version and commit of <build>/generated/mfcd/version.hpp (generated at
// configure time, cmake/MfcVersion.cmake), read through one compiled file so that a new commit
// recompiles that file alone, not every program that reports the version.
namespace mfcd {

// project(mfcd VERSION ...) of the top-level CMakeLists.txt, e.g. "0.1.0".
const char* version();
// The short hash of the commit the source tree was at when the build was configured; "unknown"
// when the source is not a git checkout.
const char* git_commit();

}  // namespace mfcd

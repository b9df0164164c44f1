#include "tools/common/build_version.hpp"

#include "mfcd/version.hpp"

namespace mfcd {

const char* version() { return kVersion; }
const char* git_commit() { return kGitCommit; }

}  // namespace mfcd

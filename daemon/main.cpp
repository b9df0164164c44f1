// mfcd: the vision daemon of the bin-picking cell (docs/operations.md).
#include "daemon/daemon.hpp"

int main(int argc, char** argv) { return mfcd::daemon::daemon_main(argc, argv, mfcd::daemon::make_pipeline_stage); }

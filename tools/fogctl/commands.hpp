#pragma once
// fogctl's commands: each cmd_*.cpp defines one, with its usage text; main.cpp lists them.
#include <string>

namespace fogmap::cli {

struct Command {
  std::string name;
  std::string synopsis;  // its line in `fogctl --help`
  std::string usage;     // `fogctl NAME --help`
  int (*run)(int argc, char** argv);  // the process exit code: 0 ok, 1 failure, 2 usage error
};

Command clusterCommand();
Command benchCommand();
Command demoCommand();
Command evalCommand();
Command trackEvalCommand();
Command overlayCommand();
Command upCommand();
Command downCommand();
Command watchCommand();
Command geofenceCommand();
Command faultsCommand();
Command certsCommand();
Command composeCommand();
Command topologyCommand();
Command sceneCommand();
Command splitCommand();
Command trainClassifierCommand();
Command viewCommand();

}  // namespace fogmap::cli

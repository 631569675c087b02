#pragma once
// fogctl subcommands; each returns the process exit code (0 ok, 1 failure, 2 usage error).
namespace fogmap::cli {

int runCluster(int argc, char** argv);
int runBench(int argc, char** argv);
int runUp(int argc, char** argv);
int runDown(int argc, char** argv);
int runTopology(int argc, char** argv);
int runSplit(int argc, char** argv);
int runWatch(int argc, char** argv);
int runGeofence(int argc, char** argv);
int runDemo(int argc, char** argv);
int runFaults(int argc, char** argv);
int runCerts(int argc, char** argv);
int runCompose(int argc, char** argv);
int runScene(int argc, char** argv);
int runEval(int argc, char** argv);
int runTrackEval(int argc, char** argv);
int runOverlay(int argc, char** argv);

}  // namespace fogmap::cli

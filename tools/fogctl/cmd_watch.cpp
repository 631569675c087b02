// fogctl watch: the root's global maps (or a tracker's tracks) as they come.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <optional>
#include <set>
#include <string>

#include <grpcpp/grpcpp.h>

#include "fogmap/v1/fogmap.grpc.pb.h"
#include "common/base/angles.hpp"
#include "common/base/clock.hpp"
#include "harness/epoch_latency.hpp"
#include "harness/launcher.hpp"
#include "services/common/grpc_options.hpp"
#include "services/common/proto_convert.hpp"
#include "services/common/stream_follow.hpp"
#include "tools/fogctl/args.hpp"
#include "tools/fogctl/commands.hpp"

namespace fogmap::cli {
namespace {

using harness::endToEndLatencyMs;
using harness::installStopHandlers;
using harness::stopRequested;

// How long watch waits for the root to accept a connection when --timeout-s does not say.
constexpr double kConnectTimeoutS = 5.0;

void printGlobalMap(const v1::GlobalMap& message, long shown) {
  auto global = fromProto(message);
  if (!global) {
    std::fprintf(stderr, "fogctl: malformed global map: %s\n", global.error().message.c_str());
    return;
  }
  const auto& h = global->header;
  const std::optional<double> e2e_ms = endToEndLatencyMs(*global);
  char e2e[32] = "no sensor time";
  if (e2e_ms) std::snprintf(e2e, sizeof e2e, "%.1f ms", *e2e_ms);
  std::string contributing;
  for (const auto n : h.contributing_nodes) contributing += std::to_string(n) + " ";
  std::string missing;
  for (const auto n : h.missing_nodes) missing += std::to_string(n) + " ";
  std::printf("epoch %lu  objects %zu  ellipsoids %zu  merge %.3f ms  e2e %s  nodes [ %s]  missing [ %s]\n",
              static_cast<unsigned long>(h.epoch), global->map.objects.size(), global->map.ellipsoidCount(),
              global->merge_seconds * 1e3, e2e, contributing.c_str(), missing.c_str());
  // The largest objects first: position (box centre) and size (box extent) in metres.
  std::vector<const MapObject*> objects;
  for (const auto& o : global->map.objects) objects.push_back(&o);
  std::sort(objects.begin(), objects.end(), [](const MapObject* a, const MapObject* b) {
    return (a->box.max - a->box.min).prod() > (b->box.max - b->box.min).prod();
  });
  for (long k = 0; k < std::min<long>(shown, static_cast<long>(objects.size())); ++k) {
    const auto& o = *objects[static_cast<std::size_t>(k)];
    const Eigen::Vector3d c = 0.5 * (o.box.min + o.box.max);
    const Eigen::Vector3d s = o.box.max - o.box.min;
    std::set<std::uint32_t> nodes;
    for (const auto& e : o.ellipsoids) nodes.insert(e.node());
    std::string from;
    for (const auto n : nodes) from += std::to_string(n) + " ";
    std::printf("  object at (%7.2f, %7.2f, %5.2f) m  size %5.2f x %5.2f x %4.2f m  %zu ellipsoids from nodes [ %s]\n",
                c.x(), c.y(), c.z(), s.x(), s.y(), s.z(), o.ellipsoids.size(), from.c_str());
  }
  std::fflush(stdout);
}

void printTrackList(const v1::TrackList& message) {
  const double e2e_ms = nsToMs(message.published_time_ns() - message.lidar_time_ns());
  std::printf("tracks %d  association %s  e2e %.1f ms\n", message.tracks_size(), message.association().c_str(), e2e_ms);
  for (const auto& proto : message.tracks()) {
    const auto track = fromProto(proto);
    if (!track) {
      std::fprintf(stderr, "fogctl: malformed track: %s\n", track.error().message.c_str());
      continue;
    }
    char heading[32] = "";
    if (track->heading_rad) std::snprintf(heading, sizeof heading, "  heading %.0f deg", *track->heading_rad * kRadToDeg);
    std::printf("  track %4lu  %-10s %-9s at (%7.2f, %7.2f) m  velocity (%5.2f, %5.2f) m/s  sigma %.2f m%s%s\n",
                static_cast<unsigned long>(track->id), track->label.c_str(), tracking::trackStateName(track->state),
                track->position.x(), track->position.y(), track->velocity.x(), track->velocity.y(),
                std::sqrt(std::max(0.0, track->covariance.trace() / 2.0)), heading, track->camera_confirmed ? "  camera" : "");
  }
  std::fflush(stdout);
}

// Follows the stream until --count messages, Ctrl-C, --timeout-s without a message or its end,
// saying so after every --idle-s without one; `what` names the messages, `who` the server.
template <class Message>
int follow(grpc::ClientContext& context, grpc::ClientReaderInterface<Message>& reader, const std::function<void(const Message&)>& print,
           long count, double idle_s, double timeout_s, const std::string& what, const std::string& who) {
  FollowOptions options;
  options.count = count;
  options.idle_s = idle_s;
  options.timeout_s = timeout_s;
  options.stop = stopRequested;
  options.on_idle = [&](double silent_s) { std::fprintf(stderr, "fogctl: no %s from %s for %g s\n", what.c_str(), who.c_str(), silent_s); };
  const FollowResult result = followStream(context, reader, print, options);
  switch (result.end) {
    case FollowEnd::kCounted:
    case FollowEnd::kStopped:
      return 0;
    case FollowEnd::kGaveUp:
      std::fprintf(stderr, "fogctl: no %s from %s for %g s; giving up\n", what.c_str(), who.c_str(), timeout_s);
      return 1;
    case FollowEnd::kLost:
      break;
  }
  std::fprintf(stderr, "fogctl: lost %s: %s\n", who.c_str(), result.why.c_str());
  return 1;
}

int runWatch(int argc, char** argv) {
  const auto args = Args::parse(argc, argv, 2, {"target", "count", "objects", "idle-s", "timeout-s", "identity", "cert", "key", "ca"},
                                {"tracks"});
  if (!args) return fail(args.error());
  const bool tracks = args->has("tracks");
  const auto connection = rootConnection(
      *args, "fogctl watch TOPOLOGY.yaml | --target HOST:PORT [--tracks] [--count N] [--objects 10] [--idle-s 10] [--timeout-s 0]",
      tracks ? Role::kTracker : Role::kAggregator);
  if (!connection) return fail(connection.error());
  const std::string target = connection->target;
  const auto count = args->getInt("count", 0);
  const auto shown = args->getInt("objects", 10);
  if (!count || *count < 0 || !shown || *shown < 0) return fail(invalidArgument("--count and --objects must be non-negative"));
  const auto idle_s = args->getDouble("idle-s", 10.0);
  if (!idle_s || !(*idle_s > 0.0)) return fail(invalidArgument("--idle-s must be a positive number of seconds"));
  const auto timeout_s = args->getDouble("timeout-s", 0.0);
  if (!timeout_s || *timeout_s < 0.0) return fail(invalidArgument("--timeout-s must be a non-negative number of seconds"));
  installStopHandlers();
  const std::string who = std::string(tracks ? "the tracker" : "the root") + " at " + target;
  auto channel = makeChannel(target, connection->credentials, 64U << 20);
  if (const std::string problem = waitForChannel(*channel, *timeout_s > 0.0 ? *timeout_s : kConnectTimeoutS, stopRequested); !problem.empty()) {
    if (stopRequested()) return 0;
    std::fprintf(stderr, "fogctl: cannot reach %s: %s (is the cluster up?)\n", who.c_str(), problem.c_str());
    return 1;
  }
  grpc::ClientContext context;
  if (tracks) {
    auto stub = v1::TrackerService::NewStub(channel);
    v1::TrackSubscribeRequest request;
    auto reader = stub->Subscribe(&context, request);
    return follow<v1::TrackList>(context, *reader, printTrackList, *count, *idle_s, *timeout_s, "tracks", who);
  }
  auto stub = v1::GlobalMapService::NewStub(channel);
  v1::SubscribeRequest request;
  auto reader = stub->Subscribe(&context, request);
  const long objects = *shown;
  return follow<v1::GlobalMap>(
      context, *reader, [objects](const v1::GlobalMap& m) { printGlobalMap(m, objects); }, *count, *idle_s, *timeout_s,
      "global map", who);
}

}  // namespace

Command watchCommand() {
  return {"watch",
          "TOPOLOGY.yaml | --target HOST:PORT [--tracks] [--count N]   print the live global map or tracks",
          "usage: fogctl watch TOPOLOGY.yaml | --target HOST:PORT [--tracks] [--count N] [--objects 10] [--idle-s 10] [--timeout-s 0]\n"
          "                    [--identity NAME | --cert FILE --key FILE --ca FILE]\n"
          "Prints the root aggregator's global maps as they come. A root that is still starting is tried again\n"
          "until it answers; exits 1 when it cannot be reached within --timeout-s (default 5 s), when it goes\n"
          "away, or after --timeout-s without a map.\n"
          "  --tracks       the tracks of the topology's tracker (or of the tracker at --target) instead:\n"
          "                 id, label, state, position, velocity, and whether a camera confirmed it\n"
          "  --count N      stop after N maps (default 0: until Ctrl-C)\n"
          "  --objects N    objects listed per map, the largest first (default 10)\n"
          "  --idle-s S     say so after every S seconds without a global map (default 10)\n"
          "  --timeout-s S  give up after S seconds without a global map (default 0: never)\n" +
              std::string(kTlsFlagsUsage),
          runWatch};
}

}  // namespace fogmap::cli

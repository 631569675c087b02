// fogctl geofence: defines a box geofence on the root, or asks which objects are in the geofences.
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <sstream>
#include <string>
#include <vector>

#include <grpcpp/grpcpp.h>

#include "common/geometry/geofence.hpp"
#include "fogmap/v1/fogmap.grpc.pb.h"
#include "services/common/grpc_options.hpp"
#include "services/common/proto_convert.hpp"
#include "tools/fogctl/args.hpp"
#include "tools/fogctl/commands.hpp"

namespace fogmap::cli {
namespace {

// "a,b,c,d,e,f": exactly `count` finite numbers separated by commas.
Expected<std::vector<double>> numberList(const std::string& text, std::size_t count, const std::string& flag) {
  std::vector<double> out;
  std::stringstream in(text);
  std::string item;
  while (std::getline(in, item, ',')) {
    char* end = nullptr;
    const double v = std::strtod(item.c_str(), &end);
    if (item.empty() || end != item.c_str() + item.size() || !std::isfinite(v)) {
      return invalidArgument(flag + ": '" + item + "' is not a number");
    }
    out.push_back(v);
  }
  if (out.size() != count) return invalidArgument(flag + " expects " + std::to_string(count) + " numbers separated by commas");
  return out;
}

int runGeofence(int argc, char** argv) {
  const std::string usage =
      "fogctl geofence set TOPOLOGY.yaml | --target HOST:PORT --name NAME --box XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX\n"
      "       fogctl geofence query TOPOLOGY.yaml | --target HOST:PORT [--name NAME]";
  if (argc < 3 || (std::string(argv[2]) != "set" && std::string(argv[2]) != "query")) {
    return fail(invalidArgument("usage: " + usage));
  }
  const bool set = std::string(argv[2]) == "set";
  const auto args = Args::parse(argc, argv, 3, {"target", "name", "box", "identity", "cert", "key", "ca"}, {});
  if (!args) return fail(args.error());
  const auto connection = rootConnection(*args, usage);
  if (!connection) return fail(connection.error());
  const std::string& target = connection->target;
  auto stub = v1::GlobalMapService::NewStub(makeChannel(target, connection->credentials, 64U << 20));
  grpc::ClientContext context;
  context.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(10));

  if (set) {
    if (!args->has("name") || !args->has("box")) return fail(invalidArgument("usage: " + usage));
    const auto box = numberList(args->get("box"), 6, "--box");
    if (!box) return fail(box.error());
    const Eigen::Vector3d lo((*box)[0], (*box)[1], (*box)[2]);
    const Eigen::Vector3d hi((*box)[3], (*box)[4], (*box)[5]);
    if ((lo.array() >= hi.array()).any()) return fail(invalidArgument("--box: the minimum must be below the maximum on every axis"));
    v1::SetGeofenceReply reply;
    const grpc::Status status = stub->SetGeofence(&context, toProto(boxGeofence(args->get("name"), lo, hi)), &reply);
    if (!status.ok()) return fail(fromGrpcStatus(status, "SetGeofence at " + target));
    std::printf("geofence '%s' set on %s (%u geofences)\n", args->get("name").c_str(), target.c_str(), reply.geofence_count());
    return 0;
  }
  v1::GeofenceQuery query;
  query.set_name(args->get("name"));
  v1::GeofenceReport report;
  const grpc::Status status = stub->QueryGeofences(&context, query, &report);
  if (!status.ok()) return fail(fromGrpcStatus(status, "QueryGeofences at " + target));
  if (report.epoch() == 0) {
    std::printf("no global map yet\n");
    return 0;
  }
  std::printf("epoch %lu: %d intrusions\n", static_cast<unsigned long>(report.epoch()), report.intrusions_size());
  for (const auto& hit : report.intrusions()) {
    const auto containment = fromProto(hit.containment());
    const auto& lo = hit.box().min();
    const auto& hi = hit.box().max();
    std::printf("%s object %u %s box [%.2f %.2f %.2f]..[%.2f %.2f %.2f] ellipsoids %d\n", hit.geofence().c_str(),
                hit.object_index(), containment ? containmentName(*containment) : "unknown", lo.x(), lo.y(), lo.z(), hi.x(), hi.y(), hi.z(),
                hit.ellipsoids_size());
  }
  return 0;
}

}  // namespace

Command geofenceCommand() {
  return {"geofence",
          "set|query TOPOLOGY.yaml | --target HOST:PORT [--name NAME] [--box XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX]",
          "usage: fogctl geofence set TOPOLOGY.yaml | --target HOST:PORT --name NAME --box XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX\n"
          "       fogctl geofence query TOPOLOGY.yaml | --target HOST:PORT [--name NAME]\n"
          "       (either one: [--identity NAME | --cert FILE --key FILE --ca FILE])\n"
          "set: defines (or replaces) a box geofence on the root aggregator; with TLS only the clients\n"
          "     the topology's tls.geofence_clients lists may.\n"
          "query: the objects of the latest global map inside or crossing the geofences (or the one named).\n" +
              std::string(kTlsFlagsUsage),
          runGeofence};
}

}  // namespace fogmap::cli

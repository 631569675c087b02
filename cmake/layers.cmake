# The folder map: which folder's code may include which (docs/design.md, "The house"). Each folder is
# one CMake target linking only what it may use; cmake/check_layers.cmake refuses, at build time, an
# include that crosses the map. A folder always uses itself, and otherwise only folders listed before it.
set(FOGMAP_FOLDERS
  common/base common/geometry common/perception common/io common/camera common/tracking
  common/config common/scoring common/certs common/sim common/classify
  protos
  services/common services/edge_cluster services/merge_aggregator services/detection services/tracker
  harness pictures view tools/fogctl
  bench fuzz tests)

# common/: pure domain libraries (no gRPC, protobuf or Prometheus).
set(FOGMAP_MAY_USE_common/base "")
set(FOGMAP_MAY_USE_common/geometry common/base)
set(FOGMAP_MAY_USE_common/perception common/base common/geometry)
set(FOGMAP_MAY_USE_common/io common/base common/geometry)
set(FOGMAP_MAY_USE_common/camera common/base)
set(FOGMAP_MAY_USE_common/tracking common/base common/camera common/geometry common/perception)
set(FOGMAP_MAY_USE_common/scoring common/base)
# The topology: every role's configuration (the camera's, the tracker's, pre-processing's).
set(FOGMAP_MAY_USE_common/config common/base common/camera common/geometry common/io common/perception common/tracking)
set(FOGMAP_MAY_USE_common/certs common/base common/config)
set(FOGMAP_MAY_USE_common/sim common/base common/camera common/config common/geometry common/perception common/tracking)
# LiDAR-only classification of a cluster's features.
set(FOGMAP_MAY_USE_common/classify common/base common/geometry common/perception)
set(FOGMAP_COMMON common/base common/geometry common/perception common/io common/camera common/tracking
  common/config common/scoring common/certs common/sim common/classify)

# The wire (generated from protos/), then the transport layer and the services: a service never
# uses another service.
set(FOGMAP_MAY_USE_protos "")
set(FOGMAP_MAY_USE_services/common ${FOGMAP_COMMON} protos)
foreach(service edge_cluster merge_aggregator detection tracker)
  set(FOGMAP_MAY_USE_services/${service} ${FOGMAP_COMMON} protos services/common)
endforeach()

# The harness runs clusters of the real binaries and scores them; it replays scans through the edge's
# pipeline (services/edge_cluster's core) for the in-process baseline. The pictures draw what the
# harness measured; fogctl is the command line over both.
set(FOGMAP_MAY_USE_harness ${FOGMAP_COMMON} protos services/common services/edge_cluster)
set(FOGMAP_MAY_USE_pictures ${FOGMAP_COMMON} harness services/edge_cluster)
# The live view subscribes to the root and a tracker as any client does, and serves a web page.
set(FOGMAP_MAY_USE_view ${FOGMAP_COMMON} protos services/common)
set(FOGMAP_MAY_USE_tools/fogctl ${FOGMAP_COMMON} protos services/common services/edge_cluster harness pictures view)

# Benchmarks, fuzz targets and tests may use anything they measure or check.
set(FOGMAP_EVERYTHING ${FOGMAP_COMMON} protos services/common services/edge_cluster services/merge_aggregator
  services/detection services/tracker harness pictures view)
set(FOGMAP_MAY_USE_bench ${FOGMAP_EVERYTHING})
set(FOGMAP_MAY_USE_fuzz ${FOGMAP_EVERYTHING})
set(FOGMAP_MAY_USE_tests ${FOGMAP_EVERYTHING})

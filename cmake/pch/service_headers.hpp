#pragma once
// The headers that every gRPC-facing unit of fogmap parses (the services' layer, the services, the
// harness, the pictures of runs, the view and fogctl), precompiled once and reused by those
// targets (cmake/fogmap_helpers.cmake, fogmap_use_pch). Only what a large share of them
// includes belongs here; a source still includes what it uses (the dev preset builds without it).
#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <span>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <grpcpp/grpcpp.h>
#include <nlohmann/json.hpp>
#include <prometheus/counter.h>
#include <prometheus/family.h>
#include <prometheus/gauge.h>
#include <prometheus/histogram.h>
#include <prometheus/registry.h>

#include "fogmap/v1/fogmap.grpc.pb.h"

#pragma once
// Stopping a civetweb server promptly (the metrics exposer, fogctl view's web server): civetweb
// sees a stop request only when its listening socket wakes it, every 2 s or at once on a
// connection. stopHttpServer runs `stop` (which stops the server and returns when it has) on its
// own thread and meanwhile makes complete requests to host:port (each answered without holding a
// worker) until it has returned; a few tries cover the moment before the stop request is made.
#include <functional>
#include <string>

namespace fogmap {

void stopHttpServer(const std::function<void()>& stop, const std::string& host, int port);

}  // namespace fogmap

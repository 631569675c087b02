#include "services/common/http_stop.hpp"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <unistd.h>

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <mutex>
#include <thread>

namespace fogmap {
namespace {

constexpr int kStopWakeTries = 100;
constexpr std::chrono::milliseconds kStopWakeInterval{20};

void wake(const std::string& host, int port) {
  const int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (fd < 0) return;
  const timeval timeout{0, 200'000};
  ::setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &timeout, sizeof timeout);
  ::setsockopt(fd, SOL_SOCKET, SO_SNDTIMEO, &timeout, sizeof timeout);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(static_cast<std::uint16_t>(port));
  if (::inet_pton(AF_INET, host.c_str(), &addr.sin_addr) != 1 || addr.sin_addr.s_addr == htonl(INADDR_ANY)) {
    addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  }
  if (::connect(fd, reinterpret_cast<const sockaddr*>(&addr), sizeof addr) == 0) {
    static constexpr char kRequest[] = "GET /stopping HTTP/1.0\r\n\r\n";
    if (::send(fd, kRequest, sizeof kRequest - 1, MSG_NOSIGNAL) > 0) {
      char answer[256];
      while (::recv(fd, answer, sizeof answer, 0) > 0) {
      }
    }
  }
  ::close(fd);
}

}  // namespace

void stopHttpServer(const std::function<void()>& stop, const std::string& host, int port) {
  std::mutex mutex;
  std::condition_variable stopped_cv;
  bool stopped = false;
  std::thread stopper([&] {
    stop();
    {
      std::lock_guard lock(mutex);
      stopped = true;
    }
    stopped_cv.notify_all();
  });
  std::unique_lock lock(mutex);
  for (int i = 0; i < kStopWakeTries && !stopped && port > 0; ++i) {
    lock.unlock();
    wake(host, port);
    lock.lock();
    stopped_cv.wait_for(lock, kStopWakeInterval, [&] { return stopped; });
  }
  lock.unlock();
  stopper.join();
}

}  // namespace fogmap

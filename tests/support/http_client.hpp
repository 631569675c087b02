#pragma once
// Plain HTTP on loopback for the view's tests: one request and its whole answer (status and body),
// and a Server-Sent-Events reader that parses events as they come. Every wait is bounded.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <cstdint>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace fogmap::test_support {

struct HttpAnswer {
  int status = 0;  // 0: no answer
  std::string headers;
  std::string body;
};

// A connected TCP socket to address:port, or -1.
inline int connectTo(const std::string& address, std::uint16_t port) {
  const int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (fd < 0) return -1;
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(port);
  ::inet_pton(AF_INET, address.c_str(), &addr.sin_addr);
  if (::connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0) {
    ::close(fd);
    return -1;
  }
  return fd;
}

inline bool sendRequest(int fd, const std::string& method, const std::string& path) {
  const std::string request = method + " " + path + " HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n\r\n";
  return ::send(fd, request.data(), request.size(), MSG_NOSIGNAL) == static_cast<ssize_t>(request.size());
}

// Appends what arrives on fd within `wait` (less when the peer closes); false once it has closed.
inline bool readSome(int fd, std::string& into, std::chrono::milliseconds wait) {
  pollfd p{fd, POLLIN, 0};
  if (::poll(&p, 1, static_cast<int>(wait.count())) != 1) return true;
  char buffer[65536];
  const ssize_t n = ::recv(fd, buffer, sizeof buffer, 0);
  if (n <= 0) return false;
  into.append(buffer, static_cast<std::size_t>(n));
  return true;
}

inline HttpAnswer splitAnswer(const std::string& raw) {
  HttpAnswer answer;
  const auto end = raw.find("\r\n\r\n");
  if (raw.rfind("HTTP/1.", 0) != 0 || end == std::string::npos) return answer;
  answer.status = std::stoi(raw.substr(9, 3));
  answer.headers = raw.substr(0, end);
  answer.body = raw.substr(end + 4);
  return answer;
}

// One request; the answer once the server closes the connection (within `timeout`).
inline HttpAnswer httpRequest(std::uint16_t port, const std::string& path, const std::string& method = "GET",
                              std::chrono::milliseconds timeout = std::chrono::seconds(10)) {
  const int fd = connectTo("127.0.0.1", port);
  if (fd < 0 || !sendRequest(fd, method, path)) {
    if (fd >= 0) ::close(fd);
    return {};
  }
  std::string raw;
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (std::chrono::steady_clock::now() < deadline && readSome(fd, raw, std::chrono::milliseconds(100))) {
  }
  ::close(fd);
  return splitAnswer(raw);
}

// Reads /events as a page does: the answer's status, then each event (name, data) as it comes.
class SseClient {
 public:
  explicit SseClient(std::uint16_t port) : fd_(connectTo("127.0.0.1", port)) {
    if (fd_ >= 0 && !sendRequest(fd_, "GET", "/events")) close();
  }
  ~SseClient() { close(); }
  SseClient(const SseClient&) = delete;
  SseClient& operator=(const SseClient&) = delete;

  bool connected() const { return fd_ >= 0; }
  void close() {
    if (fd_ >= 0) ::close(fd_);
    fd_ = -1;
  }
  int status() const { return status_; }

  // The next event whose name is `name` (any when empty), waiting up to `timeout`; none when the
  // stream ended or nothing came in time. Events of other names are passed over.
  std::optional<std::pair<std::string, std::string>> next(const std::string& name, std::chrono::milliseconds timeout) {
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    while (true) {
      while (auto event = parsed()) {
        if (name.empty() || event->first == name) return event;
      }
      if (fd_ < 0 || std::chrono::steady_clock::now() >= deadline) return std::nullopt;
      if (!readSome(fd_, buffer_, std::chrono::milliseconds(50))) {
        close();
        while (auto event = parsed()) {
          if (name.empty() || event->first == name) return event;
        }
        return std::nullopt;
      }
    }
  }

 private:
  std::optional<std::pair<std::string, std::string>> parsed() {
    if (status_ == 0) {
      const auto end = buffer_.find("\r\n\r\n");
      if (end == std::string::npos) return std::nullopt;
      status_ = splitAnswer(buffer_.substr(0, end + 4)).status;
      buffer_.erase(0, end + 4);
    }
    while (true) {
      const auto end = buffer_.find("\n\n");
      if (end == std::string::npos) return std::nullopt;
      const std::string block = buffer_.substr(0, end);
      buffer_.erase(0, end + 2);
      std::string name;
      std::string data;
      std::size_t at = 0;
      while (at <= block.size()) {
        auto line_end = block.find('\n', at);
        if (line_end == std::string::npos) line_end = block.size();
        const std::string line = block.substr(at, line_end - at);
        if (line.rfind("event: ", 0) == 0) name = line.substr(7);
        if (line.rfind("data: ", 0) == 0) data = line.substr(6);
        at = line_end + 1;
      }
      if (!name.empty()) return std::make_pair(name, data);  // "retry:" blocks and comments carry no event
    }
  }

  int fd_ = -1;
  int status_ = 0;
  std::string buffer_;
};

}  // namespace fogmap::test_support

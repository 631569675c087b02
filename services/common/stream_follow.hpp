#pragma once
// A client's side of a server stream, as a command line follows one (fogctl watch): waiting for
// the server to come up, then reading its messages with a watchdog that reports silence and gives
// up after a timeout. A silent server is reported, never waited on silently.
#include <functional>
#include <string>

#include <grpcpp/grpcpp.h>
#include <grpcpp/support/sync_stream.h>

namespace fogmap {

// Waits until `channel` is ready, at most `window_s` seconds: a refused connection is not final,
// since a server that is still starting (fogctl up, docker-compose up) is tried again with the
// channel's capped reconnect backoff. Returns an empty string when ready, else why not ("the
// connection failed within 5 s", "interrupted" once `stop` says so; `stop` may be empty and is
// asked at least every 100 ms).
std::string waitForChannel(grpc::Channel& channel, double window_s, const std::function<bool()>& stop = {});

struct FollowOptions {
  long count = 0;          // stop after this many messages (0: until the stream ends)
  double idle_s = 10.0;    // on_idle after every idle_s seconds without a message (positive)
  double timeout_s = 0.0;  // give up after this many seconds without a message (0: never)
  std::function<bool()> stop;                    // may be empty; asked every 50 ms: true ends the stream
  std::function<void(double silent_s)> on_idle;  // may be empty; silent_s = k x idle_s, k = 1, 2, ...
};

enum class FollowEnd {
  kCounted,  // count messages were read
  kStopped,  // stop() said so
  kGaveUp,   // timeout_s without a message
  kLost,     // the server ended the stream or it failed
};

struct FollowResult {
  FollowEnd end = FollowEnd::kLost;
  long messages = 0;
  std::string why;  // kLost: the stream's error, or "it ended the stream"
};

// Reads with `read_next` (false: the stream ended) until an end above; cancels `context` from a
// watchdog thread when stopped or timed out, and after `count` messages, then calls `finish` for
// the stream's status (a stream the server ended keeps its own).
FollowResult followStream(grpc::ClientContext& context, const std::function<bool()>& read_next,
                          const std::function<grpc::Status()>& finish, const FollowOptions& options);

// The same over a server-streaming reader, handing each message to `on_message`.
template <class Message>
FollowResult followStream(grpc::ClientContext& context, grpc::ClientReaderInterface<Message>& reader,
                          const std::function<void(const Message&)>& on_message, const FollowOptions& options) {
  Message message;
  return followStream(
      context,
      [&] {
        if (!reader.Read(&message)) return false;
        on_message(message);
        return true;
      },
      [&] { return reader.Finish(); }, options);
}

}  // namespace fogmap

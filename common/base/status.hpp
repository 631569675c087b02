#pragma once
// A small typed-error result: libraries return values or errors, never exit or print.
#include <cassert>
#include <string>
#include <utility>
#include <variant>

namespace fogmap {

enum class ErrorCode {
  kInvalidArgument,  // the input (file, message, config) is malformed
  kNotFound,         // a named resource does not exist
  kIo,               // the operating system refused a read or write
  kInternal,         // a bug or a broken invariant
  kResourceExhausted,  // a bound on size or count was reached (the input may be valid, but not here)
};

// The google.rpc.Code number of an error (what a gRPC status and an Ack's code carry):
// kInvalidArgument 3, kNotFound 5, kResourceExhausted 8, kInternal 13, kIo 14 (UNAVAILABLE).
// The one mapping; services/common/grpc_options turns it into grpc::StatusCode.
int rpcCode(ErrorCode code);

struct Error {
  ErrorCode code = ErrorCode::kInternal;
  std::string message;
};

inline Error invalidArgument(std::string message) { return {ErrorCode::kInvalidArgument, std::move(message)}; }
inline Error ioError(std::string message) { return {ErrorCode::kIo, std::move(message)}; }
inline Error notFound(std::string message) { return {ErrorCode::kNotFound, std::move(message)}; }
inline Error resourceExhausted(std::string message) { return {ErrorCode::kResourceExhausted, std::move(message)}; }

const char* errorCodeName(ErrorCode code);

// Expected<T>: either a T or an Error (std::expected arrives with C++23).
template <class T>
class [[nodiscard]] Expected {
 public:
  Expected(T value) : state_(std::move(value)) {}           // NOLINT: implicit by design
  Expected(Error error) : state_(std::move(error)) {}       // NOLINT: implicit by design

  bool ok() const { return std::holds_alternative<T>(state_); }
  explicit operator bool() const { return ok(); }
  T& value() & { assert(ok()); return std::get<T>(state_); }
  const T& value() const& { assert(ok()); return std::get<T>(state_); }
  T&& value() && { assert(ok()); return std::get<T>(std::move(state_)); }
  T* operator->() { return &value(); }
  const T* operator->() const { return &value(); }
  T& operator*() & { return value(); }
  const T& operator*() const& { return value(); }
  const Error& error() const { assert(!ok()); return std::get<Error>(state_); }

 private:
  std::variant<T, Error> state_;
};

// Status: success or an Error.
class [[nodiscard]] Status {
 public:
  Status() = default;
  Status(Error error) : error_(std::move(error)), ok_(false) {}  // NOLINT: implicit by design
  bool ok() const { return ok_; }
  explicit operator bool() const { return ok_; }
  const Error& error() const { return error_; }

 private:
  Error error_;
  bool ok_ = true;
};

}  // namespace fogmap

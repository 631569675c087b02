#include "common/base/status.hpp"

namespace fogmap {

const char* errorCodeName(ErrorCode code) {
  switch (code) {
    case ErrorCode::kInvalidArgument: return "invalid argument";
    case ErrorCode::kNotFound: return "not found";
    case ErrorCode::kIo: return "i/o error";
    case ErrorCode::kInternal: return "internal error";
    case ErrorCode::kResourceExhausted: return "resource exhausted";
  }
  return "unknown error";
}

int rpcCode(ErrorCode code) {
  switch (code) {
    case ErrorCode::kInvalidArgument: return 3;
    case ErrorCode::kNotFound: return 5;
    case ErrorCode::kResourceExhausted: return 8;
    case ErrorCode::kInternal: return 13;
    case ErrorCode::kIo: return 14;
  }
  return 13;
}

}  // namespace fogmap

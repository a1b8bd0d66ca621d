#pragma once
/// \file
/// The status the service's plain-C++ cores return: a code (the same numbers as gRPC's status
/// codes, so the handlers translate it one to one) and a message that says what to fix.
/// Nothing here includes gRPC.

#include <string>
#include <string_view>
#include <utility>

namespace gd::service {

/// Mirrors grpc::StatusCode (same values).
enum class Code {
  kOk = 0,
  kCancelled = 1,
  kUnknown = 2,
  kInvalidArgument = 3,
  kDeadlineExceeded = 4,
  kNotFound = 5,
  kAlreadyExists = 6,
  kPermissionDenied = 7,
  kResourceExhausted = 8,
  kFailedPrecondition = 9,
  kAborted = 10,
  kOutOfRange = 11,
  kUnimplemented = 12,
  kInternal = 13,
  kUnavailable = 14,
  kUnauthenticated = 16,
};

/// The upper-case gRPC name of a code ("INVALID_ARGUMENT"), for logs.
inline const char* code_name(Code c) {
  switch (c) {
    case Code::kOk: return "OK";
    case Code::kCancelled: return "CANCELLED";
    case Code::kUnknown: return "UNKNOWN";
    case Code::kInvalidArgument: return "INVALID_ARGUMENT";
    case Code::kDeadlineExceeded: return "DEADLINE_EXCEEDED";
    case Code::kNotFound: return "NOT_FOUND";
    case Code::kAlreadyExists: return "ALREADY_EXISTS";
    case Code::kPermissionDenied: return "PERMISSION_DENIED";
    case Code::kResourceExhausted: return "RESOURCE_EXHAUSTED";
    case Code::kFailedPrecondition: return "FAILED_PRECONDITION";
    case Code::kAborted: return "ABORTED";
    case Code::kOutOfRange: return "OUT_OF_RANGE";
    case Code::kUnimplemented: return "UNIMPLEMENTED";
    case Code::kInternal: return "INTERNAL";
    case Code::kUnavailable: return "UNAVAILABLE";
    case Code::kUnauthenticated: return "UNAUTHENTICATED";
  }
  return "UNKNOWN";
}

/// A message fit for a client and a log line: control characters escaped (a newline or an ANSI
/// escape from a request would split or colour the log), and at most about `limit` bytes (a
/// 100 KB garment name echoed back makes a 100 KB status): the head and the tail kept, since
/// messages end with what to fix.
inline std::string printable_message(std::string_view m, size_t limit = 1024) {
  auto escape = [](std::string_view in) {
    static const char* hex = "0123456789abcdef";
    std::string out;
    out.reserve(in.size());
    for (const char ch : in) {
      const auto u = static_cast<unsigned char>(ch);
      if (u == '\n') {
        out += "\\n";
      } else if (u == '\t') {
        out += "\\t";
      } else if (u < 0x20 || u == 0x7f) {
        out += "\\x";
        out += hex[u >> 4];
        out += hex[u & 15];
      } else {
        out += ch;
      }
    }
    return out;
  };
  if (m.size() <= limit) return escape(m);
  const size_t head = limit * 5 / 8, tail = limit / 4;
  return escape(m.substr(0, head)) + " [... " + std::to_string(m.size() - head - tail) + " bytes omitted ...] " +
         escape(m.substr(m.size() - tail));
}

/// A code and a message; default-constructed it is OK.
class Status {
 public:
  Status() = default;
  Status(Code code, std::string message) : code_(code), message_(std::move(message)) {}

  static Status Ok() { return {}; }
  static Status InvalidArgument(std::string m) { return {Code::kInvalidArgument, std::move(m)}; }
  static Status NotFound(std::string m) { return {Code::kNotFound, std::move(m)}; }
  static Status ResourceExhausted(std::string m) { return {Code::kResourceExhausted, std::move(m)}; }
  static Status FailedPrecondition(std::string m) { return {Code::kFailedPrecondition, std::move(m)}; }
  static Status Unavailable(std::string m) { return {Code::kUnavailable, std::move(m)}; }
  static Status Internal(std::string m) { return {Code::kInternal, std::move(m)}; }
  static Status Unauthenticated(std::string m) { return {Code::kUnauthenticated, std::move(m)}; }

  bool ok() const { return code_ == Code::kOk; }
  Code code() const { return code_; }
  const std::string& message() const { return message_; }

 private:
  Code code_ = Code::kOk;
  std::string message_;
};

}  // namespace gd::service

/// Returns the status of an expression from the enclosing function when it is not OK.
#define GD_RETURN_IF_ERROR(expr)                      \
  do {                                                \
    ::gd::service::Status _gd_st = (expr);            \
    if (!_gd_st.ok()) return _gd_st;                  \
  } while (0)

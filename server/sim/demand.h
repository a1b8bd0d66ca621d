#pragma once
/// \file
/// GD_DEMAND: invariants of the library. A failed invariant is a bug, not bad input: it logs the
/// condition and location and aborts. Bad user input throws gd::sim::InputError instead.

#include <stdexcept>
#include <string>

namespace gd::sim {

/// Thrown when a caller passes something that cannot be simulated; the message says what to fix.
class InputError : public std::invalid_argument {
 public:
  explicit InputError(const std::string& what) : std::invalid_argument(what) {}
};

/// Thrown when a backend's device fails (a kernel that cannot launch, a fault reported by the
/// runtime, device memory exhausted): the scene's step fails with the message (Scene::failure),
/// other scenes go on where the device still can.
class BackendError : public std::runtime_error {
 public:
  explicit BackendError(const std::string& what) : std::runtime_error(what) {}
};

[[noreturn]] void demand_failed(const char* cond, const char* file, int line, const std::string& msg);

}  // namespace gd::sim

#define GD_DEMAND(cond, msg)                                                  \
  do {                                                                        \
    if (!(cond)) ::gd::sim::demand_failed(#cond, __FILE__, __LINE__, (msg));  \
  } while (0)

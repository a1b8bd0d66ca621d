#include "sim/backend/round_trips.h"

namespace gd::sim {

HostRoundTrips& host_round_trips() {
  thread_local HostRoundTrips counts;
  return counts;
}

}  // namespace gd::sim

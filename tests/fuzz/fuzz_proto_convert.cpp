// libFuzzer target: the service's request conversion (server/service/convert.cpp). The first
// byte picks the message (mod 4: CreateScenesRequest, StepScenesRequest, SubmitJobRequest, Array),
// the rest is its wire format as a gRPC handler receives it: ParseFromArray, then to_scene_spec /
// to_step_request / to_job_spec, or decode_vec3 and decode_indices for an Array. Expected: a
// refused parse, an OK Status or a non-OK Status; none of them throws.

#include <google/protobuf/stubs/logging.h>

#include "fuzz_common.h"
#include "service/convert.h"

namespace pb = gd::service::pb;
using gd::service::Status;

namespace {

/// A decoded array has the rows its shape names, and an OK decode the bytes they need.
void check_decoded(const pb::Array& a, const Status& s, size_t rows, size_t cols) {
  if (!s.ok()) {
    GD_FUZZ_CHECK(s.code() == gd::service::Code::kInvalidArgument, "a refused Array must be INVALID_ARGUMENT");
    return;
  }
  GD_FUZZ_CHECK(rows * cols * 4 == a.data().size(), "decoded rows do not match the data size");
  GD_FUZZ_CHECK(rows == 0 || (a.shape_size() > 0 && int64_t(rows) == a.shape(0)), "decoded rows do not match the shape");
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  gd::fuzz::quiet_logs();
  // protobuf logs an ERROR line for every string field with invalid UTF-8 it refuses to parse.
  google::protobuf::SetLogHandler(nullptr);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0) return 0;
  const int kind = data[0] % 4;
  const uint8_t* msg = data + 1;
  const int len = static_cast<int>(std::min<size_t>(size - 1, INT32_MAX));
  gd::fuzz::no_exceptions([&] {
    switch (kind) {
      case 0: {
        pb::CreateScenesRequest r;
        if (!r.ParseFromArray(msg, len)) return;
        gd::service::SceneSpec spec;
        const Status s = gd::service::to_scene_spec(r, &spec);
        (void)gd::service::to_grpc(s);
        if (s.ok()) GD_FUZZ_CHECK(spec.garment_params.size() == size_t(r.garment_params_size()), "garment_params");
        break;
      }
      case 1: {
        pb::StepScenesRequest r;
        if (!r.ParseFromArray(msg, len)) return;
        gd::service::StepRequest req;
        const Status s = gd::service::to_step_request(r, &req);
        (void)gd::service::to_grpc(s);
        if (s.ok()) {
          GD_FUZZ_CHECK(req.actions.size() == size_t(r.actions_size()), "actions");
          for (size_t k = 0; k < req.actions.size(); ++k) {
            const auto& a = req.actions[k];
            GD_FUZZ_CHECK(!a.scene_id.empty(), "an action without scene_id was accepted");
            GD_FUZZ_CHECK(a.arms.size() == size_t(r.actions(int(k)).arms_size()), "arms");
          }
        }
        break;
      }
      case 2: {
        pb::SubmitJobRequest r;
        if (!r.ParseFromArray(msg, len)) return;
        gd::service::JobSpec spec;
        const Status s = gd::service::to_job_spec(r, &spec);
        (void)gd::service::to_grpc(s);
        if (s.ok()) GD_FUZZ_CHECK(spec.trajectory == r.trajectory(), "trajectory");
        break;
      }
      case 3: {
        pb::Array a;
        if (!a.ParseFromArray(msg, len)) return;
        std::vector<gd::sim::Vec3> v;
        check_decoded(a, gd::service::decode_vec3(a, "fuzz", &v), v.size(), 3);
        std::vector<int> idx;
        check_decoded(a, gd::service::decode_indices(a, "fuzz", &idx), idx.size(), 1);
        break;
      }
    }
  });
  return 0;
}

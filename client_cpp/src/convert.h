#pragma once
/// \file
/// Translation between the plain structs of gd/client.h and the generated garmentdynamics.v1
/// messages. Private to gd_client (it includes the generated headers). Decoding checks dtype and
/// shape and throws ClientError(INTERNAL) naming the field when the server sent something else;
/// encoding throws ClientError(INVALID_ARGUMENT) for arrays of the wrong length.

#include <string>
#include <vector>

#include "garmentdynamics/v1/garmentdynamics.pb.h"
#include "gd/client.h"

namespace gd::client_detail {

namespace pb = ::garmentdynamics::v1;

/// float32 (rows, 3) from `values` (size rows*3); `what` names the field in errors.
void encode_vec3_array(const std::vector<float>& values, pb::Array* out, const char* rpc, const char* what);
/// int32 (n,) from `values`.
void encode_index_array(const std::vector<int32_t>& values, pb::Array* out);
/// The elements of a float32 array whose last dimension is `cols` (0: any shape); empty array -> {}.
std::vector<float> decode_float_array(const pb::Array& a, int cols, const char* rpc, const char* what);
std::vector<int32_t> decode_int_array(const pb::Array& a, int cols, const char* rpc, const char* what);

void to_proto(const SceneSpec& in, pb::CreateScenesRequest* out);
void to_proto(const SceneAction& in, pb::SceneAction* out, const char* rpc);
void to_proto(const JobSpec& in, pb::SubmitJobRequest* out);

SceneState from_proto(const pb::SceneState& in, const char* rpc);
SceneInfo from_proto(const pb::SceneInfo& in, const char* rpc);
JobInfo from_proto(const pb::JobInfo& in);
UploadedMesh from_proto(const pb::UploadedMesh& in);
MaterialInfo from_proto(const pb::MaterialInfo& in);
ServerInfo from_proto(const pb::GetServerInfoResponse& in);

}  // namespace gd::client_detail

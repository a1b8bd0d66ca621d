#pragma once
/// \file
/// grpc.reflection.v1.ServerReflection for gd-server, beside gRPC's own v1alpha plugin (gRPC 1.51
/// has no v1; tools such as grpcurl ask for v1 first). Answers from the protobuf descriptors
/// compiled into the server: list_services, file_by_filename, file_containing_symbol,
/// file_containing_extension, all_extension_numbers_of_type; an unknown name gets an
/// error_response with NOT_FOUND, and the stream goes on. Like health and v1alpha it needs no
/// token: it describes only the published proto. Included only by server.cpp.

#include <string>
#include <vector>

#include "grpc/reflection/v1/reflection.grpc.pb.h"

namespace gd::service {

class ReflectionV1 final : public ::grpc::reflection::v1::ServerReflection::Service {
 public:
  /// `services`: the fully qualified names list_services answers with.
  explicit ReflectionV1(std::vector<std::string> services) : services_(std::move(services)) {}

  grpc::Status ServerReflectionInfo(
      grpc::ServerContext* ctx,
      grpc::ServerReaderWriter<::grpc::reflection::v1::ServerReflectionResponse,
                               ::grpc::reflection::v1::ServerReflectionRequest>* stream) override;

 private:
  std::vector<std::string> services_;
};

}  // namespace gd::service

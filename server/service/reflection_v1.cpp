#include "service/reflection_v1.h"

#include <google/protobuf/descriptor.h>
#include <google/protobuf/descriptor.pb.h>

#include <set>

namespace gd::service {
namespace {

namespace rv1 = ::grpc::reflection::v1;
using google::protobuf::DescriptorPool;
using google::protobuf::FileDescriptor;

/// The file and every file it imports, each once, serialized as FileDescriptorProto.
void add_file(const FileDescriptor* f, std::set<std::string>* sent, rv1::FileDescriptorResponse* out) {
  if (f == nullptr || !sent->insert(f->name()).second) return;
  google::protobuf::FileDescriptorProto proto;
  f->CopyTo(&proto);
  proto.SerializeToString(out->add_file_descriptor_proto());
  for (int i = 0; i < f->dependency_count(); ++i) add_file(f->dependency(i), sent, out);
}

void not_found(const std::string& what, rv1::ServerReflectionResponse* resp) {
  rv1::ErrorResponse* e = resp->mutable_error_response();
  e->set_error_code(static_cast<int>(grpc::StatusCode::NOT_FOUND));
  e->set_error_message(what);
}

/// The answer to one request.
void answer(const rv1::ServerReflectionRequest& req, const std::vector<std::string>& services,
            rv1::ServerReflectionResponse* resp) {
  const DescriptorPool* pool = DescriptorPool::generated_pool();
  resp->set_valid_host(req.host());
  *resp->mutable_original_request() = req;
  std::set<std::string> sent;
  auto file_of = [&](const FileDescriptor* f, const std::string& missing) {
    if (f == nullptr) return not_found(missing, resp);
    add_file(f, &sent, resp->mutable_file_descriptor_response());
  };
  switch (req.message_request_case()) {
    case rv1::ServerReflectionRequest::kListServices:
      for (const std::string& s : services) resp->mutable_list_services_response()->add_service()->set_name(s);
      return;
    case rv1::ServerReflectionRequest::kFileByFilename:
      return file_of(pool->FindFileByName(req.file_by_filename()), "no file '" + req.file_by_filename() + "'");
    case rv1::ServerReflectionRequest::kFileContainingSymbol:
      return file_of(pool->FindFileContainingSymbol(req.file_containing_symbol()),
                     "no symbol '" + req.file_containing_symbol() + "'");
    case rv1::ServerReflectionRequest::kFileContainingExtension: {
      const auto& x = req.file_containing_extension();
      const auto* type = pool->FindMessageTypeByName(x.containing_type());
      const auto* ext = type ? pool->FindExtensionByNumber(type, x.extension_number()) : nullptr;
      return file_of(ext ? ext->file() : nullptr, "no extension " + std::to_string(x.extension_number()) + " of '" +
                                                      x.containing_type() + "'");
    }
    case rv1::ServerReflectionRequest::kAllExtensionNumbersOfType: {
      const auto* type = pool->FindMessageTypeByName(req.all_extension_numbers_of_type());
      if (type == nullptr) return not_found("no type '" + req.all_extension_numbers_of_type() + "'", resp);
      std::vector<const google::protobuf::FieldDescriptor*> exts;
      pool->FindAllExtensions(type, &exts);
      auto* out = resp->mutable_all_extension_numbers_response();
      out->set_base_type_name(type->full_name());
      for (const auto* e : exts) out->add_extension_number(e->number());
      return;
    }
    default: {
      rv1::ErrorResponse* e = resp->mutable_error_response();
      e->set_error_code(static_cast<int>(grpc::StatusCode::INVALID_ARGUMENT));
      e->set_error_message("an empty or unknown reflection request");
    }
  }
}

}  // namespace

grpc::Status ReflectionV1::ServerReflectionInfo(
    grpc::ServerContext* ctx,
    grpc::ServerReaderWriter<rv1::ServerReflectionResponse, rv1::ServerReflectionRequest>* stream) {
  rv1::ServerReflectionRequest req;
  while (!ctx->IsCancelled() && stream->Read(&req)) {
    rv1::ServerReflectionResponse resp;
    answer(req, services_, &resp);
    if (!stream->Write(resp)) break;
  }
  return grpc::Status::OK;
}

}  // namespace gd::service

# gRPC and protobuf from Debian (libgrpc++-dev, protobuf-compiler-grpc, libprotobuf-dev).
find_package(Protobuf REQUIRED)
find_package(gRPC CONFIG REQUIRED)
if(NOT TARGET gRPC::grpc_cpp_plugin)
  message(FATAL_ERROR "gRPC's protoc plugin is missing: apt-get install protobuf-compiler-grpc")
endif()
find_package(SQLite3 REQUIRED)

// SPDX-License-Identifier: Apache-2.0
// gRPC answers a request it cannot parse (truncated, a wrong wire type,
// groups nested past protobuf's recursion limit) with INTERNAL and an empty
// message, before any handler runs. This interceptor turns that into what it
// is, the client's error: INVALID_ARGUMENT, saying why.
#pragma once

#include <grpcpp/support/server_interceptor.h>

#include <memory>

namespace erg::server {

std::unique_ptr<grpc::experimental::ServerInterceptorFactoryInterface>
malformed_request_interceptor();

}  // namespace erg::server

// SPDX-License-Identifier: Apache-2.0
#include "api/malformed_requests.h"

#include <string>

namespace erg::server {

namespace {

using grpc::experimental::InterceptionHookPoints;

class MalformedRequest final : public grpc::experimental::Interceptor {
 public:
  explicit MalformedRequest(grpc::experimental::ServerRpcInfo* info)
      : method_(info->method() ? info->method() : ""),
        // A client stream ends with a receive that has no message: only
        // single requests are known to be unparsed by a missing one.
        single_request_(info->type() == grpc::experimental::ServerRpcInfo::Type::UNARY ||
                        info->type() == grpc::experimental::ServerRpcInfo::Type::SERVER_STREAMING) {
  }

  void Intercept(grpc::experimental::InterceptorBatchMethods* m) override {
    // A request that did not deserialize reaches this hook without a message.
    if (m->QueryInterceptionHookPoint(InterceptionHookPoints::POST_RECV_MESSAGE) &&
        single_request_ && m->GetRecvMessage() == nullptr)
      unparsed_ = true;
    if (m->QueryInterceptionHookPoint(InterceptionHookPoints::PRE_SEND_STATUS)) {
      const grpc::Status st = m->GetSendStatus();
      if (unparsed_ ||
          (st.error_code() == grpc::StatusCode::INTERNAL && st.error_message().empty()))
        m->ModifySendStatus(grpc::Status(
            grpc::StatusCode::INVALID_ARGUMENT,
            "request: not a valid protobuf message for " + method_.substr(0, 128) +
                " (truncated, a wrong wire type, invalid UTF-8 in a string, or nested deeper "
                "than 100 levels)"));
    }
    m->Proceed();
  }

 private:
  std::string method_;
  bool single_request_;
  bool unparsed_ = false;
};

class Factory final : public grpc::experimental::ServerInterceptorFactoryInterface {
 public:
  grpc::experimental::Interceptor* CreateServerInterceptor(
      grpc::experimental::ServerRpcInfo* info) override {
    return new MalformedRequest(info);
  }
};

}  // namespace

std::unique_ptr<grpc::experimental::ServerInterceptorFactoryInterface>
malformed_request_interceptor() {
  return std::make_unique<Factory>();
}

}  // namespace erg::server

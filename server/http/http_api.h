// ergd's HTTP side (cpp-httplib): for dashboards and monitoring.
//   GET /                      the tenant's jobs: progress bars and the latest
//                              preview, refreshing itself every 5 s
//   GET /api/jobs              the tenant's jobs as JSON (protobuf JSON of
//                              erg.v1.Job, without the spec)
//   GET /api/jobs/ID           one job with its spec
//   GET /api/jobs/ID/preview.png   the latest preview
//   GET /metrics               Prometheus text format
//   GET /login                 a sign-in form that POSTs the token
//   POST /login (token=T)      sets a session cookie holding T (HttpOnly,
//                              SameSite=Strict, Secure under TLS) and
//                              redirects to / (303): browsers cannot send a
//                              bearer header on a page load
//   GET /login?token=T         the same in one link (T then shows in the URL)
// Every route but /login needs `Authorization: Bearer T` or that cookie; an
// unauthenticated GET / answers 401 with the sign-in form.
#pragma once

#include <memory>
#include <string>
#include <thread>

#include "auth/tokens.h"
#include "metrics/metrics.h"
#include "scheduler/job_manager.h"

namespace httplib {
class Server;
}

namespace erg::server {

class HttpApi {
 public:
  HttpApi(JobManager& manager, Tokens& tokens, Metrics& metrics, const std::string& tls_cert,
          const std::string& tls_key);
  ~HttpApi();
  // Binds host:port (throws when it cannot) and serves on a thread.
  void start(const std::string& host, int port);
  void stop();

 private:
  JobManager& mgr_;
  Tokens& tokens_;
  Metrics& metrics_;
  std::unique_ptr<httplib::Server> server_;
  std::thread thread_;
  bool tls_ = false;
};

}  // namespace erg::server

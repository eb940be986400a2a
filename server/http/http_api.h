// SPDX-License-Identifier: Apache-2.0
// ergd's HTTP side: for dashboards and monitoring.
//   GET /                      the tenant's jobs: progress bars and the latest
//                              preview, refreshing itself every 5 s
//   GET /api/jobs              the tenant's jobs as JSON (protobuf JSON of
//                              erg.v1.Job, without the spec)
//   GET /api/jobs/ID           one job with its spec
//   GET /api/jobs/ID/preview.png[?step=S]   the latest preview (or step S's)
//   GET /api/jobs/ID/events    the job's events (JSON array of erg.v1.JobEvent)
//   GET /api/jobs/ID/relief    relief at each snapshot [{step, time_days, relief_m}]
//   POST /api/jobs/ID/cancel   CancelJob; POST /api/jobs/ID/steer (an Event or
//                              an array, protobuf JSON): SteerJob
//   GET /jobs/ID               the job page (server/http/assets/job.js):
//                              preview, snapshot slider, plots, events, controls
//   GET /?state=S              the list filtered by state
//   GET /static/job.js, /static/dashboard.css   the page's own assets
//   GET /metrics               Prometheus text format: every series for an
//                              operator token, the tenant's own otherwise
//   GET /login                 a sign-in form that POSTs the token
//   POST /login (token=T)      opens a session: a cookie holding a random
//                              session id (HttpOnly, SameSite=Strict, Secure
//                              under TLS), then 303 to /; throttled per
//                              address, cross-site posts refused
//   GET /login?token=T         the same in one link (T then shows in the URL)
//   POST /logout               ends the session, clears the cookie, 303 to
//                              /login
// Every route but /login needs `Authorization: Bearer T` or a session; an
// unauthenticated GET / answers 401 with the sign-in form. Sockets, TLS,
// timeouts and connection caps are HttpFront's (http/front.h); httplib only
// parses and routes complete requests.
#pragma once

#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>

#include "auth/sessions.h"
#include "auth/throttle.h"
#include "auth/tokens.h"
#include "http/front.h"
#include "metrics/metrics.h"
#include "scheduler/job_manager.h"

namespace httplib {
struct Request;
struct Response;
}  // namespace httplib

namespace erg::server {

class HttpRouter;

class HttpApi {
 public:
  HttpApi(JobManager& manager, Tokens& tokens, Metrics& metrics, const std::string& tls_cert,
          const std::string& tls_key, FrontLimits limits = {});
  ~HttpApi();
  // Binds host:port (throws when it cannot) and serves on threads of its own.
  void start(const std::string& host, int port);
  void stop();

 private:
  // The caller's identity (bearer header or session cookie), or a 401 in res.
  std::optional<Identity> identity_of(const httplib::Request& req, httplib::Response& res);
  void add_auth_routes();
  void sign_in(const httplib::Request& req, const std::string& token, httplib::Response& res);
  std::string session_cookie(const std::string& value, bool clear) const;
  std::string relief_json(const erg::v1::Job& job);

  JobManager& mgr_;
  Tokens& tokens_;
  Metrics& metrics_;
  Sessions sessions_;
  SignInThrottle throttle_;
  std::unique_ptr<HttpRouter> router_;
  std::unique_ptr<HttpFront> front_;
  bool tls_ = false;
  std::mutex relief_mu_;
  std::map<std::string, std::map<std::int64_t, std::pair<double, double>>> relief_;
};

}  // namespace erg::server

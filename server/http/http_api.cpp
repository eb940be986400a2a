// SPDX-License-Identifier: Apache-2.0
#include "http/http_api.h"

#include <google/protobuf/util/json_util.h>
#include <httplib.h>
#include <sys/socket.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <functional>
#include <limits>
#include <optional>
#include <sstream>

#include "auth/request_checks.h"
#include "core/fields.h"
#include "dashboard_assets.h"
#include "io/io.h"

namespace erg::server {

namespace {

std::string html_escape(const std::string& s) {
  std::string o;
  for (char c : s) {
    switch (c) {
      case '&':
        o += "&amp;";
        break;
      case '<':
        o += "&lt;";
        break;
      case '>':
        o += "&gt;";
        break;
      case '"':
        o += "&quot;";
        break;
      case '\'':
        o += "&#39;";
        break;
      default:
        o += c;
    }
  }
  return o;
}

std::string job_json(erg::v1::Job job, bool with_spec) {
  if (!with_spec) job.clear_spec();
  std::string out;
  google::protobuf::util::JsonPrintOptions opt;
  opt.preserve_proto_field_names = true;
  opt.always_print_primitive_fields = true;
  (void)google::protobuf::util::MessageToJsonString(job, &out, opt);
  return out;
}

std::string message_json(const google::protobuf::Message& m) {
  std::string out;
  google::protobuf::util::JsonPrintOptions opt;
  opt.preserve_proto_field_names = true;
  (void)google::protobuf::util::MessageToJsonString(m, &out, opt);
  return out;
}

// The HTTP status of a refused call (the gRPC code of the same refusal).
int http_status(grpc::StatusCode c) {
  switch (c) {
    case grpc::StatusCode::NOT_FOUND:
      return 404;
    case grpc::StatusCode::INVALID_ARGUMENT:
      return 400;
    case grpc::StatusCode::PERMISSION_DENIED:
      return 403;
    case grpc::StatusCode::FAILED_PRECONDITION:
      return 409;
    case grpc::StatusCode::RESOURCE_EXHAUSTED:
      return 429;
    default:
      return 500;
  }
}

void refuse(httplib::Response& res, const ApiError& e) {
  res.status = http_status(e.code);
  res.set_content(std::string(e.what()) + "\n", "text/plain");
}

// The list page's state filters: ?state=NAME, as `erg jobs --state NAME`.
constexpr const char* kStateFilters[] = {"queued", "running", "succeeded", "failed", "cancelled"};

// The job page: a frame that server/http/assets/job.js fills from the API.
std::string job_page(const erg::v1::Job& j) {
  const std::string id = html_escape(j.id());
  std::ostringstream o;
  o << "<!doctype html>\n<html><head><meta charset=\"utf-8\"><title>erg job " << id
    << "</title>\n<link rel=\"stylesheet\" href=\"/static/dashboard.css\"></head>\n"
    << "<body data-job=\"" << id << "\">\n<p><a href=\"/\" id=\"all-jobs\">all jobs</a></p>\n"
    << "<h1>" << html_escape(j.spec().name().empty() ? j.id() : j.spec().name()) << " <small><code>"
    << id << "</code></small> <span id=\"state\"></span></h1>\n"
    << "<p id=\"summary\"></p>\n"
    << "<div id=\"controls\"><button id=\"cancel\" type=\"button\">Cancel job</button>"
    << "<textarea id=\"steer-event\" aria-label=\"steering event\">"
    << "{\"sand\": {\"x_m\": 20, \"y_m\": 40, \"radius_m\": 6, \"height\": 1.5}}</textarea> "
    << "<button id=\"steer\" type=\"button\">Steer</button> <span id=\"control-result\"></span>"
    << "</div>\n<figure><img id=\"preview\" alt=\"no preview yet\">"
    << "<figcaption id=\"preview-caption\"></figcaption></figure>\n"
    << "<label>snapshot <input type=\"range\" id=\"slider\" min=\"0\" max=\"0\" value=\"0\">"
    << "</label>\n<div id=\"plots\"></div>\n<h2>Events and steering</h2>\n"
    << "<table id=\"events\"></table>\n<script src=\"/static/job.js\"></script>\n</body></html>\n";
  return o.str();
}

constexpr const char* kSessionCookie = "erg_session";

std::string cookie_value(const httplib::Request& req, const std::string& name) {
  const std::string cookies = req.get_header_value("Cookie");
  const std::string key = name + "=";
  size_t p = 0;
  while ((p = cookies.find(key, p)) != std::string::npos) {
    if (p == 0 || cookies[p - 1] == ' ' || cookies[p - 1] == ';') {
      const size_t start = p + key.size();
      return cookies.substr(start, cookies.find(';', start) - start);
    }
    p += key.size();
  }
  return "";
}

const char* kPage = R"(<!doctype html>
<html><head><meta charset="utf-8"><meta http-equiv="refresh" content="5">
<title>erg jobs</title>
<style>
body{font-family:system-ui,sans-serif;margin:2em;color:#222}
table{border-collapse:collapse}td,th{padding:.35em .8em;border-bottom:1px solid #ddd;text-align:left}
.bar{width:220px;height:12px;background:#eee;border-radius:6px;overflow:hidden}
.bar>div{height:100%;background:#c8953a}
.QUEUED{color:#777}.RUNNING{color:#1a6}.SUCCEEDED{color:#26a}.FAILED{color:#c22}.CANCELLED{color:#a60}
img{height:96px;image-rendering:pixelated;border:1px solid #ccc}
</style></head><body>
)";

// The sign-in page: the token goes in a POST body, so it stays out of the
// address bar, the browser's history and the access logs of proxies.
const char* kLoginPage = R"(<!doctype html>
<html><head><meta charset="utf-8"><title>erg: sign in</title>
<style>body{font-family:system-ui,sans-serif;margin:2em;color:#222}
input{font:inherit;padding:.3em}</style></head><body>
<h1>erg</h1>
<form method="post" action="/login" id="login">
<label>Token <input type="password" name="token" autocomplete="current-password" required></label>
<button type="submit">Sign in</button>
</form>
<p>The bearer token from ergd's tokens file (<code>ERG_TOKEN</code>).</p>
</body></html>
)";

// A request the front read completely, as an httplib stream: httplib parses
// and routes it from memory and writes its answer into `out`.
class MemoryStream final : public httplib::Stream {
 public:
  MemoryStream(const std::string& in, int fd, std::string ip, int port)
      : in_(in), fd_(fd), ip_(std::move(ip)), port_(port) {}
  bool is_readable() const override { return pos_ < in_.size(); }
  bool is_writable() const override { return true; }
  ssize_t read(char* ptr, size_t size) override {
    const size_t n = std::min(size, in_.size() - pos_);
    std::copy_n(in_.data() + pos_, n, ptr);
    pos_ += n;
    return static_cast<ssize_t>(n);
  }
  ssize_t write(const char* ptr, size_t size) override {
    out.append(ptr, size);
    return static_cast<ssize_t>(size);
  }
  void get_remote_ip_and_port(std::string& ip, int& port) const override {
    ip = ip_;
    port = port_;
  }
  void get_local_ip_and_port(std::string& ip, int& port) const override {
    sockaddr_storage sa{};
    socklen_t len = sizeof sa;
    char host[64] = "";
    char serv[16] = "0";
    if (::getsockname(fd_, reinterpret_cast<sockaddr*>(&sa), &len) == 0)
      (void)::getnameinfo(reinterpret_cast<sockaddr*>(&sa), len, host, sizeof host, serv,
                          sizeof serv, NI_NUMERICHOST | NI_NUMERICSERV);
    ip = host;
    port = std::atoi(serv);
  }
  socket_t socket() const override { return fd_; }
  std::string out;

 private:
  const std::string& in_;
  size_t pos_ = 0;
  int fd_;
  std::string ip_;
  int port_;
};

// Same-origin check for state-changing requests (sign-in, sign-out): a
// browser sends Origin on a cross-origin POST, and Sec-Fetch-Site on
// modern ones; either naming another site is refused. Scripts (curl) send
// neither and pass.
bool same_origin(const httplib::Request& req, bool tls) {
  const std::string site = req.get_header_value("Sec-Fetch-Site");
  if (!site.empty() && site != "same-origin" && site != "none") return false;
  if (!req.has_header("Origin")) return true;
  const std::string want = std::string(tls ? "https://" : "http://") + req.get_header_value("Host");
  return req.get_header_value("Origin") == want;
}

}  // namespace

// httplib's routing, without its sockets: HttpFront reads the requests.
class HttpRouter : public httplib::Server {
 public:
  std::string handle(const std::string& request, int fd, const std::string& ip, int port) {
    MemoryStream s(request, fd, ip, port);
    bool closed = false;
    (void)process_request(s, true, closed, nullptr);
    return std::move(s.out);
  }
};

HttpApi::HttpApi(JobManager& manager, Tokens& tokens, Metrics& metrics, const std::string& cert,
                 const std::string& key, FrontLimits limits)
    : mgr_(manager),
      tokens_(tokens),
      metrics_(metrics),
      sessions_(tokens),
      router_(std::make_unique<HttpRouter>()),
      tls_(!cert.empty()) {
  front_ = std::make_unique<HttpFront>(
      limits,
      [this](const std::string& request, int fd, const std::string& ip, int port) {
        return router_->handle(request, fd, ip, port);
      },
      cert, key);
  add_auth_routes();
  auto& s = *router_;
  auto tenant_of = [this](const httplib::Request& req, httplib::Response& res) {
    auto who = identity_of(req, res);
    return who ? std::optional<std::string>(who->tenant) : std::nullopt;
  };

  // Operators see every series; a tenant sees only those of its own jobs.
  s.Get("/metrics", [this](const httplib::Request& req, httplib::Response& res) {
    auto who = identity_of(req, res);
    if (!who) return;
    res.set_content(who->is_operator ? metrics_.text() : metrics_.text_of_tenant(who->tenant),
                    "text/plain; version=0.0.4");
  });

  s.Get("/api/jobs", [this, tenant_of](const httplib::Request& req, httplib::Response& res) {
    auto tenant = tenant_of(req, res);
    if (!tenant) return;
    std::int64_t last = 0;
    std::string out = "[";
    bool first = true;
    for (auto& j : mgr_.list(*tenant, 0, 0, 1000, &last)) {
      if (!first) out += ',';
      out += job_json(j, false);
      first = false;
    }
    res.set_content(out + "]\n", "application/json");
  });

  s.Get(R"(/api/jobs/([A-Za-z0-9-]+))", [this, tenant_of](const httplib::Request& req,
                                                          httplib::Response& res) {
    auto tenant = tenant_of(req, res);
    if (!tenant) return;
    try {
      check_job_id(req.matches[1]);
      res.set_content(job_json(mgr_.get(*tenant, req.matches[1]), true) + "\n", "application/json");
    } catch (const ApiError& e) {
      res.status = 404;
      res.set_content(std::string(e.what()) + "\n", "text/plain");
    }
  });

  s.Get(R"(/api/jobs/([A-Za-z0-9-]+)/preview.png)",
        [this, tenant_of](const httplib::Request& req, httplib::Response& res) {
          auto tenant = tenant_of(req, res);
          if (!tenant) return;
          try {
            check_job_id(req.matches[1]);
            const auto job = mgr_.get(*tenant, req.matches[1]);
            std::int64_t step = job.progress().latest_snapshot_step();
            if (req.has_param("step")) {
              // Only a step the job wrote a snapshot at names a file.
              const std::string v = req.get_param_value("step");
              step = -1;
              for (auto s : job.snapshot_steps())
                if (std::to_string(s) == v) step = s;
              if (step < 0)
                throw ApiError(grpc::StatusCode::NOT_FOUND,
                               "no snapshot at step " + echo_id(v) + " of this job");
            }
            std::ifstream f(mgr_.preview_path(job.id(), step), std::ios::binary);
            if (step < 0 || !f) throw ApiError(grpc::StatusCode::NOT_FOUND, "no preview yet");
            std::stringstream ss;
            ss << f.rdbuf();
            res.set_header("Cache-Control", "no-store");
            res.set_content(ss.str(), "image/png");
          } catch (const ApiError& e) {
            res.status = 404;
            res.set_content(std::string(e.what()) + "\n", "text/plain");
          }
        });

  // A route about one of the caller's jobs: authenticated, the id checked,
  // a refused call answered with its HTTP status; a POST must come from
  // ergd's own pages (cross-site requests are refused).
  using JobHandler = std::function<void(const std::string& tenant, const std::string& id,
                                        const httplib::Request&, httplib::Response&)>;
  auto job_route = [this, tenant_of](bool post, JobHandler h) {
    return [this, tenant_of, post, h](const httplib::Request& req, httplib::Response& res) {
      if (post && !same_origin(req, tls_))
        return refuse(res,
                      ApiError(grpc::StatusCode::PERMISSION_DENIED, "cross-site request refused"));
      auto tenant = tenant_of(req, res);
      if (!tenant) return;
      try {
        check_job_id(req.matches[1]);
        h(*tenant, req.matches[1], req, res);
      } catch (const ApiError& e) {
        refuse(res, e);
      }
    };
  };

  // The job page and what it draws: the events (progress, states,
  // snapshots, steering, notes), the relief at each snapshot, the assets.
  s.Get(R"(/jobs/([A-Za-z0-9-]+))",
        job_route(false, [this](const std::string& tenant, const std::string& id,
                                const httplib::Request&, httplib::Response& res) {
          res.set_content(job_page(mgr_.get(tenant, id)), "text/html; charset=utf-8");
        }));
  s.Get("/static/job.js", [tenant_of](const httplib::Request& req, httplib::Response& res) {
    if (tenant_of(req, res)) res.set_content(assets::kJobJs, "text/javascript; charset=utf-8");
  });
  s.Get("/static/dashboard.css", [tenant_of](const httplib::Request& req, httplib::Response& res) {
    if (tenant_of(req, res)) res.set_content(assets::kDashboardCss, "text/css; charset=utf-8");
  });
  s.Get(R"(/api/jobs/([A-Za-z0-9-]+)/events)",
        job_route(false, [this](const std::string& tenant, const std::string& id,
                                const httplib::Request&, httplib::Response& res) {
          const auto job = mgr_.get(tenant, id);
          std::string out = "[";
          for (const auto& e : mgr_.store().events_after(job.id(), 0, 20000)) {
            if (out.size() > 1) out += ',';
            out += message_json(e);
          }
          res.set_content(out + "]\n", "application/json");
        }));
  s.Get(R"(/api/jobs/([A-Za-z0-9-]+)/relief)",
        job_route(false, [this](const std::string& tenant, const std::string& id,
                                const httplib::Request&, httplib::Response& res) {
          res.set_content(relief_json(mgr_.get(tenant, id)), "application/json");
        }));
  // Controls of the job page, for the job's own tenant (another tenant's id
  // is NOT_FOUND, as everywhere).
  s.Post(R"(/api/jobs/([A-Za-z0-9-]+)/cancel)",
         job_route(true, [this](const std::string& tenant, const std::string& id,
                                const httplib::Request&, httplib::Response& res) {
           const auto job = mgr_.cancel(tenant, id);
           res.set_content("cancel requested: " + erg::v1::JobState_Name(job.state()) + "\n",
                           "text/plain");
         }));
  s.Post(R"(/api/jobs/([A-Za-z0-9-]+)/steer)",
         job_route(true, [this](const std::string& tenant, const std::string& id,
                                const httplib::Request& req, httplib::Response& res) {
           // One erg.v1.Event or an array of them, as `erg steer`.
           const std::string& body = req.body;
           const auto first = body.find_first_not_of(" \t\r\n");
           const bool array = first != std::string::npos && body[first] == '[';
           erg::v1::SteerJobRequest parsed;
           const auto st = google::protobuf::util::JsonStringToMessage(
               "{\"events\": " + (array ? body : "[" + body + "]") + "}", &parsed);
           if (!st.ok() || parsed.events().empty()) {
             std::string why =
                 "the body must be an erg.v1.Event or an array of them in protobuf JSON";
             if (!st.ok()) {
               why += ": ";
               why += std::string(st.message());
             }
             throw ApiError(grpc::StatusCode::INVALID_ARGUMENT, why);
           }
           const std::vector<erg::v1::Event> events(parsed.events().begin(), parsed.events().end());
           const auto r = mgr_.steer(tenant, id, events);
           std::string out = "applied";
           for (const auto& e : r.applied()) {
             out += ' ';
             out += message_json(e);
           }
           res.set_content(out + "\n", "text/plain");
         }));

  s.Get("/", [this, tenant_of](const httplib::Request& req, httplib::Response& res) {
    auto tenant = tenant_of(req, res);
    if (!tenant) {
      // Still a 401 for scripts; a browser gets the sign-in form.
      res.set_content(kLoginPage, "text/html; charset=utf-8");
      return;
    }
    int state_filter = 0;  // JOB_STATE_UNSPECIFIED: every state
    const std::string want = req.has_param("state") ? req.get_param_value("state") : "";
    std::ostringstream filters;
    filters << "<p id=\"filters\">show: <a href=\"/\"" << (want.empty() ? " class=\"on\"" : "")
            << ">all</a>";
    for (const char* f : kStateFilters) {
      std::string upper = f;
      for (auto& c : upper) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
      if (want == f) {
        erg::v1::JobState st{};
        if (erg::v1::JobState_Parse(upper, &st)) state_filter = st;
      }
      filters << " <a href=\"/?state=" << f << "\"" << (want == f ? " class=\"on\"" : "") << ">"
              << f << "</a>";
    }
    filters << "</p>\n";
    std::ostringstream o;
    o << kPage << "<h1>erg jobs of " << html_escape(*tenant) << "</h1>\n"
      << filters.str()
      << "<form method=\"post\" action=\"/logout\" id=\"logout\"><button type=\"submit\">"
         "Sign out</button></form>\n<table id=\"jobs\">\n"
      << "<tr><th>job</th><th>name</th><th>state</th><th>progress</th><th>steps/s</th>"
         "<th>runs on</th><th>preview</th></tr>\n";
    std::int64_t last = 0;
    const auto jobs = mgr_.list(*tenant, state_filter, 0, 200, &last);
    for (const auto& j : jobs) {
      const auto& p = j.progress();
      const double frac = p.total_steps() > 0
                              ? static_cast<double>(p.step()) / static_cast<double>(p.total_steps())
                              : 0.0;
      const char* state = erg::v1::JobState_Name(j.state()).c_str();
      o << "<tr class=\"job\" data-job=\"" << html_escape(j.id()) << "\"><td><a href=\"/jobs/"
        << html_escape(j.id()) << "\"><code>" << html_escape(j.id()) << "</code></a></td><td>"
        << html_escape(j.spec().name()) << "</td><td class=\"" << state << "\">" << state
        << "</td><td><div class=\"bar\"><div "
        << "style=\"width:" << static_cast<int>(frac * 100) << "%\"></div></div>" << p.step()
        << " / " << p.total_steps();
      // Simulated time beside the steps, in the years the job page and the
      // snapshots use (physical when the wind is calibrated, else the
      // model's time_step_days label).
      char years[48];
      std::snprintf(years, sizeof years, "%.3g", p.time_days() / 365.25);
      o << "<br><span class=\"years\">" << years << " years</span></td><td>";
      char rate[32];
      std::snprintf(rate, sizeof rate, "%.2f", p.steps_per_s());
      o << rate << "</td><td class=\"launcher\">" << html_escape(j.launcher()) << " "
        << html_escape(j.launcher_id()) << " " << html_escape(j.launcher_state()) << "</td><td>";
      if (p.latest_snapshot_step() >= 0)
        o << "<img alt=\"preview of step " << p.latest_snapshot_step() << "\" src=\"/api/jobs/"
          << html_escape(j.id()) << "/preview.png?step=" << p.latest_snapshot_step()
          << "\" onload=\"this.dataset.loaded='1'\">";
      o << "</td></tr>\n";
    }
    o << "</table>\n";
    if (jobs.empty()) o << "<p>No jobs yet: <code>erg submit JOB.json</code>.</p>\n";
    o << "</body></html>\n";
    res.set_content(o.str(), "text/html; charset=utf-8");
  });
}

namespace {
// A snapshot's time and relief: from the ground range the worker reduced over
// its tiles (attributes: bytes, whatever the domain), or, in snapshots
// written before it did, from the layers. Empty: no cells.
std::optional<std::pair<double, double>> relief_of(const std::string& path) {
  const io::SnapshotMeta meta = io::read_snapshot_meta(path);
  if (std::isfinite(meta.ground_min_m) && std::isfinite(meta.ground_max_m))
    return std::pair{meta.time_days, meta.ground_max_m - meta.ground_min_m};
  const io::Snapshot snap = io::read_snapshot(path, true);
  const auto& b = snap[fields::kBedrock];
  const auto& sand = snap[fields::kSand];
  if (b.empty()) return std::nullopt;
  float lo = std::numeric_limits<float>::infinity(), hi = -lo;
  for (std::size_t i = 0; i < b.size() && i < sand.size(); ++i) {
    lo = std::min(lo, b[i] + sand[i]);
    hi = std::max(hi, b[i] + sand[i]);
  }
  return std::pair{snap.meta.time_days, static_cast<double>(hi - lo)};
}
}  // namespace

// Relief (highest minus lowest ground, bedrock + sand) of each snapshot of
// a job, read from its snapshot files once and kept: [{step, time_days,
// relief_m}]. A snapshot that cannot be read (deleted, being written) is
// left out.
std::string HttpApi::relief_json(const erg::v1::Job& job) {
  std::string out = "[";
  for (const std::int64_t step : job.snapshot_steps()) {
    std::pair<double, double> v;
    {
      std::lock_guard<std::mutex> lock(relief_mu_);
      auto& known = relief_[job.id()];
      if (auto it = known.find(step); it != known.end()) {
        v = it->second;
      } else {
        try {
          const std::optional<std::pair<double, double>> r =
              relief_of(mgr_.snapshot_path(job.id(), step));
          if (!r) continue;
          v = *r;
          known[step] = v;
        } catch (const std::exception&) {
          continue;
        }
      }
    }
    char item[128];
    std::snprintf(item, sizeof item, "%s{\"step\":%lld,\"time_days\":%.17g,\"relief_m\":%.9g}",
                  out.size() > 1 ? "," : "", static_cast<long long>(step), v.first, v.second);
    out += item;
  }
  return out + "]\n";
}

HttpApi::~HttpApi() {
  stop();
}

// ---- authentication: bearer tokens, sessions, sign-in and sign-out ---------

std::optional<Identity> HttpApi::identity_of(const httplib::Request& req, httplib::Response& res) {
  std::optional<Identity> who;
  if (req.has_header("Authorization"))
    who = tokens_.identity_of_header(req.get_header_value("Authorization"));
  else if (const std::string id = cookie_value(req, kSessionCookie); !id.empty())
    who = sessions_.identity(id);
  if (!who) {
    res.status = 401;
    res.set_header("WWW-Authenticate", "Bearer realm=\"ergd\"");
    // A missing token and a wrong one are told apart.
    res.set_content(req.has_header("Authorization")
                        ? "the token is not one of ergd's tokens (mistyped, or no longer in "
                          "ergd's tokens file)\n"
                    : cookie_value(req, kSessionCookie).empty()
                        ? "no token: a bearer token from ergd's tokens file is required\n"
                        : "the session has ended (ergd restarted, or it timed out); sign in "
                          "again\n",
                    "text/plain");
  }
  return who;
}

std::string HttpApi::session_cookie(const std::string& value, bool clear) const {
  return std::string(kSessionCookie) + "=" + value + "; Path=/; HttpOnly; SameSite=Strict" +
         (tls_ ? "; Secure" : "") + (clear ? "; Max-Age=0" : "");
}

void HttpApi::sign_in(const httplib::Request& req, const std::string& token,
                      httplib::Response& res) {
  if (const double wait = throttle_.wait_s(req.remote_addr); wait > 0) {
    res.status = 429;
    res.set_header("Retry-After", std::to_string(static_cast<int>(std::ceil(wait))));
    res.set_content("too many failed sign-ins from this address; try again in " +
                        std::to_string(static_cast<int>(std::ceil(wait))) + " s\n",
                    "text/plain");
    return;
  }
  auto session = token.empty() ? std::nullopt : sessions_.open(token);
  if (!session) {
    throttle_.failed(req.remote_addr);
    res.status = 401;
    res.set_content("unknown token\n", "text/plain");
    return;
  }
  res.set_header("Set-Cookie", session_cookie(*session, false));
  res.set_redirect("/", 303);
}

void HttpApi::add_auth_routes() {
  auto& s = *router_;
  auto cross_site = [](httplib::Response& res) {
    res.status = 403;
    res.set_content("cross-site request refused\n", "text/plain");
  };
  // GET /login shows the form; GET /login?token=T (for links and scripts)
  // signs in directly, at the cost of T in the URL.
  s.Get("/login", [this, cross_site](const httplib::Request& req, httplib::Response& res) {
    if (!req.has_param("token")) {
      res.set_content(kLoginPage, "text/html; charset=utf-8");
      return;
    }
    if (!same_origin(req, tls_)) return cross_site(res);
    sign_in(req, req.get_param_value("token"), res);
  });
  s.Post("/login", [this, cross_site](const httplib::Request& req, httplib::Response& res) {
    if (!same_origin(req, tls_)) return cross_site(res);
    sign_in(req, req.get_param_value("token"), res);
  });
  // Sign-out ends the session (the token stays valid) and clears the cookie.
  s.Post("/logout", [this, cross_site](const httplib::Request& req, httplib::Response& res) {
    if (!same_origin(req, tls_)) return cross_site(res);
    if (const std::string id = cookie_value(req, kSessionCookie); !id.empty()) sessions_.close(id);
    res.set_header("Set-Cookie", session_cookie("", true));
    res.set_redirect("/login", 303);
  });
}

void HttpApi::start(const std::string& host, int port) {
  front_->start(host, port);
}

void HttpApi::stop() {
  if (front_) front_->stop();
}

}  // namespace erg::server

#include "http/http_api.h"

#include <google/protobuf/util/json_util.h>
#include <httplib.h>

#include <chrono>
#include <fstream>
#include <sstream>

#include "auth/request_checks.h"

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

std::string cookie_token(const httplib::Request& req) {
  const std::string cookies = req.get_header_value("Cookie");
  const std::string key = "erg_token=";
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

}  // namespace

HttpApi::HttpApi(JobManager& manager, Tokens& tokens, Metrics& metrics, const std::string& cert,
                 const std::string& key)
    : mgr_(manager), tokens_(tokens), metrics_(metrics) {
  if (!cert.empty()) {
    server_ = std::make_unique<httplib::SSLServer>(cert.c_str(), key.c_str());
    tls_ = true;
  } else {
    server_ = std::make_unique<httplib::Server>();
  }
  auto& s = *server_;
  // The tenant of a request, or a 401 answer.
  auto tenant_of = [this](const httplib::Request& req, httplib::Response& res) {
    std::optional<std::string> who;
    if (req.has_header("Authorization"))
      who = tokens_.tenant_of_header(req.get_header_value("Authorization"));
    if (!who) {
      const std::string t = cookie_token(req);
      if (!t.empty()) who = tokens_.tenant_of_token(t);
    }
    if (!who) {
      res.status = 401;
      res.set_header("WWW-Authenticate", "Bearer realm=\"ergd\"");
      res.set_content("a bearer token from ergd's tokens file is required\n", "text/plain");
    }
    return who;
  };

  // Sign-in: a valid token becomes a session cookie and the browser goes on
  // to the dashboard (303: the next request is a GET).
  auto sign_in = [this](const std::string& token, httplib::Response& res) {
    if (token.empty() || !tokens_.tenant_of_token(token)) {
      res.status = 401;
      res.set_content("unknown token\n", "text/plain");
      return;
    }
    res.set_header("Set-Cookie", "erg_token=" + token + "; Path=/; HttpOnly; SameSite=Strict" +
                                     (tls_ ? "; Secure" : ""));
    res.set_redirect("/", 303);
  };
  // GET /login shows the form; GET /login?token=T (for links and scripts)
  // signs in directly, at the cost of T in the URL.
  s.Get("/login", [sign_in](const httplib::Request& req, httplib::Response& res) {
    if (!req.has_param("token")) {
      res.set_content(kLoginPage, "text/html; charset=utf-8");
      return;
    }
    sign_in(req.get_param_value("token"), res);
  });
  s.Post("/login", [sign_in](const httplib::Request& req, httplib::Response& res) {
    sign_in(req.get_param_value("token"), res);
  });

  s.Get("/metrics", [this, tenant_of](const httplib::Request& req, httplib::Response& res) {
    if (!tenant_of(req, res)) return;
    res.set_content(metrics_.text(), "text/plain; version=0.0.4");
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
            std::ifstream f(mgr_.preview_path(job.id(), job.progress().latest_snapshot_step()),
                            std::ios::binary);
            if (job.progress().latest_snapshot_step() < 0 || !f)
              throw ApiError(grpc::StatusCode::NOT_FOUND, "no preview yet");
            std::stringstream ss;
            ss << f.rdbuf();
            res.set_header("Cache-Control", "no-store");
            res.set_content(ss.str(), "image/png");
          } catch (const ApiError& e) {
            res.status = 404;
            res.set_content(std::string(e.what()) + "\n", "text/plain");
          }
        });

  s.Get("/", [this, tenant_of](const httplib::Request& req, httplib::Response& res) {
    auto tenant = tenant_of(req, res);
    if (!tenant) {
      // Still a 401 for scripts; a browser gets the sign-in form.
      res.set_content(kLoginPage, "text/html; charset=utf-8");
      return;
    }
    std::ostringstream o;
    o << kPage << "<h1>erg jobs of " << html_escape(*tenant) << "</h1>\n<table id=\"jobs\">\n"
      << "<tr><th>job</th><th>name</th><th>state</th><th>progress</th><th>steps/s</th>"
         "<th>runs on</th><th>preview</th></tr>\n";
    std::int64_t last = 0;
    const auto jobs = mgr_.list(*tenant, 0, 0, 200, &last);
    for (const auto& j : jobs) {
      const auto& p = j.progress();
      const double frac = p.total_steps() > 0
                              ? static_cast<double>(p.step()) / static_cast<double>(p.total_steps())
                              : 0.0;
      const char* state = erg::v1::JobState_Name(j.state()).c_str();
      o << "<tr class=\"job\" data-job=\"" << html_escape(j.id()) << "\"><td><code>"
        << html_escape(j.id()) << "</code></td><td>" << html_escape(j.spec().name())
        << "</td><td class=\"" << state << "\">" << state << "</td><td><div class=\"bar\"><div "
        << "style=\"width:" << static_cast<int>(frac * 100) << "%\"></div></div>" << p.step()
        << " / " << p.total_steps() << "</td><td>";
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

HttpApi::~HttpApi() {
  stop();
}

void HttpApi::start(const std::string& host, int port) {
  if (!server_->is_valid()) throw std::runtime_error("HTTP server: bad TLS certificate or key");
  if (!server_->bind_to_port(host.c_str(), port))
    throw std::runtime_error("cannot listen on " + host + ":" + std::to_string(port) + " (HTTP)");
  thread_ = std::thread([this] { server_->listen_after_bind(); });
}

void HttpApi::stop() {
  if (server_) server_->stop();
  if (thread_.joinable()) thread_.join();
}

}  // namespace erg::server

// SPDX-License-Identifier: Apache-2.0
#include "api/job_service.h"

#include <chrono>
#include <fstream>
#include <sstream>

#include "auth/request_checks.h"
#include "util/sha256.h"

namespace erg::server {

namespace {

constexpr std::int64_t kChunkBytes = 1 << 20;  // service.proto: at most 1 MiB

bool terminal(erg::v1::JobState s) {
  return s == erg::v1::SUCCEEDED || s == erg::v1::FAILED || s == erg::v1::CANCELLED;
}

const char* code_name(grpc::StatusCode c) {
  switch (c) {
    case grpc::StatusCode::OK:
      return "OK";
    case grpc::StatusCode::CANCELLED:
      return "CANCELLED";
    case grpc::StatusCode::INVALID_ARGUMENT:
      return "INVALID_ARGUMENT";
    case grpc::StatusCode::DEADLINE_EXCEEDED:
      return "DEADLINE_EXCEEDED";
    case grpc::StatusCode::NOT_FOUND:
      return "NOT_FOUND";
    case grpc::StatusCode::RESOURCE_EXHAUSTED:
      return "RESOURCE_EXHAUSTED";
    case grpc::StatusCode::FAILED_PRECONDITION:
      return "FAILED_PRECONDITION";
    case grpc::StatusCode::OUT_OF_RANGE:
      return "OUT_OF_RANGE";
    case grpc::StatusCode::UNAUTHENTICATED:
      return "UNAUTHENTICATED";
    case grpc::StatusCode::PERMISSION_DENIED:
      return "PERMISSION_DENIED";
    default:
      return "INTERNAL";
  }
}

// The snapshot step a request names: the latest, or one the job has.
std::int64_t snapshot_step(const erg::v1::Job& job, bool latest, std::int64_t step) {
  if (latest) {
    if (job.progress().latest_snapshot_step() < 0)
      throw ApiError(grpc::StatusCode::NOT_FOUND, "job " + job.id() + " has no snapshot yet");
    return job.progress().latest_snapshot_step();
  }
  for (auto s : job.snapshot_steps())
    if (s == step) return s;
  std::string have;
  for (auto s : job.snapshot_steps()) have += (have.empty() ? "" : ", ") + std::to_string(s);
  throw ApiError(grpc::StatusCode::NOT_FOUND,
                 "step: job " + job.id() + " has no snapshot at step " + std::to_string(step) +
                     " (it has: " + (have.empty() ? "none" : have) + ")");
}

}  // namespace

// An open stream re-checks its caller's token (the tokens file is re-read
// when it changes): a revoked token ends the stream within a second.
bool JobService::still_allowed(grpc::ServerContext* ctx, const std::string& tenant) {
  const auto& md = ctx->client_metadata();
  auto it = md.find("authorization");
  if (it == md.end()) return false;
  const auto who = tokens_.tenant_of_header(std::string(it->second.data(), it->second.size()));
  return who && *who == tenant;
}

const grpc::Status JobService::kRevoked(grpc::StatusCode::UNAUTHENTICATED,
                                        "the token was revoked (it is no longer in ergd's "
                                        "tokens file)");

template <class F>
grpc::Status JobService::call(const char* method, grpc::ServerContext* ctx, F&& body) {
  const auto t0 = std::chrono::steady_clock::now();
  grpc::Status status;
  std::string tenant;
  const auto& md = ctx->client_metadata();
  auto it = md.find("authorization");
  std::optional<std::string> who;
  if (it != md.end())
    who = tokens_.tenant_of_header(std::string(it->second.data(), it->second.size()));
  if (!who && it == md.end()) {
    status = grpc::Status(grpc::StatusCode::UNAUTHENTICATED,
                          "no token: every call needs a bearer token from ergd's tokens file "
                          "(metadata `authorization: Bearer TOKEN`)");
  } else if (!who) {
    const bool bearer = std::string(it->second.data(), it->second.size()).rfind("Bearer ", 0) == 0;
    status = grpc::Status(grpc::StatusCode::UNAUTHENTICATED,
                          bearer ? "the token is not one of ergd's tokens (mistyped, or no "
                                   "longer in ergd's tokens file)"
                                 : "the authorization metadata is not `Bearer TOKEN`");
  } else {
    try {
      status = body(*who);
    } catch (const ApiError& e) {
      status = grpc::Status(e.code, e.what());
    } catch (const std::exception& e) {
      status = grpc::Status(grpc::StatusCode::INTERNAL, e.what());
    }
  }
  metrics_.observe_rpc(
      method, std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
  if (!status.ok()) metrics_.rpc_error(method, code_name(status.error_code()));
  return status;
}

grpc::Status JobService::SubmitJob(grpc::ServerContext* ctx, const erg::v1::SubmitJobRequest* req,
                                   erg::v1::Job* out) {
  return call("SubmitJob", ctx, [&](const std::string& tenant) {
    *out = mgr_.submit(tenant, *req);
    return grpc::Status::OK;
  });
}

grpc::Status JobService::GetJob(grpc::ServerContext* ctx, const erg::v1::GetJobRequest* req,
                                erg::v1::Job* out) {
  return call("GetJob", ctx, [&](const std::string& tenant) {
    check_job_id(req->id());
    *out = mgr_.get(tenant, req->id());
    return grpc::Status::OK;
  });
}

grpc::Status JobService::ListJobs(grpc::ServerContext* ctx, const erg::v1::ListJobsRequest* req,
                                  erg::v1::ListJobsResponse* out) {
  return call("ListJobs", ctx, [&](const std::string& tenant) {
    int size = req->page_size() == 0 ? 50 : req->page_size();
    if (size < 1 || size > 1000)
      throw ApiError(
          grpc::StatusCode::INVALID_ARGUMENT,
          "page_size: " + std::to_string(req->page_size()) + " is out of range [0, 1000]");
    std::int64_t before = 0;
    if (!req->page_token().empty()) {
      try {
        before = std::stoll(req->page_token());
      } catch (...) {
        throw ApiError(grpc::StatusCode::INVALID_ARGUMENT, "page_token: not a token ListJobs gave");
      }
    }
    std::int64_t last = 0;
    auto jobs = mgr_.list(tenant, req->state(), before, size + 1, &last);
    if (static_cast<int>(jobs.size()) > size) {
      jobs.pop_back();
      out->set_next_page_token(std::to_string(mgr_.store().seq_of(jobs.back().id())));
    }
    for (auto& j : jobs) *out->add_jobs() = std::move(j);
    return grpc::Status::OK;
  });
}

grpc::Status JobService::CancelJob(grpc::ServerContext* ctx, const erg::v1::CancelJobRequest* req,
                                   erg::v1::Job* out) {
  return call("CancelJob", ctx, [&](const std::string& tenant) {
    check_job_id(req->id());
    *out = mgr_.cancel(tenant, req->id());
    return grpc::Status::OK;
  });
}

grpc::Status JobService::WatchJob(grpc::ServerContext* ctx, const erg::v1::WatchJobRequest* req,
                                  grpc::ServerWriter<erg::v1::JobEvent>* writer) {
  std::string tenant;
  grpc::Status st = call("WatchJob", ctx, [&](const std::string& t) {
    check_job_id(req->id());
    (void)mgr_.get(t, req->id());
    tenant = t;
    return grpc::Status::OK;
  });
  if (!st.ok()) return st;
  auto& store = mgr_.store();
  std::int64_t after = std::max<std::int64_t>(0, req->after_event_id());
  for (;;) {
    if (!still_allowed(ctx, tenant)) return kRevoked;
    const std::uint64_t gen = store.generation();
    auto events = store.events_after(req->id(), after, 256);
    bool ended = false;
    for (const auto& ev : events) {
      if (!writer->Write(ev)) return grpc::Status(grpc::StatusCode::CANCELLED, "client went away");
      after = ev.id();
      if (ev.kind_case() == erg::v1::JobEvent::kStateChanged && terminal(ev.state_changed()))
        ended = true;
    }
    if (ended) return grpc::Status::OK;
    if (events.empty()) {
      // Nothing new: a job already final when we caught up ends the stream.
      try {
        if (terminal(mgr_.get(tenant, req->id()).state()) &&
            store.events_after(req->id(), after, 1).empty())
          return grpc::Status::OK;
      } catch (const ApiError& e) {
        return grpc::Status(e.code, e.what());
      }
      if (ctx->IsCancelled()) return grpc::Status(grpc::StatusCode::CANCELLED, "cancelled");
      store.wait_events(gen, 1000);
    }
  }
}

grpc::Status JobService::StreamSnapshot(grpc::ServerContext* ctx,
                                        const erg::v1::StreamSnapshotRequest* req,
                                        grpc::ServerWriter<erg::v1::SnapshotChunk>* writer) {
  std::string path, tenant;
  std::int64_t step = 0, size = 0;
  std::string sha;
  grpc::Status st = call("StreamSnapshot", ctx, [&](const std::string& t) {
    tenant = t;
    check_job_id(req->id());
    const erg::v1::Job job = mgr_.get(tenant, req->id());
    step = snapshot_step(job, req->latest(), req->step());
    path = mgr_.snapshot_path(job.id(), step);
    std::ifstream probe(path, std::ios::binary | std::ios::ate);
    if (!probe)
      throw ApiError(grpc::StatusCode::NOT_FOUND,
                     "snapshot file of step " + std::to_string(step) + " is gone");
    size = static_cast<std::int64_t>(probe.tellg());
    if (req->offset() < 0 || req->offset() > size)
      throw ApiError(grpc::StatusCode::OUT_OF_RANGE, "offset: " + std::to_string(req->offset()) +
                                                         " is out of range [0, " +
                                                         std::to_string(size) + "]");
    sha = sha256_hex_of_file(path);
    return grpc::Status::OK;
  });
  if (!st.ok()) return st;
  std::ifstream f(path, std::ios::binary);
  f.seekg(req->offset());
  std::int64_t offset = req->offset();
  std::string buf(static_cast<size_t>(kChunkBytes), '\0');
  bool first = true;
  const std::string name = path.substr(path.rfind('/') + 1);
  do {
    if (!still_allowed(ctx, tenant)) return kRevoked;
    const std::int64_t want = std::min(kChunkBytes, size - offset);
    f.read(buf.data(), want);
    if (f.gcount() != want)
      return grpc::Status(grpc::StatusCode::INTERNAL, "short read of " + name);
    erg::v1::SnapshotChunk c;
    if (first) {
      c.set_size(size);
      c.set_step(step);
      c.set_sha256(sha);
      c.set_name(name);
      first = false;
    }
    c.set_offset(offset);
    c.set_data(buf.data(), static_cast<size_t>(want));
    if (!writer->Write(c)) return grpc::Status(grpc::StatusCode::CANCELLED, "client went away");
    metrics_.streamed(static_cast<double>(want));
    offset += want;
  } while (offset < size);
  return grpc::Status::OK;
}

grpc::Status JobService::GetPreview(grpc::ServerContext* ctx, const erg::v1::GetPreviewRequest* req,
                                    erg::v1::Preview* out) {
  return call("GetPreview", ctx, [&](const std::string& tenant) {
    check_job_id(req->id());
    const erg::v1::Job job = mgr_.get(tenant, req->id());
    const std::int64_t step = snapshot_step(job, req->latest(), req->step());
    std::ifstream f(mgr_.preview_path(job.id(), step), std::ios::binary);
    if (!f)
      throw ApiError(grpc::StatusCode::NOT_FOUND, "job " + job.id() + " has no preview at step " +
                                                      std::to_string(step) +
                                                      " (run.previews is off?)");
    std::stringstream ss;
    ss << f.rdbuf();
    out->set_step(step);
    out->set_png(ss.str());
    return grpc::Status::OK;
  });
}

grpc::Status JobService::SteerJob(grpc::ServerContext* ctx, const erg::v1::SteerJobRequest* req,
                                  erg::v1::SteerJobResponse* out) {
  return call("SteerJob", ctx, [&](const std::string& tenant) {
    check_job_id(req->id());
    *out = mgr_.steer(tenant, req->id(), {req->events().begin(), req->events().end()});
    return grpc::Status::OK;
  });
}

grpc::Status JobService::ResumeJob(grpc::ServerContext* ctx, const erg::v1::ResumeJobRequest* req,
                                   erg::v1::Job* out) {
  return call("ResumeJob", ctx, [&](const std::string& tenant) {
    check_job_id(req->id());
    *out = mgr_.resume(tenant, req->id());
    return grpc::Status::OK;
  });
}

}  // namespace erg::server

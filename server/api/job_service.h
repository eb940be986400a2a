// SPDX-License-Identifier: Apache-2.0
// erg.v1.JobService over gRPC (proto/erg/v1/service.proto): authenticates
// every call (bearer token -> tenant), maps JobManager errors to status
// codes, streams events and snapshot files, records metrics.
#pragma once

#include <grpcpp/grpcpp.h>

#include "auth/tokens.h"
#include "erg/v1/service.grpc.pb.h"
#include "metrics/metrics.h"
#include "scheduler/job_manager.h"

namespace erg::server {

class JobService final : public erg::v1::JobService::Service {
 public:
  JobService(JobManager& manager, Tokens& tokens, Metrics& metrics)
      : mgr_(manager), tokens_(tokens), metrics_(metrics) {}

  grpc::Status SubmitJob(grpc::ServerContext*, const erg::v1::SubmitJobRequest*,
                         erg::v1::Job*) override;
  grpc::Status GetJob(grpc::ServerContext*, const erg::v1::GetJobRequest*, erg::v1::Job*) override;
  grpc::Status ListJobs(grpc::ServerContext*, const erg::v1::ListJobsRequest*,
                        erg::v1::ListJobsResponse*) override;
  grpc::Status CancelJob(grpc::ServerContext*, const erg::v1::CancelJobRequest*,
                         erg::v1::Job*) override;
  grpc::Status WatchJob(grpc::ServerContext*, const erg::v1::WatchJobRequest*,
                        grpc::ServerWriter<erg::v1::JobEvent>*) override;
  grpc::Status StreamSnapshot(grpc::ServerContext*, const erg::v1::StreamSnapshotRequest*,
                              grpc::ServerWriter<erg::v1::SnapshotChunk>*) override;
  grpc::Status GetPreview(grpc::ServerContext*, const erg::v1::GetPreviewRequest*,
                          erg::v1::Preview*) override;
  grpc::Status SteerJob(grpc::ServerContext*, const erg::v1::SteerJobRequest*,
                        erg::v1::SteerJobResponse*) override;
  grpc::Status ResumeJob(grpc::ServerContext*, const erg::v1::ResumeJobRequest*,
                         erg::v1::Job*) override;

 private:
  template <class F>
  grpc::Status call(const char* method, grpc::ServerContext* ctx, F&& body);
  bool still_allowed(grpc::ServerContext* ctx, const std::string& tenant);
  static const grpc::Status kRevoked;
  JobManager& mgr_;
  Tokens& tokens_;
  Metrics& metrics_;
};

}  // namespace erg::server

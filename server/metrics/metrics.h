// SPDX-License-Identifier: Apache-2.0
// ergd's Prometheus metrics (prometheus-cpp), served as text at /metrics.
//   erg_jobs{state}                       jobs in each state (gauge)
//   erg_job_steps_per_second{job,tenant}  running jobs' rates (gauge)
//   erg_snapshot_bytes_streamed_total     StreamSnapshot payload bytes (counter)
//   erg_rpc_latency_seconds{method}       RPC handling time (histogram;
//                                         streams: until the first message)
//   erg_rpc_errors_total{method,code}     failed RPCs (counter)
// An operator token reads them all; a tenant's token only the series
// labelled with its tenant (server/http/http_api.h).
#pragma once

#include <prometheus/counter.h>
#include <prometheus/family.h>
#include <prometheus/gauge.h>
#include <prometheus/histogram.h>
#include <prometheus/registry.h>

#include <memory>
#include <string>

namespace erg::server {

class Metrics {
 public:
  Metrics();
  void observe_rpc(const std::string& method, double seconds);
  void rpc_error(const std::string& method, const std::string& code);
  void streamed(double bytes) { streamed_->Increment(bytes); }
  void set_jobs(const std::string& state, double n);
  void set_rate(const std::string& job, const std::string& tenant, double steps_per_s);
  void remove_rate(const std::string& job, const std::string& tenant);
  std::string text();  // Prometheus text exposition format
  // Only the series labelled tenant="TENANT" (what a tenant's token sees).
  std::string text_of_tenant(const std::string& tenant);

 private:
  std::shared_ptr<prometheus::Registry> registry_;
  prometheus::Family<prometheus::Gauge>* jobs_;
  prometheus::Family<prometheus::Gauge>* rates_;
  prometheus::Family<prometheus::Histogram>* latency_;
  prometheus::Family<prometheus::Counter>* errors_;
  prometheus::Counter* streamed_;
};

}  // namespace erg::server

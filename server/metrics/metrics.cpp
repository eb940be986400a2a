// SPDX-License-Identifier: Apache-2.0
#include "metrics/metrics.h"

#include <prometheus/text_serializer.h>

namespace erg::server {

Metrics::Metrics() : registry_(std::make_shared<prometheus::Registry>()) {
  jobs_ = &prometheus::BuildGauge().Name("erg_jobs").Help("Jobs by state").Register(*registry_);
  rates_ = &prometheus::BuildGauge()
                .Name("erg_job_steps_per_second")
                .Help("Steps per second of running jobs")
                .Register(*registry_);
  latency_ = &prometheus::BuildHistogram()
                  .Name("erg_rpc_latency_seconds")
                  .Help("RPC handling time (streams: until the first message)")
                  .Register(*registry_);
  errors_ = &prometheus::BuildCounter()
                 .Name("erg_rpc_errors_total")
                 .Help("RPCs that failed, by status code")
                 .Register(*registry_);
  streamed_ = &prometheus::BuildCounter()
                   .Name("erg_snapshot_bytes_streamed_total")
                   .Help("Snapshot bytes sent by StreamSnapshot")
                   .Register(*registry_)
                   .Add({});
  for (const char* s : {"QUEUED", "RUNNING", "SUCCEEDED", "FAILED", "CANCELLED"})
    jobs_->Add({{"state", s}}).Set(0);
}

void Metrics::observe_rpc(const std::string& method, double seconds) {
  static const prometheus::Histogram::BucketBoundaries kBuckets{
      0.0001, 0.00025, 0.0005, 0.001, 0.0025, 0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1, 2.5, 10};
  latency_->Add({{"method", method}}, kBuckets).Observe(seconds);
}

void Metrics::rpc_error(const std::string& method, const std::string& code) {
  errors_->Add({{"method", method}, {"code", code}}).Increment();
}

void Metrics::set_jobs(const std::string& state, double n) {
  jobs_->Add({{"state", state}}).Set(n);
}

void Metrics::set_rate(const std::string& job, const std::string& tenant, double r) {
  rates_->Add({{"job", job}, {"tenant", tenant}}).Set(r);
}

void Metrics::remove_rate(const std::string& job, const std::string& tenant) {
  auto& g = rates_->Add({{"job", job}, {"tenant", tenant}});
  rates_->Remove(&g);
}

std::string Metrics::text() {
  return prometheus::TextSerializer().Serialize(registry_->Collect());
}

std::string Metrics::text_of_tenant(const std::string& tenant) {
  // Only series labelled with this tenant: the others would tell it about
  // other tenants' jobs (ids, names, activity).
  std::vector<prometheus::MetricFamily> mine;
  for (auto& family : registry_->Collect()) {
    std::vector<prometheus::ClientMetric> keep;
    for (auto& m : family.metric)
      for (const auto& l : m.label)
        if (l.name == "tenant" && l.value == tenant) {
          keep.push_back(std::move(m));
          break;
        }
    if (keep.empty()) continue;
    family.metric = std::move(keep);
    mine.push_back(std::move(family));
  }
  return prometheus::TextSerializer().Serialize(mine);
}

}  // namespace erg::server

// SPDX-License-Identifier: Apache-2.0
// erg jobs [--state S] [--all-pages]
// erg status ID [--json]
// erg cancel ID
// erg resume ID
// erg steer ID EVENTS.json
#include <google/protobuf/util/json_util.h>

#include <cstdio>
#include <fstream>
#include <iostream>
#include <sstream>

#include "commands.h"
#include "progress_bar.h"
#include "remote/args.h"
#include "remote/common.h"
#include "remote/connection.h"
#include "remote/status.h"

namespace erg::client {

int cmd_jobs(Remote& remote, const std::vector<std::string>& args) {
  erg::v1::ListJobsRequest req;
  bool all_pages = false;
  try {
    const auto p = parse_args(args, {"--state"}, {"--all-pages"});
    if (!p.positional.empty())
      return usage_error("jobs", p.positional[0] + ": unexpected argument");
    if (p.values.count("--state")) {
      erg::v1::JobState s{};
      if (!parse_state(p.values.at("--state"), &s))
        return usage_error("jobs", "--state " + p.values.at("--state") +
                                       ": expected queued, running, succeeded, failed or "
                                       "cancelled");
      req.set_state(s);
    }
    all_pages = p.switches.count("--all-pages") > 0;
  } catch (const std::invalid_argument& e) {
    return usage_error("jobs", e.what());
  }
  req.set_page_size(all_pages ? 1000 : 50);

  bool header = false;
  for (;;) {
    erg::v1::ListJobsResponse resp;
    grpc::ClientContext ctx;
    remote.prepare(ctx, kUnaryDeadline);
    const grpc::Status status = remote.stub().ListJobs(&ctx, req, &resp);
    if (!status.ok()) {
      std::fflush(stdout);
      return remote.fail("jobs", status);
    }
    if (!header)
      std::printf("%-20s %-10s %-21s %9s  %-19s  %s\n", "ID", "STATE", "STEP/TOTAL", "STEPS/S",
                  "CREATED", "NAME");
    header = true;
    for (const auto& j : resp.jobs()) {
      const auto& pr = j.progress();
      const std::string steps = std::to_string(pr.step()) + "/" + std::to_string(pr.total_steps());
      char rate[32] = "-";
      if (j.state() == erg::v1::RUNNING) std::snprintf(rate, sizeof rate, "%.2f", pr.steps_per_s());
      std::printf("%-20s %-10s %-21s %9s  %-19s  %s\n", j.id().c_str(),
                  state_name(j.state()).c_str(), steps.c_str(), rate,
                  fmt_time_ms(j.created_unix_ms()).c_str(), j.spec().name().c_str());
    }
    if (!resp.jobs_size() && !req.page_token().size())
      std::cerr << "erg: no jobs" << (req.state() ? " in state " + state_name(req.state()) : "")
                << "\n";
    if (resp.next_page_token().empty()) break;
    if (!all_pages) {
      std::fflush(stdout);
      std::cerr << "erg: more jobs than shown; --all-pages lists them all\n";
      break;
    }
    req.set_page_token(resp.next_page_token());
  }
  return kExitOk;
}

namespace {

void print_log_tail(const std::string& tail) {
  std::istringstream in(tail);
  std::string line;
  while (std::getline(in, line)) std::cout << "  | " << line << "\n";
}

}  // namespace

int cmd_status(Remote& remote, const std::vector<std::string>& args) {
  bool json = false;
  std::string id;
  try {
    const auto p = parse_args(args, {}, {"--json"});
    if (p.positional.size() != 1) return usage_error("status", "expected one job id");
    id = p.positional[0];
    json = p.switches.count("--json") > 0;
  } catch (const std::invalid_argument& e) {
    return usage_error("status", e.what());
  }
  erg::v1::Job j;
  int code = 0;
  if (!get_job(remote, "status", id, &j, &code)) return code;
  if (json) {
    std::cout << to_json(j, true, true) << "\n";
    return kExitOk;
  }
  const auto& pr = j.progress();
  const auto& s = j.spec();
  auto row = [](const char* k, const std::string& v) { std::printf("%-10s %s\n", k, v.c_str()); };
  row("id", j.id());
  if (!s.name().empty()) row("name", s.name());
  row("state", state_name(j.state()));
  row("progress", j.state() == erg::v1::RUNNING ? progress_text(pr)
                                                : "step " + std::to_string(pr.step()) + "/" +
                                                      std::to_string(pr.total_steps()));
  if (pr.time_years() > 0) {
    char sim[64];
    std::snprintf(sim, sizeof sim, "%.3g years (%.4g days)", pr.time_years(), pr.time_days());
    row("simulated", sim);
  }
  row("domain",
      std::to_string(s.domain().nx()) + " x " + std::to_string(s.domain().ny()) + " cells");
  row("resources", std::to_string(std::max(1, j.resources().ranks())) + " rank(s), " +
                       (j.resources().threads_per_rank() > 0
                            ? std::to_string(j.resources().threads_per_rank()) + " thread(s) each"
                            : std::string("threads: ergd's choice")));
  row("created", fmt_time_ms(j.created_unix_ms()));
  row("started", fmt_time_ms(j.started_unix_ms()));
  row("finished", fmt_time_ms(j.finished_unix_ms()));
  row("snapshots", steps_text(j.snapshot_steps()));
  if (const std::string sand = sand_text(pr, s.domain().cell_size_m()); !sand.empty())
    row("sand", sand);
  row("disk", fmt_bytes(static_cast<double>(j.disk_bytes())));
  row("attempts", std::to_string(j.attempts()));
  if (const std::string w = worker_text(j); !w.empty()) row("worker", w);
  if (!j.idempotency_key().empty()) row("key", j.idempotency_key());
  if (!j.failure_reason().empty()) row("reason", j.failure_reason());
  if (j.state() == erg::v1::FAILED && !j.log_tail().empty()) {
    std::cout << "log tail:\n";
    print_log_tail(j.log_tail());
  }
  return kExitOk;
}

int cmd_cancel(Remote& remote, const std::vector<std::string>& args) {
  if (args.size() != 1 || (args[0].size() > 1 && args[0][0] == '-'))
    return usage_error("cancel", "expected one job id");
  erg::v1::CancelJobRequest req;
  req.set_id(args[0]);
  erg::v1::Job j;
  grpc::ClientContext ctx;
  remote.prepare(ctx, kUnaryDeadline);
  const grpc::Status status = remote.stub().CancelJob(&ctx, req, &j);
  if (!status.ok()) return remote.fail("cancel", status);
  std::cout << state_name(j.state()) << "\n";
  switch (j.state()) {
    case erg::v1::CANCELLED:
      std::cerr << "erg: job " << j.id() << " cancelled at step " << j.progress().step() << "\n";
      break;
    case erg::v1::SUCCEEDED:
    case erg::v1::FAILED:
      std::cerr << "erg: job " << j.id() << " had already ended: " << state_name(j.state()) << "\n";
      break;
    default:
      std::cerr << "erg: job " << j.id()
                << " is stopping (its worker writes a checkpoint, then it ends CANCELLED; "
                   "erg watch "
                << j.id() << " follows it)\n";
  }
  return kExitOk;
}

int cmd_resume(Remote& remote, const std::vector<std::string>& args) {
  if (args.size() != 1 || (args[0].size() > 1 && args[0][0] == '-'))
    return usage_error("resume", "expected one job id");
  erg::v1::ResumeJobRequest req;
  req.set_id(args[0]);
  erg::v1::Job j;
  grpc::ClientContext ctx;
  remote.prepare(ctx, kUnaryDeadline);
  const grpc::Status status = remote.stub().ResumeJob(&ctx, req, &j);
  if (!status.ok()) return remote.fail("resume", status);
  std::cout << state_name(j.state()) << "\n";
  std::cerr << "erg: job " << j.id()
            << " is queued again; its worker continues from its newest intact checkpoint (erg "
               "watch "
            << j.id() << " follows it)\n";
  return kExitOk;
}

int cmd_steer(Remote& remote, const std::vector<std::string>& args) {
  if (args.size() != 2) return usage_error("steer", "expected a job id and an events file");
  std::ifstream in(args[1]);
  if (!in) return usage_error("steer", "cannot read " + args[1]);
  std::stringstream buf;
  buf << in.rdbuf();
  const std::string text = buf.str();
  erg::v1::SteerJobRequest req;
  req.set_id(args[0]);
  // A JSON array of erg.v1.Event, or one Event object.
  const auto first = text.find_first_not_of(" \t\r\n");
  google::protobuf::util::JsonParseOptions opts;
  opts.ignore_unknown_fields = false;
  google::protobuf::util::Status parsed;
  if (first != std::string::npos && text[first] == '[') {
    erg::v1::SteerJobRequest list;
    parsed = google::protobuf::util::JsonStringToMessage("{\"events\": " + text + "}", &list, opts);
    for (auto& e : *list.mutable_events()) *req.add_events() = std::move(e);
  } else {
    parsed = google::protobuf::util::JsonStringToMessage(text, req.add_events(), opts);
  }
  if (!parsed.ok())
    return usage_error("steer", args[1] + ": not an erg.v1.Event or a JSON array of them: " +
                                    std::string(parsed.message()));
  if (req.events_size() == 0) return usage_error("steer", args[1] + ": no events");

  erg::v1::SteerJobResponse resp;
  grpc::ClientContext ctx;
  remote.prepare(ctx, kSteerDeadline);
  const grpc::Status status = remote.stub().SteerJob(&ctx, req, &resp);
  if (!status.ok()) return remote.fail("steer", status);
  for (const auto& e : resp.applied()) {
    erg::v1::Event shown = e;
    shown.clear_step();
    std::cout << "step " << e.step() << ": " << to_json(shown, false) << "\n";
  }
  std::cerr << "erg: " << resp.applied_size() << " event(s) applied to " << args[0]
            << " (recorded in its spec)\n";
  return kExitOk;
}

}  // namespace erg::client
